// ms_usb_ep_out: receive buffer of the bulk OUT endpoint (EP 0x01) with commit/rollback.
//
// Timing contract:
// - Engine side: wr_begin_i starts a packet (drops any uncommitted bytes); wr_valid_i/wr_byte_i
//   write payload bytes; wr_commit_i makes the packet visible to the application (its last byte
//   carries out_last_o), wr_abort_i drops it (bad CRC, NAK, duplicate, STALL). room_o is high
//   when a whole 64-byte packet fits; the engine checks it at the OUT token and NAKs otherwise.
//   Bytes of one packet are written at most every 32 clocks, so the one-byte write hold-back
//   (needed to mark the last byte at commit) never collides.
// - Application side: out_valid_o/out_data_o, an entry is taken on a clock with out_ready_i high
//   (first-word-fall-through, one per clock). out_last_o marks the last byte of a USB packet,
//   out_end_o the end of a transfer (the packet was short, < 64 bytes). A zero-length packet
//   is one entry with out_zlp_o = out_last_o = out_end_o = 1 and no data byte (out_data_o = 0):
//   it ends a transfer whose size is a multiple of 64. DEPTH (power of two, >= 64) entries.
module ms_usb_ep_out #(
  parameter int DEPTH = 128,
  parameter int AW    = $clog2(DEPTH)
) (
  input  logic       clk_i,
  input  logic       rst_i,
  output logic       room_o,
  input  logic       wr_begin_i,
  input  logic       wr_valid_i,
  input  logic [7:0] wr_byte_i,
  input  logic       wr_commit_i,
  input  logic       wr_abort_i,
  output logic [7:0] out_data_o,
  output logic       out_valid_o,
  output logic       out_last_o,
  output logic       out_end_o,
  output logic       out_zlp_o,
  input  logic       out_ready_i
);
  logic [10:0] mem_q [DEPTH];   // {zlp, end, last, byte}
  logic [AW:0] wp_q, commit_q, rp_q, used;
  logic        hold_v_q;
  logic [7:0]  hold_q;
  logic        we;
  logic [10:0] wdata;
  logic [6:0]  cnt_q;           // bytes of the current packet, the held one included

  assign used   = commit_q - rp_q;
  assign room_o = (used <= (AW + 1)'(DEPTH - 64));

  always_comb begin
    we    = 1'b0;
    wdata = {3'b000, hold_q};
    if (wr_commit_i) begin
      we    = 1'b1;
      wdata = hold_v_q ? {1'b0, cnt_q != 7'd64, 1'b1, hold_q} : {3'b111, 8'h00};
    end else if (wr_valid_i && hold_v_q && !wr_begin_i && !wr_abort_i) begin
      we = 1'b1;
    end
  end

  always_ff @(posedge clk_i) begin
    if (we) mem_q[wp_q[AW-1:0]] <= wdata;
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      wp_q     <= '0;
      commit_q <= '0;
      hold_v_q <= 1'b0;
      hold_q   <= '0;
      cnt_q    <= '0;
    end else if (wr_begin_i || wr_abort_i) begin
      wp_q     <= commit_q;
      hold_v_q <= 1'b0;
      cnt_q    <= '0;
    end else if (wr_commit_i) begin
      hold_v_q <= 1'b0;
      cnt_q    <= '0;
      commit_q <= wp_q + 1'b1;
      wp_q     <= wp_q + 1'b1;
    end else if (wr_valid_i) begin
      hold_q   <= wr_byte_i;
      hold_v_q <= 1'b1;
      if (cnt_q != 7'd64) cnt_q <= cnt_q + 7'd1;
      if (hold_v_q) wp_q <= wp_q + 1'b1;
    end
  end

  // first-word-fall-through read with a registered (block-RAM) read port
  logic fetch;
  assign fetch = (rp_q != commit_q) && (!out_valid_o || out_ready_i);
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      rp_q        <= '0;
      out_valid_o <= 1'b0;
      out_data_o  <= '0;
      out_last_o  <= 1'b0;
      out_end_o   <= 1'b0;
      out_zlp_o   <= 1'b0;
    end else if (fetch) begin
      {out_zlp_o, out_end_o, out_last_o, out_data_o} <= mem_q[rp_q[AW-1:0]];
      rp_q        <= rp_q + 1'b1;
      out_valid_o <= 1'b1;
    end else if (out_ready_i) begin
      out_valid_o <= 1'b0;
    end
  end
endmodule
