// ms_usb_pkt_rx: packet decoder on the byte stream of ms_usb_rx: PID check, token fields and
// CRC5, data payload with CRC16 check, handshakes.
//
// Timing contract (all outputs are one-clock pulses unless noted, registered):
// - pkt_start_o: a packet (any) began (SYNC seen).
// - tok_valid_o at the end (EOP) of a good IN/OUT/SETUP token: tok_pid_o/tok_addr_o/tok_ep_o
//   hold until the next token. SOF and bad tokens (PID check, CRC5, length, stuff error) give
//   nothing.
// - Data packet: dat_start_o when its PID arrives (dat_pid1_o = 1 for DATA1, holds); then
//   dat_valid_o/dat_byte_o once per payload byte, delayed by two bytes so the CRC bytes are never
//   delivered; dat_end_o exactly once at its end with dat_ok_o = CRC16 good, framing good.
// - hs_valid_o with hs_pid_o for an ACK/NAK/STALL packet of exactly one byte.
module ms_usb_pkt_rx (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       rx_start_i,
  input  logic       rx_valid_i,
  input  logic [7:0] rx_byte_i,
  input  logic       rx_eop_i,
  input  logic       rx_err_i,
  output logic       pkt_start_o,
  output logic       tok_valid_o,
  output logic [3:0] tok_pid_o,
  output logic [6:0] tok_addr_o,
  output logic [3:0] tok_ep_o,
  output logic       dat_start_o,
  output logic       dat_pid1_o,
  output logic       dat_valid_o,
  output logic [7:0] dat_byte_o,
  output logic       dat_end_o,
  output logic       dat_ok_o,
  output logic       hs_valid_o,
  output logic [3:0] hs_pid_o
);
  import ms_usb_pkg::*;

  typedef enum logic [1:0] {K_NONE, K_TOKEN, K_DATA, K_HS} kind_e;

  kind_e       kind_q;
  logic [3:0]  pid_q;
  logic [1:0]  cnt_q;     // bytes seen, saturating at 3
  logic [7:0]  b1_q, b2_q;
  logic [15:0] crc_q;
  logic [10:0] tok_bits;
  assign tok_bits = {b2_q[2:0], b1_q};

  always_ff @(posedge clk_i) begin
    pkt_start_o <= 1'b0;
    tok_valid_o <= 1'b0;
    dat_start_o <= 1'b0;
    dat_valid_o <= 1'b0;
    dat_end_o   <= 1'b0;
    hs_valid_o  <= 1'b0;
    if (rst_i) begin
      kind_q     <= K_NONE;
      pid_q      <= '0;
      cnt_q      <= '0;
      b1_q       <= '0;
      b2_q       <= '0;
      crc_q      <= 16'hFFFF;
      tok_pid_o  <= '0;
      tok_addr_o <= '0;
      tok_ep_o   <= '0;
      dat_pid1_o <= 1'b0;
      dat_byte_o <= '0;
      dat_ok_o   <= 1'b0;
      hs_pid_o   <= '0;
    end else begin
      if (rx_start_i) begin
        pkt_start_o <= 1'b1;
        kind_q      <= K_NONE;
        cnt_q       <= '0;
        crc_q       <= 16'hFFFF;
      end else if (rx_valid_i) begin
        if (cnt_q != 2'd3) cnt_q <= cnt_q + 2'd1;
        if (cnt_q == 2'd0) begin
          pid_q <= rx_byte_i[3:0];
          if (rx_byte_i[7:4] != ~rx_byte_i[3:0]) kind_q <= K_NONE;
          else begin
            case (rx_byte_i[3:0])
              PID_OUT, PID_IN, PID_SETUP, PID_SOF: kind_q <= K_TOKEN;
              PID_DATA0, PID_DATA1: begin
                kind_q      <= K_DATA;
                dat_start_o <= 1'b1;
                dat_pid1_o  <= rx_byte_i[3];
              end
              PID_ACK, PID_NAK, PID_STALL: kind_q <= K_HS;
              default: kind_q <= K_NONE;
            endcase
          end
        end else begin
          b1_q <= b2_q;  // the last two bytes: b1 older, b2 newer
          b2_q <= rx_byte_i;
          if (cnt_q == 2'd3 && kind_q == K_DATA) begin
            dat_valid_o <= 1'b1;
            dat_byte_o  <= b1_q;
            crc_q       <= crc16_byte(crc_q, b1_q);
          end
        end
      end else if (rx_eop_i) begin
        kind_q <= K_NONE;
        case (kind_q)
          K_TOKEN: begin
            if (cnt_q == 2'd3 && crc5_11(tok_bits) == b2_q[7:3] && pid_q != PID_SOF) begin
              tok_valid_o <= 1'b1;
              tok_pid_o   <= pid_q;
              tok_addr_o  <= b1_q[6:0];
              tok_ep_o    <= {b2_q[2:0], b1_q[7]};
            end
          end
          K_DATA: begin
            dat_end_o <= 1'b1;
            dat_ok_o  <= (cnt_q == 2'd3) && ({b2_q, b1_q} == ~crc_q);
          end
          K_HS: begin
            if (cnt_q == 2'd1) begin
              hs_valid_o <= 1'b1;
              hs_pid_o   <= pid_q;
            end
          end
          default: ;
        endcase
      end else if (rx_err_i) begin
        kind_q <= K_NONE;
        if (kind_q == K_DATA) begin
          dat_end_o <= 1'b1;
          dat_ok_o  <= 1'b0;
        end
      end
    end
  end
endmodule
