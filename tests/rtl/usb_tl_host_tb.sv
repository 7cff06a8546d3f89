// usb_tl_host_tb: transaction-level host for the cocotb tests: drives the wire-less packet port
// of ms_usb_device (tl_en_i = 1) from a byte buffer and records the device's answer.
// Runs on the device clock. go_i high (while done_o is low): tl_rx_start, tx_len_i bytes of
// tx_bytes_i (byte k at [8k+7:8k], PID first, CRC included) one per clock, tl_rx_end; then with
// listen_i != 0 wait up to listen_i clocks for the device's packet and record it (rx_bytes_o,
// rx_len_o; resp_delay_o = clocks from tl_rx_end to its first byte). done_o high at the end,
// low after go_i low.
module usb_tl_host_tb #(
  parameter int NB = 72
) (
  input  logic            clk_i,
  input  logic            rst_i,
  input  logic            go_i,
  input  logic [8*NB-1:0] tx_bytes_i,
  input  logic [7:0]      tx_len_i,
  input  logic [15:0]     listen_i,
  output logic            done_o,
  output logic [8*NB-1:0] rx_bytes_o,
  output logic [7:0]      rx_len_o,
  output logic [15:0]     resp_delay_o,
  output logic            tl_rx_start_o,
  output logic            tl_rx_valid_o,
  output logic [7:0]      tl_rx_byte_o,
  output logic            tl_rx_end_o,
  input  logic            tl_tx_valid_i,
  input  logic [7:0]      tl_tx_byte_i,
  input  logic            tl_tx_end_i
);
  typedef enum logic [2:0] {T_IDLE, T_START, T_BYTES, T_END, T_LISTEN, T_RX} state_e;
  state_e      state_q;
  logic [7:0]  idx_q;
  logic [15:0] timer_q;

  always_ff @(posedge clk_i) begin
    tl_rx_start_o <= 1'b0;
    tl_rx_valid_o <= 1'b0;
    tl_rx_end_o   <= 1'b0;
    if (rst_i) begin
      state_q      <= T_IDLE;
      done_o       <= 1'b0;
      idx_q        <= '0;
      timer_q      <= '0;
      rx_len_o     <= '0;
      rx_bytes_o   <= '0;
      resp_delay_o <= '0;
      tl_rx_byte_o <= '0;
    end else begin
      case (state_q)
        T_IDLE: begin
          if (!go_i) done_o <= 1'b0;
          else if (!done_o) begin
            state_q       <= T_BYTES;
            tl_rx_start_o <= 1'b1;
            idx_q         <= '0;
            rx_len_o      <= '0;
            rx_bytes_o    <= '0;
            resp_delay_o  <= '0;
          end
        end
        T_BYTES: begin
          if (idx_q == tx_len_i) begin
            tl_rx_end_o <= 1'b1;
            timer_q     <= '0;
            state_q     <= (listen_i == 16'd0) ? T_END : T_LISTEN;
          end else begin
            tl_rx_valid_o <= 1'b1;
            tl_rx_byte_o  <= tx_bytes_i[8*idx_q +: 8];
            idx_q         <= idx_q + 8'd1;
          end
        end
        T_LISTEN, T_RX: begin
          timer_q <= timer_q + 16'd1;
          if (tl_tx_valid_i) begin
            if (state_q == T_LISTEN) resp_delay_o <= timer_q;
            state_q <= T_RX;
            if (rx_len_o < 8'(NB)) begin
              rx_bytes_o[8*rx_len_o +: 8] <= tl_tx_byte_i;
              rx_len_o <= rx_len_o + 8'd1;
            end
          end
          if ((state_q == T_RX && tl_tx_end_i) || (state_q == T_LISTEN && timer_q == listen_i)) begin
            state_q <= T_END;
          end
        end
        default: begin  // T_END
          done_o  <= 1'b1;
          state_q <= T_IDLE;
        end
      endcase
    end
  end
endmodule
