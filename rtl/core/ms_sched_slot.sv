// ms_sched_slot: the scheduler engine's slot unit (docs/sched_engine.md): scans the valid
// reserved windows of one element, one per clock, for the microcode's conflict, edge, head
// and cancel searches. Its golden model is multisonar.tools.sched_program.SlotUnit; the
// modes and results below are that model's.
//
// Timing contract (clocks of clk_i; ticks and offsets modulo 2^32, compares signed):
//   - Range: every difference of two ticks the scan takes (a window's end or start, TA, TB,
//     TWA, TWB, a close tick) lies within +-2^25 (the scheduler's windows end less than
//     2^24 + LEAD ticks after the tick, and a slot is freed when its window closes). The scan
//     computes modulo 2^RW (RW = 26), which then gives the model's 32-bit results.
//   - go_i (one clock) with mode_i, el_i, bon_i, won_i, valid_i and ta_i, tb_i, twa_i, twb_i:
//     busy_o is high from the next clock for n + 4 clocks (n = valid slots); x_o, flags_o
//     and minc_o hold the results from the clock busy_o falls to the next go_i (n + 5 clocks
//     after go_i, the model's done_at). A go while busy restarts the scan.
//   - WIN read port: win_ra_o (slot el * WSLOTS + k) in a clock with win_re_o, the slot's
//     fields on win_*_i in the next clock (a registered block-RAM read). WIN does not store a
//     window's start: win_len_i is its length (the sensor's, looked up by the caller).
//   - A slot's window is [t0 + we - len, t0 + we), closing at t0 + we + latm1_i (latm1_i =
//     L - 1).
// Modes (the model's SU_GO bits 11:10):
//   CONF:   x = the largest retry end - TA (blank interval [TA, TB), bon_i) or end - TWA (window
//           [TWA, TWB), won_i) over the windows overlapping them; flags[0] any overlap,
//           flags[1] won_i and every slot valid; minc = the close tick nearest after TA.
//   EDGE:   the slot holding tick TA (windows of one element never overlap): x = it, flags[0].
//   HEAD:   the slot closing first after TA: x = it, minc = its close tick, flags[0].
//   SENSOR: x = the mask of the slots of sensor TA.
// One datapath serves every mode: EDGE is the blank-overlap test with [TA, TA + 1), HEAD the
// CONF close search; both candidates of a slot are end - TA and end - TWA, so which one is
// larger is fixed for the scan (TWA - TA) and needs no compare per slot.
module ms_sched_slot #(
  parameter int NUM_CH = 24,
  parameter int WSLOTS = 16,
  localparam int KW = $clog2(WSLOTS),
  localparam int EW = $clog2(NUM_CH),
  localparam int AW = $clog2(NUM_CH * WSLOTS)
) (
  input  logic              clk_i,
  input  logic              rst_i,
  input  logic              go_i,
  input  logic [1:0]        mode_i,     // 0 CONF, 1 EDGE, 2 HEAD, 3 SENSOR
  input  logic [EW-1:0]     el_i,
  input  logic              bon_i,
  input  logic              won_i,
  input  logic [WSLOTS-1:0] valid_i,
  input  logic [31:0]       ta_i,
  input  logic [31:0]       tb_i,
  input  logic [31:0]       twa_i,
  input  logic [31:0]       twb_i,
  input  logic [7:0]        latm1_i,
  output logic [AW-1:0]     win_ra_o,
  output logic              win_re_o,
  input  logic [31:0]       win_t0_i,
  input  logic [23:0]       win_len_i,
  input  logic [23:0]       win_we_i,
  input  logic [2:0]        win_sensor_i,
  output logic              busy_o,
  output logic [31:0]       x_o,
  output logic [7:0]        flags_o,
  output logic [31:0]       minc_o
);
  localparam logic [1:0] M_CONF = 2'd0, M_EDGE = 2'd1, M_HEAD = 2'd2, M_SENSOR = 2'd3;
  localparam int RW = 26;   // the scan's arithmetic width (the range above)
  typedef logic [RW-1:0] rt_t;

  // ---- the scan's operands, latched at go
  logic [1:0]        mode_q;
  logic [EW-1:0]     el_q;
  logic              bon_q, won_q, full_q, bwin_q;
  logic [31:0]       ta_q;               // whole: minc_o = TA + the close's distance
  rt_t               tb_q, twa_q, twb_q, tal_q;
  logic [WSLOTS-1:0] srem_q, srem_d;
  logic              go_q;               // the clock after go (busy while no slot is issued)
  logic [2:0]        tail_q;             // go's marker through the pipeline, for n = 0
  always_ff @(posedge clk_i) begin
    if (go_i) begin
      mode_q  <= mode_i;
      el_q    <= el_i;
      bon_q   <= bon_i || mode_i == M_EDGE;
      won_q   <= won_i && mode_i == M_CONF;
      full_q  <= won_i && mode_i == M_CONF && &valid_i;
      ta_q    <= ta_i;
      tb_q    <= mode_i == M_EDGE ? RW'(ta_i) + rt_t'(1) : RW'(tb_i);  // EDGE: [TA, TA + 1)
      twa_q   <= RW'(twa_i);
      twb_q   <= RW'(twb_i);
      tal_q   <= RW'(ta_i - 32'(latm1_i));     // close - TA = end - (TA - latm1)
      bwin_q  <= $signed(RW'(twa_i - ta_i)) > 0;  // end - TA > end - TWA
    end
  end

  // ---- stage A: issue the lowest valid slot left
  logic [KW-1:0] k_a;
  always_comb begin
    k_a = '0;
    for (int k = WSLOTS - 1; k >= 0; k--) if (srem_q[k]) k_a = KW'(k);
    srem_d = srem_q & (srem_q - 1'b1);
  end
  assign win_re_o = srem_q != '0;
  assign win_ra_o = AW'(int'(el_q) * WSLOTS + int'(k_a));

  // ---- stage B: the slot's fields (RAM output) -> its end; S: its start; C: the compares;
  // D: the fold
  logic          v_b, v_s, v_c, v_d;
  logic [KW-1:0] k_b, k_s, k_c, k_d;
  rt_t           end_s, start_c, end_c;
  logic [23:0]   len_s;
  logic [2:0]    sensor_s, sensor_c, sensor_d;
  rt_t           rel_b_d, rel_w_d, crel_d;
  rt_t           rel_b_c, rel_w_c;       // stage C: the end's distance after TA, after TWA
  logic          ov_b_d, ov_w_d;
  assign rel_b_c = end_c - RW'(ta_q);
  assign rel_w_c = end_c - twa_q;
  always_ff @(posedge clk_i) begin
    if (rst_i || go_i) begin
      srem_q <= go_i ? valid_i : '0;
      go_q   <= go_i;
      tail_q <= '0;
      v_b    <= 1'b0;
      v_s    <= 1'b0;
      v_c    <= 1'b0;
      v_d    <= 1'b0;
    end else begin
      srem_q <= srem_d;
      go_q   <= 1'b0;
      tail_q <= {tail_q[1:0], go_q};
      v_b    <= srem_q != '0;
      v_s    <= v_b;
      v_c    <= v_s;
      v_d    <= v_c;
    end
    k_b      <= k_a;
    // B: the window's end from the slot's t0 and end offset
    k_s      <= k_b;
    end_s    <= RW'(win_t0_i) + RW'(win_we_i);
    len_s    <= win_len_i;
    sensor_s <= win_sensor_i;
    // S: its start
    k_c      <= k_s;
    start_c  <= end_s - RW'(len_s);
    end_c    <= end_s;
    sensor_c <= sensor_s;
    // C: overlaps, retries, the close tick and its distance after TA
    k_d      <= k_c;
    sensor_d <= sensor_c;
    rel_b_d  <= rel_b_c;
    rel_w_d  <= rel_w_c;
    ov_b_d   <= bon_q && $signed(rel_b_c) > 0 && $signed(start_c - tb_q) < 0;
    ov_w_d   <= won_q && $signed(rel_w_c) > 0 && $signed(start_c - twb_q) < 0;
    crel_d   <= end_c - tal_q;
  end

  // D: fold the slot into the results (two-process: next from current, then registers)
  // (two candidates' difference fits RW bits: both are ends after TA or TWA; two close
  // distances' may not, so they compare on RW + 1 bits)
  rt_t         best_q, best_d, crel_q, crel_dd, cand;
  logic [31:0] mask_q, mask_d;
  logic [KW-1:0] hit_k_q, hit_k_d, min_k_q, min_k_d;
  logic        any_q, any_d, seen_q, seen_d;
  always_comb begin
    best_d  = best_q;
    any_d   = any_q;
    hit_k_d = hit_k_q;
    crel_dd = crel_q;
    min_k_d = min_k_q;
    seen_d  = seen_q;
    mask_d  = mask_q;
    cand    = (ov_b_d && (!ov_w_d || bwin_q)) ? rel_b_d : rel_w_d;
    if (v_d) begin
      if (ov_b_d || ov_w_d) begin
        if (!any_q || $signed(cand - best_q) > 0) best_d = cand;
        if (!any_q) hit_k_d = k_d;            // EDGE: the one slot holding TA
        any_d = 1'b1;
      end
      if (!seen_q || $signed({crel_d[RW-1], crel_d}) < $signed({crel_q[RW-1], crel_q})) begin
        crel_dd = crel_d;
        min_k_d = k_d;
      end
      seen_d = 1'b1;
      if (sensor_d == ta_q[2:0]) mask_d = mask_q | (32'd1 << k_d);
    end
  end
  always_ff @(posedge clk_i) begin
    if (go_i) begin
      any_q  <= 1'b0;
      seen_q <= 1'b0;
      best_q <= '0;
      mask_q <= '0;
      hit_k_q <= '0;
      min_k_q <= '0;
    end else begin
      any_q   <= any_d;
      seen_q  <= seen_d;
      best_q  <= best_d;
      mask_q  <= mask_d;
      hit_k_q <= hit_k_d;
      min_k_q <= min_k_d;
    end
    crel_q <= crel_dd;
  end

  assign busy_o = go_q || srem_q != '0 || v_b || v_s || v_c || v_d || tail_q != '0;
  logic unused_hi;           // the bits above RW of the operands the scan takes modulo 2^RW
  assign unused_hi = ^{tb_i[31:RW], twb_i[31:RW], win_t0_i[31:RW]};
  logic [31:0] best, minc;   // the results on 32 bits: a distance sign-extended, TA + distance
  assign best = 32'($signed(best_q));
  assign minc = seen_q ? ta_q + 32'($signed(crel_q)) : '0;
  always_comb begin
    unique case (mode_q)
      M_CONF:   begin x_o = any_q ? best : '0;        flags_o = {6'd0, full_q, any_q};
                      minc_o = minc; end
      M_EDGE:   begin x_o = any_q ? 32'(hit_k_q) : '0; flags_o = {7'd0, any_q};  minc_o = '0; end
      M_HEAD:   begin x_o = 32'(min_k_q);             flags_o = {7'd0, seen_q}; minc_o = minc; end
      M_SENSOR: begin x_o = mask_q;                   flags_o = '0;             minc_o = '0; end
    endcase
    if (busy_o) flags_o = 8'h80;
  end
endmodule
