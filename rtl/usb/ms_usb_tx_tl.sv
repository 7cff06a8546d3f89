// ms_usb_tx_tl: transaction-level twin of ms_usb_tx for the wire-less entry point of
// ms_usb_device (tl_en_i): builds the same packet bytes (PID with check nibble, data, CRC16)
// but hands them out as a byte stream instead of serialising them on D+/D-.
//
// Timing contract: same control interface as ms_usb_tx (start_i when idle; rd_o pulses once
// per data byte, byte_i valid 2 clocks later until the next rd_o; done_o at the end). Bytes come
// out as byte_valid_o/byte_o pulses every 4 clocks: PID, the len_i data bytes, CRC16 low, high
// (PID only for a handshake); done_o pulses 4 clocks after the last byte.
module ms_usb_tx_tl (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       start_i,
  input  logic [3:0] pid_i,
  input  logic       with_data_i,
  input  logic [6:0] len_i,
  output logic       rd_o,
  input  logic [7:0] byte_i,
  output logic       done_o,
  output logic       byte_valid_o,
  output logic [7:0] byte_o
);
  import ms_usb_pkg::*;

  typedef enum logic [2:0] {B_IDLE, B_PID, B_DATA, B_CRCL, B_CRCH, B_DONE} stage_e;

  stage_e      stage_q;
  logic [1:0]  div_q;
  logic [3:0]  pid_q;
  logic        with_data_q;
  logic [6:0]  len_q, idx_q;
  logic [15:0] crc_q;

  always_ff @(posedge clk_i) begin
    rd_o         <= 1'b0;
    done_o       <= 1'b0;
    byte_valid_o <= 1'b0;
    if (rst_i) begin
      stage_q     <= B_IDLE;
      div_q       <= '0;
      pid_q       <= '0;
      with_data_q <= 1'b0;
      len_q       <= '0;
      idx_q       <= '0;
      crc_q       <= 16'hFFFF;
      byte_o      <= '0;
    end else if (stage_q == B_IDLE) begin
      if (start_i) begin
        stage_q     <= B_PID;
        div_q       <= '0;
        pid_q       <= pid_i;
        with_data_q <= with_data_i;
        len_q       <= len_i;
        idx_q       <= '0;
        crc_q       <= 16'hFFFF;
      end
    end else begin
      div_q <= div_q + 2'd1;
      if (div_q == 2'd0) begin
        case (stage_q)
          B_PID: begin
            byte_valid_o <= 1'b1;
            byte_o       <= {~pid_q, pid_q};
            if (!with_data_q) stage_q <= B_DONE;
            else if (len_q == 7'd0) stage_q <= B_CRCL;
            else begin
              stage_q <= B_DATA;
              rd_o    <= 1'b1;
            end
          end
          B_DATA: begin
            byte_valid_o <= 1'b1;
            byte_o       <= byte_i;
            crc_q        <= crc16_byte(crc_q, byte_i);
            idx_q        <= idx_q + 7'd1;
            if (idx_q + 7'd1 == len_q) stage_q <= B_CRCL;
            else rd_o <= 1'b1;
          end
          B_CRCL: begin
            byte_valid_o <= 1'b1;
            byte_o       <= ~crc_q[7:0];
            stage_q      <= B_CRCH;
          end
          B_CRCH: begin
            byte_valid_o <= 1'b1;
            byte_o       <= ~crc_q[15:8];
            stage_q      <= B_DONE;
          end
          default: begin  // B_DONE
            done_o  <= 1'b1;
            stage_q <= B_IDLE;
          end
        endcase
      end
    end
  end
endmodule
