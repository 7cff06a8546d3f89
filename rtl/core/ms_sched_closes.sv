// ms_sched_closes: the scheduler's close detector (docs/sched_engine.md): which elements' head
// window closes at a tick. Each element has at most one head (the window of its reserved slots
// closing first, set by the engine); the detector compares every head's close tick with the
// tick counter in every clock.
//
// Timing contract (ticks of clk_i; tick_i counts by one every clock):
//   - we_i with el_i, vld_i (0: the element has no head) and close_i: the element's head from
//     the next clock. A head's close tick must lie in (tick_i, tick_i + 2^(HCW-1)) when written.
//   - closes_o[e], in the clock with tick_i = T + 1: element e's head closes at T.
//   - rst_i clears every head.
// Only the low HCW bits of a close tick are kept, split at LB: time runs in blocks of 2^LB
// ticks. Each element keeps the low LB bits in flops and two flags, "the head's block is the
// current block" and "... the next block"; the high bits are compared with one shared
// comparator, at the write and by a scan that visits element L in the clock with
// tick_i[LB-1:0] == L (2^LB > NUM_CH). At the end of a block the current flag takes the next
// one. So the per-clock compare per element is LB bits and a flag, not HCW bits (24 x 26-bit
// compares were ~630 TRELLIS_COMB in ms_scheduler, which has the same scheme inline).
module ms_sched_closes #(
  parameter int NUM_CH = 24,
  parameter int HCW    = 26,
  localparam int EW    = $clog2(NUM_CH),
  localparam int LB    = $clog2(NUM_CH + 1),
  localparam int HBW   = HCW - LB
) (
  input  logic              clk_i,
  input  logic              rst_i,
  input  logic [31:0]       tick_i,
  input  logic              we_i,
  input  logic [EW-1:0]     el_i,
  input  logic              vld_i,
  input  logic [31:0]       close_i,
  output logic [NUM_CH-1:0] closes_o
);
  logic [NUM_CH-1:0][LB-1:0] lo_q;
  logic [NUM_CH-1:0]         vld_q, cur_q, nxt_q, eq_q;
  logic [HBW-1:0]            hi_m [2**LB];     // close tick bits [HCW-1:LB], read by the scan
  logic [HBW-1:0]            blk_c_q, blk_n_q, hbw_t2, w_hi;
  logic [LB-1:0]             pos;
  logic                      blk_end, w_cur, w_nxt, s_nxt;

  // block(tick + 1) and block(tick + 1) + 1 in the clock of a write (registered from tick + 2)
  assign hbw_t2  = HBW'((tick_i[HCW-1:0] + HCW'(2)) >> LB);
  assign pos     = tick_i[LB-1:0];
  assign blk_end = pos == '1;
  assign w_hi    = close_i[HCW-1:LB];
  assign w_cur   = w_hi == blk_c_q;
  assign w_nxt   = w_hi == blk_n_q;
  assign s_nxt   = hi_m[pos] == blk_n_q;
  always_ff @(posedge clk_i) begin
    blk_c_q <= hbw_t2;
    blk_n_q <= hbw_t2 + HBW'(1);
    if (we_i) hi_m[LB'(el_i)] <= w_hi;
    for (int e = 0; e < NUM_CH; e++) begin
      if (rst_i) begin
        vld_q[e] <= 1'b0;
        cur_q[e] <= 1'b0;
        nxt_q[e] <= 1'b0;
      end else if (we_i && el_i == EW'(e)) begin
        vld_q[e] <= vld_i;
        lo_q[e]  <= close_i[LB-1:0];
        cur_q[e] <= w_cur;
        nxt_q[e] <= w_nxt;
      end else begin
        if (blk_end)         cur_q[e] <= nxt_q[e];
        if (pos == LB'(e))   nxt_q[e] <= s_nxt;
      end
      // the head closes at this tick: closes_o in the next clock
      eq_q[e] <= !rst_i && vld_q[e] && cur_q[e] && lo_q[e] == tick_i[LB-1:0];
    end
  end
  assign closes_o = eq_q;

  logic unused_ok;
  assign unused_ok = ^{tick_i[31:HCW], close_i[31:HCW]};
endmodule
