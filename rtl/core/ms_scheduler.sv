// ms_scheduler: fast-firing scheduler, window gating, tracking and event words
// (docs/sonar_core.md; behaviour = golden model host/multisonar/fastfiring.py, contract
// docs/fast_firing.md, with the decision lead P = LEAD of section 3.1).
//
// STAGE 1 (what this file implements; a later stage adds the rest in the marked places):
//   - ONE virtual sensor, table entry 0 (any tx group, any rx set, phasing delays from the
//     delay RAM, modes track / init-only, order 0..4, K-miss re-initialisation + quiet rule).
//   - NOT YET: sensors 1..7, per-element reservations (blank_until, window overlap, slot
//     count, earliest-due-first) and therefore deferral; apply_i validation / refusal
//     (cfg_error_o stays 0; the table of entry 0 is latched when enable_i rises);
//     max_echoes_per_window > 1 (only the first edge of a window is reported).
//     A single sensor is only deferred by the model when a pulse's dead zone or window would
//     overlap one of its own pending windows (not in the stage-1 test scenarios, which
//     assert the model never defers).
//
// Timing contract (ticks of clk_i; tick_i[31:0] wraps, all comparisons modulo 2^32):
//   - rise_i[r] high in the cycle with tick_i = T + 1 (the conditioner's strobe register was
//     loaded at tick T): accepted edge of receiver r with timestamp n = T - L,
//     L = 1 + max(glitch_min_i, 1); T is the model's detection tick.
//   - The work of logical tick T (EDGE rx ascending, CLOSE rx ascending, SCHED) is done by
//     one serial engine, in the model's order, a bounded number of clocks after T. A SCHED
//     decision at logical tick T is for the pulse with t0 = T + LEAD; fire_o is high in the
//     cycle with tick_i = t0. The engine needs far fewer than LEAD clocks; if it ever falls
//     LEAD ticks behind, overrun_o rises (sticky) and the output no longer matches the model.
//   - fire_o / fire_* outputs: one-clock strobe in the issue tick t0 (pulse_o with it);
//     element i of fire_mask_o triggers at t0 + fire_delay_o[i].
//   - evt_valid_o / evt_data_o: event words (docs/fast_firing.md section 6) in the golden
//     model's order, at most one per clock, a few clocks after their detection tick.
//
// Storage: window table WIN (pulse slot x receiver: predicted T_E, active, hit) and the
// per-receiver tracking state RXS are arrays with one access per clock (distributed RAM);
// pulse slots (t0, seq, init, epoch) and the per-receiver "head" window (the next window of
// that receiver to close, whose close tick is compared with tick_i) are flops.
module ms_scheduler #(
  parameter int          NUM_CH  = 24,  // ms_layout_pkg::NUM_CH, passed by the top
  parameter int          NUM_VS  = 8,
  parameter int          DELAY_W = 16,
  parameter int unsigned LEAD    = 1024,  // decision lead P, ticks (FastFiringModel decision_lead)
  parameter int          SLOTS   = 8,     // pulses of the sensor with live windows (>= order + 2)
  parameter int          QDEPTH  = 16     // work-queue entries (ticks with edges/closes pending)
) (
  input  logic                           clk_i,
  input  logic                           rst_i,
  input  logic [31:0]                    tick_i,
  input  logic                           enable_i,
  input  logic                           apply_i,
  input  logic [NUM_VS-1:0][NUM_CH-1:0]  vs_tx_mask_i,
  input  logic [NUM_VS-1:0][NUM_CH-1:0]  vs_rx_mask_i,
  input  logic [NUM_VS-1:0][1:0]         vs_mode_i,
  input  logic [NUM_VS-1:0][2:0]         vs_order_i,
  input  logic [NUM_VS-1:0][3:0]         vs_miss_limit_i,
  input  logic [NUM_VS-1:0][15:0]        vs_t_v_i,
  input  logic [NUM_VS-1:0][15:0]        vs_t_n_i,
  input  logic [NUM_VS-1:0][19:0]        vs_t_dead_i,
  input  logic [NUM_VS-1:0][23:0]        vs_max_tof_i,
  input  logic [NUM_VS-1:0][19:0]        vs_t_xtalk_i,
  input  logic [NUM_VS-1:0][1:0]         vs_xtalk_nb_i,
  input  logic [NUM_VS-1:0][15:0]        vs_vmax_i,
  input  logic [NUM_VS-1:0][7:0]         vs_burst_cycles_i,
  input  logic [NUM_VS-1:0][23:0]        vs_phase_i,
  input  logic [7:0]                     glitch_min_i,
  output logic [7:0]                     delay_raddr_o,
  input  logic [DELAY_W-1:0]             delay_rdata_i,
  input  logic [NUM_CH-1:0]              rise_i,
  output logic                           fire_o,
  output logic [2:0]                     fire_vs_o,
  output logic [NUM_CH-1:0]              fire_mask_o,
  output logic [NUM_CH-1:0][DELAY_W-1:0] fire_delay_o,
  output logic [7:0]                     fire_burst_cycles_o,
  output logic                           evt_valid_o,
  output logic [63:0]                    evt_data_o,
  output logic                           pulse_o,
  output logic                           running_o,
  output logic [3:0]                     cfg_error_o,
  output logic [3:0]                     cfg_error_vs_o,
  output logic                           overrun_o       // sticky: engine late or queue overflow
);
  localparam int SW  = $clog2(SLOTS);
  localparam int RW  = 5;                 // receiver index width (event field)
  localparam int WI  = SW + RW;           // window-table index {slot, rx}
  localparam int QW  = 32 + 2 * NUM_CH;   // work-queue word {tick, edges, closes}
  localparam logic [31:0] LEAD32 = 32'(LEAD);

  // ------------------------------------------------------------------ configuration (entry 0)
  logic [NUM_CH-1:0]              tx_mask_q, rx_mask_q;
  logic [1:0]                     mode_q;
  logic [2:0]                     order_q;
  logic [3:0]                     klim_q;
  logic [15:0]                    tv_q, tn_q, vmax_q;
  logic [23:0]                    rmax_q;      // R = MAX_TOF
  logic [23:0]                    dblank_q;    // D = max(T_dead, T_xtalk) + max delay
  logic [19:0]                    dead_q;
  logic [7:0]                     burst_q;
  logic [NUM_CH-1:0][DELAY_W-1:0] delay_q;
  logic [DELAY_W-1:0]             dmax_q;
  logic [5:0]                     cfg_cnt_q;

  // ------------------------------------------------------------------ sensor state
  logic [31:0]      due_q, quiet_q, start_tick_q;
  logic             quiet_vld_q, tracking_q, in_init_q, epoch_q;
  logic [7:0]       seq_q;
  logic [RW:0]      init_open_q;
  logic [NUM_CH-1:0] tracked_q;

  // pulse slots (indexed by seq mod SLOTS)
  logic [SLOTS-1:0]       sl_valid_q, sl_init_q, sl_epoch_q;
  logic [SLOTS-1:0][31:0] sl_t0_q;
  logic [SLOTS-1:0][7:0]  sl_seq_q;

  // window table: {te[23:0], active, hit}
  typedef struct packed {
    logic [23:0] te;
    logic        act;
    logic        hit;
  } win_t;
  win_t win_q [2**WI];

  // per-receiver tracking state
  typedef struct packed {
    logic [23:0]        tof;
    logic [7:0]         seq;
    logic signed [16:0] v;
    logic [3:0]         miss;
    logic               init;
  } rxs_t;
  rxs_t rxs_q [NUM_CH];

  // head window per receiver (next to close)
  logic [NUM_CH-1:0]          head_vld_q;
  logic [NUM_CH-1:0][SW-1:0]  head_slot_q;
  logic [NUM_CH-1:0][31:0]    head_close_q;

  // fire staging
  logic        fire_pend_q, fire_q, ovr_q;
  logic [31:0] fire_t0_q;

  // events
  logic        evt_valid_q;
  logic [63:0] evt_data_q;

  // ------------------------------------------------------------------ engine
  typedef enum logic [3:0] {
    S_OFF, S_CFG, S_IDLE, S_DISP, S_EDGE, S_HIT, S_CLOSE, S_HEAD, S_SCHED, S_ISSUE, S_ORDER, S_COMMIT
  } state_t;
  state_t st_q;

  logic [31:0]       eng_tick_q, cur_tick_q, t0_q;
  logic [NUM_CH-1:0] edges_q, closes_q;
  logic [SW-1:0]     scan_q, fslot_q;
  logic [SW:0]       hscan_q;
  logic [RW-1:0]     ir_q;          // receiver counter in ISSUE
  logic [RW-1:0]     cr_q;          // receiver being closed (head scan)
  logic [23:0]       te_min_q, te_max_q;
  logic [2:0]        n_q;
  logic [23:0]       period_q;

  // latency L = 1 + max(glitch_min, 1)
  logic [8:0] lat;
  assign lat = 9'd1 + ((glitch_min_i == 8'd0) ? 9'd1 : {1'b0, glitch_min_i});

  // ---- work queue: one word per tick with an edge (of an rx of the sensor) or a close
  logic [NUM_CH-1:0] close_now, edge_now;
  logic [31:0]       tick_prev;
  logic              q_push, q_pop, q_empty, q_ovf;
  logic [QW-1:0]     q_head;
  logic              running;

  assign running = (st_q != S_OFF) && (st_q != S_CFG);
  for (genvar r = 0; r < NUM_CH; r++) begin : g_close
    assign close_now[r] = head_vld_q[r] && (head_close_q[r] == tick_prev);
  end
  // rise_i was loaded at the edge ending cycle tick_i - 1: its detection tick is tick_i - 1
  // (docs/sonar_core.md tick convention); closes are looked up for the same tick.
  assign tick_prev = tick_i - 32'd1;
  assign edge_now  = rise_i & rx_mask_q;
  assign q_push   = running && ((|edge_now) || (|close_now));

  ms_sched_workq #(.WIDTH(QW), .DEPTH(QDEPTH)) u_workq (
    .clk_i     (clk_i),
    .rst_i     (rst_i || !running),
    .push_i    (q_push),
    .data_i    ({tick_prev, edge_now, close_now}),
    .pop_i     (q_pop),
    .head_o    (q_head),
    .empty_o   (q_empty),
    .overflow_o(q_ovf)
  );

  logic [31:0]       qh_tick;
  logic [NUM_CH-1:0] qh_edges, qh_closes;
  assign {qh_tick, qh_edges, qh_closes} = q_head;

  // ---- next time-driven decision tick Td = eng_tick + max(0, due-P-eng, quiet-P-eng)
  logic signed [31:0] dd, qq, td_off;
  logic [31:0]        td;
  logic               armed;
  always_comb begin
    dd = $signed(due_q - LEAD32 - eng_tick_q);
    qq = $signed(quiet_q - LEAD32 - eng_tick_q);
    td_off = 32'sd0;
    if (dd > td_off) td_off = dd;
    if (!tracking_q && quiet_vld_q && qq > td_off) td_off = qq;
    td = eng_tick_q + 32'(td_off);
  end
  assign armed = running && !in_init_q;

  logic take_q;  // IDLE: the queue head comes before the next time-driven decision
  assign take_q = !q_empty && (!armed || ($signed(qh_tick - td) <= 0));
  assign q_pop  = (st_q == S_IDLE) && take_q;

  // ---- lowest set bit
  function automatic logic [RW-1:0] lsb_idx(input logic [NUM_CH-1:0] v);
    lsb_idx = '0;
    for (int i = NUM_CH - 1; i >= 0; i--) if (v[i]) lsb_idx = RW'(i);
  endfunction

  logic [RW-1:0] er, clr;
  assign er  = lsb_idx(edges_q);
  assign clr = lsb_idx(closes_q);

  // ---- window bounds of (slot s, te) as offsets from t0
  function automatic logic [23:0] ws_off(input logic init, input logic [23:0] te,
                                         input logic [23:0] dbl, input logic [15:0] tv);
    ws_off = init ? dbl : te - 24'(tv);
  endfunction
  function automatic logic [23:0] we_off(input logic init, input logic [23:0] te,
                                         input logic [23:0] rmax, input logic [15:0] tn);
    we_off = init ? rmax : te + 24'(tn);
  endfunction

  // ---- EDGE: window of receiver er in slot scan_q
  logic [31:0] n_edge;
  win_t        we_w;
  logic [31:0] e_ws, e_we;
  logic        e_match;
  assign n_edge = cur_tick_q - 32'(lat);
  assign we_w   = win_q[{scan_q, er}];
  assign e_ws   = sl_t0_q[scan_q] + 32'(ws_off(sl_init_q[scan_q], we_w.te, dblank_q, tv_q));
  assign e_we   = sl_t0_q[scan_q] + 32'(we_off(sl_init_q[scan_q], we_w.te, rmax_q, tn_q));
  assign e_match = sl_valid_q[scan_q] && we_w.act && ($signed(n_edge - e_ws) >= 0)
                   && ($signed(n_edge - e_we) < 0);

  // ---- HIT: first edge of window (fslot_q, er)
  win_t        hw;
  rxs_t        hrx;
  logic [23:0] h_tof;
  logic [7:0]  h_gap;
  logic signed [24:0] h_dv;
  logic signed [16:0] h_v;
  assign hw    = win_q[{fslot_q, er}];
  assign hrx   = rxs_q[er];
  assign h_tof = 24'(n_edge - sl_t0_q[fslot_q]);
  assign h_gap = sl_seq_q[fslot_q] - hrx.seq;
  assign h_dv  = $signed({1'b0, h_tof}) - $signed({1'b0, hrx.tof});
  always_comb begin
    if (h_dv > $signed({9'd0, vmax_q}))       h_v = $signed({1'b0, vmax_q});
    else if (h_dv < -$signed({9'd0, vmax_q})) h_v = -$signed({1'b0, vmax_q});
    else                                      h_v = 17'(h_dv);
  end

  // ---- CLOSE: head window of receiver clr
  logic [SW-1:0] c_slot;
  win_t          cw;
  rxs_t          crx;
  logic [23:0]   c_weo;
  logic          c_valid;
  logic [3:0]    c_miss;
  assign c_slot  = head_slot_q[clr];
  assign cw      = win_q[{c_slot, clr}];
  assign crx     = rxs_q[clr];
  assign c_weo   = we_off(sl_init_q[c_slot], cw.te, rmax_q, tn_q);
  assign c_valid = head_vld_q[clr] && sl_valid_q[c_slot] && cw.act
                   && (sl_t0_q[c_slot] + 32'(c_weo) - 32'd1 + 32'(lat) == cur_tick_q);
  assign c_miss  = (crx.miss == 4'hF) ? 4'hF : crx.miss + 4'd1;

  // ---- HEAD: next live window of receiver cr_q after slot fslot_q
  logic [SW-1:0] hs_slot;
  win_t          hs_w;
  assign hs_slot = fslot_q + hscan_q[SW-1:0];
  assign hs_w    = win_q[{hs_slot, cr_q}];

  // ---- SCHED condition at logical tick cur_tick_q
  logic [31:0] t0_cand;
  logic        sched_ok;
  assign t0_cand  = cur_tick_q + LEAD32;
  assign sched_ok = !in_init_q && ($signed(t0_cand - due_q) >= 0)
                    && (tracking_q || !quiet_vld_q || ($signed(t0_cand - quiet_q) >= 0));

  // ---- ISSUE: prediction for receiver ir_q of pulse seq_q
  logic [SW-1:0] i_slot;
  rxs_t          irx;
  logic [7:0]    i_gap;
  logic signed [26:0] i_pred;
  logic [23:0]   i_lo, i_hi, i_te;
  logic          i_act;
  assign i_slot = seq_q[SW-1:0];
  assign irx    = rxs_q[ir_q];
  assign i_gap  = seq_q - irx.seq;
  assign i_pred = $signed({3'd0, irx.tof}) + $signed({1'b0, i_gap}) * irx.v;
  assign i_lo   = dblank_q + 24'(tv_q);
  assign i_hi   = rmax_q - 24'(tn_q);
  always_comb begin
    if (i_pred < $signed({3'd0, i_lo}))      i_te = i_lo;
    else if (i_pred > $signed({3'd0, i_hi})) i_te = i_hi;
    else                                     i_te = i_pred[23:0];
  end
  assign i_act = rx_mask_q[ir_q] && (!tracking_q ? 1'b1 : tracked_q[ir_q]);

  // ---- ORDER: T_s = floor((te_min - T_V - D) / n), feasible if T_s > 0 and (n+1) T_s >= te_max + T_N
  logic [23:0] o_x, o_ts;
  logic [49:0] o_mul3;
  logic [26:0] o_lhs, o_rhs;
  logic        o_feas;
  assign o_x    = te_min_q - 24'(tv_q) - dblank_q;
  assign o_mul3 = 50'(o_x) * 50'd11184811;  // ceil(2^25 / 3): exact floor(x / 3) for x < 2^25
  always_comb begin
    unique case (n_q)
      3'd1:    o_ts = o_x;
      3'd2:    o_ts = o_x >> 1;
      3'd3:    o_ts = o_mul3[48:25];
      default: o_ts = o_x >> 2;
    endcase
  end
  assign o_lhs  = 27'(o_ts) * 27'({24'd0, n_q} + 27'd1);
  assign o_rhs  = 27'(te_max_q) + 27'(tn_q);
  assign o_feas = (o_ts != 24'd0) && (o_lhs >= o_rhs);

  assign delay_raddr_o = {3'd0, cfg_cnt_q[RW-1:0]};  // entry 0 * 32 + element
  logic [RW-1:0] cfg_el;  // element whose delay is on delay_rdata_i
  assign cfg_el = cfg_cnt_q[RW-1:0] - RW'(1);

  always_ff @(posedge clk_i) begin
    evt_valid_q <= 1'b0;
    fire_q      <= 1'b0;
    if (rst_i) begin
      st_q        <= S_OFF;
      fire_pend_q <= 1'b0;
      ovr_q       <= 1'b0;
      head_vld_q  <= '0;
      sl_valid_q  <= '0;
      tracked_q   <= '0;
      cfg_cnt_q   <= '0;
    end else begin
      // ---- fire exactly in tick t0 (registered: loaded in tick t0 - 1)
      if (fire_pend_q && (fire_t0_q - tick_i == 32'd1)) begin
        fire_q      <= 1'b1;
        fire_pend_q <= 1'b0;
      end
      if (q_ovf) ovr_q <= 1'b1;

      if (!enable_i) begin
        st_q        <= S_OFF;
        fire_pend_q <= 1'b0;
        head_vld_q  <= '0;
        sl_valid_q  <= '0;
      end else begin
        unique case (st_q)
          S_OFF: begin  // STAGE 1: entry 0 is taken when enable rises (apply_i: later stage)
            tx_mask_q    <= vs_tx_mask_i[0];
            rx_mask_q    <= vs_rx_mask_i[0];
            mode_q       <= vs_mode_i[0];
            order_q      <= vs_order_i[0];
            klim_q       <= vs_miss_limit_i[0];
            tv_q         <= vs_t_v_i[0];
            tn_q         <= vs_t_n_i[0];
            dead_q       <= (vs_t_dead_i[0] > vs_t_xtalk_i[0]) ? vs_t_dead_i[0] : vs_t_xtalk_i[0];
            rmax_q       <= vs_max_tof_i[0];
            vmax_q       <= vs_vmax_i[0];
            burst_q      <= vs_burst_cycles_i[0];
            start_tick_q <= tick_i;
            eng_tick_q   <= tick_i;
            due_q        <= tick_i + 32'(vs_phase_i[0]);
            quiet_vld_q  <= 1'b0;
            tracking_q   <= 1'b0;
            in_init_q    <= 1'b0;
            epoch_q      <= 1'b0;
            seq_q        <= '0;
            tracked_q    <= '0;
            dmax_q       <= '0;
            cfg_cnt_q    <= '0;
            st_q         <= (vs_mode_i[0] == 2'd0) ? S_OFF : S_CFG;
          end
          S_CFG: begin  // read the phasing delays of entry 0 (data one clock after the address)
            cfg_cnt_q <= cfg_cnt_q + 6'd1;
            if (cfg_cnt_q != 6'd0 && cfg_cnt_q <= 6'(NUM_CH)) begin
              delay_q[cfg_el] <= tx_mask_q[cfg_el] ? delay_rdata_i : '0;
              if (tx_mask_q[cfg_el] && delay_rdata_i > dmax_q) dmax_q <= delay_rdata_i;
            end
            if (cfg_cnt_q == 6'(NUM_CH + 1)) begin
              dblank_q <= 24'(dead_q) + 24'(dmax_q);
              st_q     <= S_IDLE;
            end
          end
          S_IDLE: begin
            if (take_q) begin
              cur_tick_q <= qh_tick;
              edges_q    <= qh_edges;
              closes_q   <= qh_closes;
              st_q       <= S_DISP;
            end else if (armed && ($signed(tick_i - td) >= 3)) begin
              cur_tick_q <= td;
              st_q       <= S_SCHED;
            end
          end
          S_DISP: begin
            scan_q <= '0;
            if (edges_q != '0)       st_q <= S_EDGE;
            else if (closes_q != '0) st_q <= S_CLOSE;
            else                     st_q <= S_SCHED;
          end
          S_EDGE: begin
            if (e_match) begin
              fslot_q <= scan_q;
              st_q    <= S_HIT;
            end else if (scan_q == SW'(SLOTS - 1)) begin
              edges_q[er] <= 1'b0;  // outside every window: gated
              st_q        <= S_DISP;
            end else begin
              scan_q <= scan_q + 1'b1;
            end
          end
          S_HIT: begin
            edges_q[er] <= 1'b0;
            st_q        <= S_DISP;
            if (!hw.hit) begin  // max_echoes_per_window = 1: later edges of the window dropped
              win_q[{fslot_q, er}] <= '{te: hw.te, act: hw.act, hit: 1'b1};
              evt_valid_q <= 1'b1;
              evt_data_q  <= {20'd0, sl_init_q[fslot_q], 1'b0, 1'b1, 1'b1, 3'd0,
                              sl_seq_q[fslot_q], er, h_tof};
              if (sl_epoch_q[fslot_q] == epoch_q) begin
                if (sl_init_q[fslot_q]) begin
                  tracked_q[er] <= 1'b1;
                  rxs_q[er]     <= '{tof: h_tof, seq: sl_seq_q[fslot_q], v: 17'sd0, miss: 4'd0, init: 1'b1};
                end else if (tracked_q[er] && h_gap != 8'd0 && !h_gap[7]) begin
                  rxs_q[er] <= '{tof: h_tof, seq: sl_seq_q[fslot_q],
                                 v: (h_gap == 8'd1 && !hrx.init) ? h_v : 17'sd0,
                                 miss: 4'd0, init: 1'b0};
                end
              end
            end
          end
          S_CLOSE: begin
            closes_q[clr] <= 1'b0;
            if (!c_valid) begin
              st_q <= S_DISP;  // cancelled by a re-initialisation
            end else begin
              win_q[{c_slot, clr}] <= '{te: cw.te, act: 1'b0, hit: cw.hit};
              fslot_q <= c_slot;
              cr_q    <= clr;
              hscan_q <= (SW + 1)'(1);
              st_q    <= S_HEAD;
              if (!cw.hit) begin
                evt_valid_q <= 1'b1;
                evt_data_q  <= {20'd0, sl_init_q[c_slot], 1'b1, 1'b0, 1'b0, 3'd0,
                                sl_seq_q[c_slot], clr, c_weo};
                if (!sl_init_q[c_slot] && sl_epoch_q[c_slot] == epoch_q) begin
                  rxs_q[clr] <= '{tof: crx.tof, seq: crx.seq, v: crx.v, miss: c_miss, init: crx.init};
                  if (c_miss >= klim_q && tracking_q) begin
                    // safety: re-initialise now; every window of the sensor is cancelled
                    tracking_q <= 1'b0;
                    if ($signed(cur_tick_q - due_q) < 0) due_q <= cur_tick_q;
                    sl_valid_q <= '0;
                    head_vld_q <= '0;
                  end
                end
              end
              if (sl_init_q[c_slot] && sl_epoch_q[c_slot] == epoch_q) begin
                init_open_q <= init_open_q - 1'b1;
                if (init_open_q == (RW + 1)'(1)) begin
                  in_init_q  <= 1'b0;
                  // tracked_q may gain this tick's samples already written (EDGE before CLOSE)
                  tracking_q <= (mode_q == 2'd1) && (|tracked_q);
                end
              end
            end
          end
          S_HEAD: begin  // next live window of receiver cr_q, in pulse order
            if (sl_valid_q[hs_slot] && hs_w.act) begin
              head_slot_q[cr_q]  <= hs_slot;
              head_close_q[cr_q] <= sl_t0_q[hs_slot]
                                    + 32'(we_off(sl_init_q[hs_slot], hs_w.te, rmax_q, tn_q))
                                    - 32'd1 + 32'(lat);
              st_q <= S_DISP;
            end else if (hscan_q == (SW + 1)'(SLOTS - 1)) begin
              head_vld_q[cr_q] <= 1'b0;
              st_q <= S_DISP;
            end else begin
              hscan_q <= hscan_q + 1'b1;
            end
          end
          S_SCHED: begin
            if (sched_ok) begin
              t0_q     <= t0_cand;
              ir_q     <= '0;
              te_min_q <= '1;
              te_max_q <= '0;
              sl_valid_q[i_slot] <= 1'b0;
              sl_t0_q[i_slot]    <= t0_cand;
              sl_seq_q[i_slot]   <= seq_q;
              sl_init_q[i_slot]  <= !tracking_q;
              sl_epoch_q[i_slot] <= tracking_q ? epoch_q : !epoch_q;
              if (!tracking_q) begin  // init ping: new epoch, every receiver untracked
                epoch_q     <= !epoch_q;
                tracked_q   <= '0;
                in_init_q   <= 1'b1;
                init_open_q <= '0;
              end
              st_q <= S_ISSUE;
            end else begin
              eng_tick_q <= cur_tick_q + 32'd1;
              st_q       <= S_IDLE;
            end
          end
          S_ISSUE: begin  // one receiver per clock: its window in this pulse
            win_q[{i_slot, ir_q}] <= '{te: i_te, act: i_act, hit: 1'b0};
            if (i_act) begin
              if (sl_init_q[i_slot]) begin
                init_open_q <= init_open_q + 1'b1;
              end else begin
                if (i_te < te_min_q) te_min_q <= i_te;
                if (i_te > te_max_q) te_max_q <= i_te;
              end
              if (!head_vld_q[ir_q]) begin
                head_vld_q[ir_q]   <= 1'b1;
                head_slot_q[ir_q]  <= i_slot;
                head_close_q[ir_q] <= t0_q
                                      + 32'(we_off(sl_init_q[i_slot], i_te, rmax_q, tn_q))
                                      - 32'd1 + 32'(lat);
              end
            end
            ir_q <= ir_q + 1'b1;
            if (ir_q == RW'(NUM_CH - 1)) begin
              n_q  <= order_q;
              st_q <= S_ORDER;
            end
          end
          S_ORDER: begin  // effective order: n = N, N-1, ..., 1, else 0 (one try per clock)
            if (sl_init_q[i_slot]) begin
              period_q <= rmax_q;
              st_q     <= S_COMMIT;
            end else if (n_q == 3'd0) begin
              period_q <= te_max_q + 24'(tn_q);
              st_q     <= S_COMMIT;
            end else if (o_feas) begin
              period_q <= o_ts;
              st_q     <= S_COMMIT;
            end else begin
              n_q <= n_q - 3'd1;
            end
          end
          S_COMMIT: begin
            sl_valid_q[i_slot] <= 1'b1;
            due_q       <= t0_q + 32'(period_q);
            quiet_q     <= t0_q + 32'(rmax_q) - 32'(dblank_q);
            quiet_vld_q <= 1'b1;
            seq_q       <= seq_q + 8'd1;
            fire_pend_q <= 1'b1;
            fire_t0_q   <= t0_q;
            if ($signed(t0_q - tick_i) < 2 || fire_pend_q) ovr_q <= 1'b1;  // engine too late
            eng_tick_q  <= cur_tick_q + 32'd1;
            st_q        <= S_IDLE;
          end
          default: st_q <= S_OFF;
        endcase
      end
    end
  end

  // ---- outputs
  assign fire_o              = fire_q;
  assign pulse_o             = fire_q;
  assign fire_vs_o           = 3'd0;
  assign fire_mask_o         = tx_mask_q;
  assign fire_delay_o        = delay_q;
  assign fire_burst_cycles_o = burst_q;
  assign evt_valid_o         = evt_valid_q;
  assign evt_data_o          = evt_data_q;
  assign running_o           = running;
  assign cfg_error_o         = 4'd0;  // STAGE 1: no apply-time validation yet
  assign cfg_error_vs_o      = 4'd0;
  assign overrun_o           = ovr_q;

  // STAGE 1: sensors 1..7, crosstalk neighbours and apply_i are used by the later stage
  logic unused_ok;
  assign unused_ok = ^{apply_i, vs_xtalk_nb_i, start_tick_q, vs_tx_mask_i[NUM_VS-1:1],
                       vs_rx_mask_i[NUM_VS-1:1], vs_mode_i[NUM_VS-1:1], vs_order_i[NUM_VS-1:1],
                       vs_miss_limit_i[NUM_VS-1:1], vs_t_v_i[NUM_VS-1:1], vs_t_n_i[NUM_VS-1:1],
                       vs_t_dead_i[NUM_VS-1:1], vs_max_tof_i[NUM_VS-1:1], vs_t_xtalk_i[NUM_VS-1:1],
                       vs_vmax_i[NUM_VS-1:1], vs_burst_cycles_i[NUM_VS-1:1], vs_phase_i[NUM_VS-1:1],
                       o_mul3[49], o_mul3[24:0], i_pred[26:24],
                       we_w.hit, hs_w.hit, hrx.v, hrx.miss, irx.miss, irx.init};
endmodule
