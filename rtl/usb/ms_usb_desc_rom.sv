// ms_usb_desc_rom: descriptor ROM of the Multisonar USB device (device, configuration with one
// vendor interface and two bulk endpoints, strings, BOS with the Microsoft OS 2.0 platform
// capability, and the MS OS 2.0 descriptor set: compatible ID "WINUSB" + DeviceInterfaceGUIDs).
// The image is generated (multisonar.usb.descriptors -> multisonar.tools.gen_contracts, make's gen
// step): ms_usb_desc_pkg::DESC_HEX for $readmemh, each descriptor's offset and length as
// DESC_*_OFF / DESC_*_LEN in ms_usb_desc_pkg. The simulated device serves the same bytes.
//
// Timing contract: synchronous read, data_o shows the byte at addr_i of the previous clock.
// Parameter: SERIAL, the board's serial number: the serial string's 8 characters (its upper-case
// hex digits) replace the image's at DESC_SERIAL_OFF, so boards differ without a new image.
module ms_usb_desc_rom
  import ms_usb_desc_pkg::*;
#(
  parameter int SERIAL = 'h00000001
) (
  input  logic       clk_i,
  input  logic [8:0] addr_i,
  output logic [7:0] data_o
);
  function automatic logic [7:0] hex_char(input logic [3:0] n);
    hex_char = (n < 4'd10) ? 8'h30 + {4'd0, n} : 8'h37 + {4'd0, n};
  endfunction

  // In logic, not block RAM: about 270 LUT4 instead of one of the LFE5U-25F's 56 DP16KD, which
  // the design needs.
  (* rom_style = "logic" *) logic [7:0] image [DESC_BYTES];
  initial $readmemh(DESC_HEX, image);

  // the serial string's characters sit at DESC_SERIAL_OFF + 2 * i (UTF-16LE, high bytes zero)
  logic [9:0] serial_rel;
  logic [7:0] b;
  assign serial_rel = {1'b0, addr_i} - 10'(DESC_SERIAL_OFF);
  always_comb begin
    b = image[addr_i];
    if (serial_rel < 10'd16 && !serial_rel[0]) begin
      b = hex_char(4'(SERIAL >> (4 * (7 - int'(serial_rel[3:1])))));
    end
  end

  always_ff @(posedge clk_i) data_o <= b;
endmodule
