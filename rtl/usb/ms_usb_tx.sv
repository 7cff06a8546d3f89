// ms_usb_tx: full-speed transmit PHY and packet framing: SYNC, PID (with its check nibble),
// optional data bytes + CRC16, bit stuffing, NRZI encode, EOP (SE0 SE0 J), output enable.
//
// Timing contract (clk_i = 48 MHz, one bit every 4 clocks):
// - start_i (accepted only when busy_o is low) latches pid_i, with_data_i and len_i (0..64 data
//   bytes; a handshake is with_data_i = 0). The first K of SYNC is on the line the next clock.
// - Data bytes are fetched one ahead: rd_o pulses once per data byte, in order; byte_i must hold
//   that byte from 2 clocks after the pulse until the next pulse (a registered RAM/ROM read).
//   The first pulse comes when the PID byte starts (>= 32 clocks before the byte is needed).
// - oe_o is high from the first SYNC bit through the J bit of EOP; done_o pulses when the line
//   is released, busy_o covers start_i..done_o. Packet length on the wire: (8 + 8 * (1 + n + 2)
//   + stuffed bits + 3) bits for n data bytes.
module ms_usb_tx (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       start_i,
  input  logic [3:0] pid_i,
  input  logic       with_data_i,
  input  logic [6:0] len_i,
  output logic       rd_o,
  input  logic [7:0] byte_i,
  output logic       busy_o,
  output logic       done_o,
  output logic       dp_o,
  output logic       dn_o,
  output logic       oe_o
);
  import ms_usb_pkg::*;

  typedef enum logic [2:0] {T_SYNC, T_PID, T_DATA, T_CRCL, T_CRCH, T_EOP} stage_e;

  stage_e      stage_q;
  logic        busy_q, with_data_q, level_q;  // level_q: 1 = J, 0 = K
  logic [3:0]  pid_q;
  logic [1:0]  div_q, eop_q;
  logic [2:0]  bitcnt_q, ones_q;
  logic [7:0]  sh_q;
  logic [6:0]  len_q, idx_q;
  logic [15:0] crc_q;
  logic        strobe;
  assign strobe = busy_q && (div_q == 2'd3);
  assign busy_o = busy_q;

  always_ff @(posedge clk_i) begin
    rd_o   <= 1'b0;
    done_o <= 1'b0;
    if (rst_i) begin
      busy_q      <= 1'b0;
      stage_q     <= T_SYNC;
      with_data_q <= 1'b0;
      pid_q       <= '0;
      level_q     <= 1'b1;
      div_q       <= '0;
      eop_q       <= '0;
      bitcnt_q    <= '0;
      ones_q      <= '0;
      sh_q        <= '0;
      len_q       <= '0;
      idx_q       <= '0;
      crc_q       <= 16'hFFFF;
      oe_o        <= 1'b0;
      dp_o        <= 1'b1;
      dn_o        <= 1'b0;
    end else if (!busy_q) begin
      if (start_i) begin
        busy_q      <= 1'b1;
        stage_q     <= T_SYNC;
        with_data_q <= with_data_i;
        pid_q       <= pid_i;
        len_q       <= len_i;
        idx_q       <= '0;
        sh_q        <= 8'h80;
        bitcnt_q    <= '0;
        ones_q      <= '0;
        eop_q       <= '0;
        level_q     <= 1'b1;
        crc_q       <= 16'hFFFF;
        div_q       <= 2'd3;
      end
    end else begin
      div_q <= div_q + 2'd1;
      if (strobe) begin
        if (ones_q == 3'd6) begin
          // stuffed 0: the level toggles
          ones_q  <= '0;
          level_q <= ~level_q;
          oe_o    <= 1'b1;
          {dp_o, dn_o} <= level_q ? SYM_K : SYM_J;
        end else if (stage_q == T_EOP) begin
          eop_q <= eop_q + 2'd1;
          case (eop_q)
            2'd0, 2'd1: {dp_o, dn_o} <= SYM_SE0;
            2'd2:       {dp_o, dn_o} <= SYM_J;
            default: begin
              oe_o   <= 1'b0;
              busy_q <= 1'b0;
              done_o <= 1'b1;
            end
          endcase
        end else begin
          oe_o     <= 1'b1;
          ones_q   <= sh_q[0] ? ones_q + 3'd1 : 3'd0;
          level_q  <= sh_q[0] ? level_q : ~level_q;
          {dp_o, dn_o} <= (sh_q[0] ? level_q : ~level_q) ? SYM_J : SYM_K;
          sh_q     <= sh_q >> 1;
          bitcnt_q <= bitcnt_q + 3'd1;
          if (bitcnt_q == 3'd7) begin
            // load the next byte
            case (stage_q)
              T_SYNC: begin
                stage_q <= T_PID;
                sh_q    <= {~pid_q, pid_q};
                if (with_data_q && len_q != 7'd0) rd_o <= 1'b1;
              end
              T_PID, T_DATA: begin
                if (!with_data_q) begin
                  stage_q <= T_EOP;
                end else if (idx_q == len_q) begin
                  stage_q <= T_CRCL;
                  sh_q    <= ~crc_q[7:0];
                end else begin
                  stage_q <= T_DATA;
                  sh_q    <= byte_i;
                  crc_q   <= crc16_byte(crc_q, byte_i);
                  idx_q   <= idx_q + 7'd1;
                  if (idx_q + 7'd1 < len_q) rd_o <= 1'b1;
                end
              end
              T_CRCL: begin
                stage_q <= T_CRCH;
                sh_q    <= ~crc_q[15:8];
              end
              default: stage_q <= T_EOP;  // after CRC high byte
            endcase
          end
        end
      end
    end
  end
endmodule
