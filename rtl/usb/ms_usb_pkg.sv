// ms_usb_pkg: constants and CRC functions of the USB 2.0 full-speed device core (rtl/usb/).
//
// PIDs are the 4-bit codes (the check nibble is added/checked by ms_usb_tx / ms_usb_pkt_rx).
// CRCs follow USB 2.0 ch. 8.3.5, bits LSB first (reflected form):
//   crc5  over 11 token bits, polynomial x^5+x^2+1, init 5'h1F, result inverted; the returned
//         value goes to token byte 2 bits [7:3] (bit 0 of the value is sent first).
//   crc16 polynomial x^16+x^15+x^2+1, init 16'hFFFF, result inverted, sent low byte first.
package ms_usb_pkg;
  localparam logic [3:0] PID_OUT   = 4'b0001;
  localparam logic [3:0] PID_IN    = 4'b1001;
  localparam logic [3:0] PID_SOF   = 4'b0101;
  localparam logic [3:0] PID_SETUP = 4'b1101;
  localparam logic [3:0] PID_DATA0 = 4'b0011;
  localparam logic [3:0] PID_DATA1 = 4'b1011;
  localparam logic [3:0] PID_ACK   = 4'b0010;
  localparam logic [3:0] PID_NAK   = 4'b1010;
  localparam logic [3:0] PID_STALL = 4'b1110;

  // Line symbols as {dp, dn}.
  localparam logic [1:0] SYM_SE0 = 2'b00;
  localparam logic [1:0] SYM_J   = 2'b10;
  localparam logic [1:0] SYM_K   = 2'b01;

  // CRC5 of the 11 token bits {endp, addr} (addr in bits [6:0]); returns the inverted remainder.
  function automatic logic [4:0] crc5_11(input logic [10:0] bits);
    logic [4:0] c;
    c = 5'h1F;
    for (int i = 0; i < 11; i++) begin
      if (c[0] ^ bits[i]) c = (c >> 1) ^ 5'h14;
      else                c = c >> 1;
    end
    crc5_11 = ~c;
  endfunction

  // One byte into a running (not inverted) CRC16 register; start with 16'hFFFF, send ~crc.
  function automatic logic [15:0] crc16_byte(input logic [15:0] crc, input logic [7:0] data);
    logic [15:0] c;
    c = crc;
    for (int i = 0; i < 8; i++) begin
      if (c[0] ^ data[i]) c = (c >> 1) ^ 16'hA001;
      else                c = c >> 1;
    end
    crc16_byte = c;
  endfunction
endpackage
