// ms_scheduler: fast-firing scheduler of up to NUM_VS virtual sensors, window gating,
// tracking and event words (docs/sonar_core.md; behaviour = golden model
// host/multisonar/fastfiring.py, contract docs/fast_firing.md, decision lead P = LEAD of
// section 3.1).
//
// What it does, in the model's terms: every virtual sensor of the applied table issues init
// pings and interlaced tracking pulses; every element holds up to WSLOTS reserved windows
// (any sensor) and a blank_until register; a candidate pulse issues only if its dead zones,
// crosstalk blanking and windows clear the reservations of the elements it touches and no
// sensor sharing an element is pending with an earlier (due, id) and its tx elements' triggers
// come after their previous dead zones (tx_until, section 5); otherwise it is
// deferred to the first tick the conflicts seen are over. K empty windows in a row cancel all
// windows of the sensor and send an init ping (the safety rule).
//
// Configuration: apply_i (CTRL.apply) or a rising enable_i has ms_sched_cfg check the CSR
// table (vs_raddr_o, delay_raddr_o). A refused table leaves everything as it was and reports
// cfg_error_o (codes: docs/protocol.md section 5) and cfg_error_vs_o; for an accepted one
// ms_sched_cfg loads the per-sensor state, the share matrix and the SNS RAM's blank offsets
// and the schedule (re)starts: an apply while running first finishes every logical tick
// before the apply tick, then drops all windows (no events for them; triggers already armed
// still fire) and starts afresh.
//
// Timing contract (ticks of clk_i; tick_i[31:0] wraps, every comparison is modulo 2^32):
//   - tick_i counts up by one every clock (the sonar core's free-running tick counter).
//   - rise_i[r] high in the cycle with tick_i = T + 1: accepted edge of receiver r with
//     timestamp n = T - L, L = 1 + max(glitch_min_i, 1); T is the model's detection tick.
//   - Start: running_o rises in the cycle after the start tick S (model start_tick = S).
//   - The work of logical tick T (EDGE rx ascending, CLOSE rx ascending, SCHED sensors
//     ascending) is done by one serial engine a bounded number of clocks after T; a SCHED
//     decision at T is for the pulse with t0 = T + LEAD. If the engine ever falls so far
//     behind that a trigger would be late, or its work queue overflows, overrun_o rises
//     (sticky) and the output no longer matches the model.
//   - pulse_o: one-clock strobe per issued pulse, in the cycle of its decision (before t0),
//     with pulse_vs_o / pulse_seq_o / pulse_t0_o / pulse_init_o.
//   - trig_valid_o: one element per clock, registered: element trig_el_o must be triggered
//     trig_delay_o ticks after the tick of this cycle (ms_tx_phaser fire with a one-hot mask),
//     i.e. at t0 + its phasing delay; trig_burst_o = the sensor's burst cycles.
//   - evt_valid_o / evt_data_o: event words (docs/fast_firing.md section 6) in the golden
//     model's order, at most one per clock, a few clocks after their detection tick; the
//     pulse record of every issued pulse (bit 62) in its decision's SCHED phase, a cancel
//     record (bits 62, 61) where a re-initialisation cancels a sensor's windows.
//
// Storage: per-element window slots (WIN: t0, offsets, seq, epoch, init) and the sensor RAM
// (SNS: per (sensor, receiver) tracking state, per (sensor, element) blank offsets and the
// applied table's words per sensor), each with one registered read and one write port (block
// RAM on the FPGA). Per element (one word each):
// slot valid, hit and gated bits, slot sensors, head slot, blank_until and tx_until in
// distributed RAM (a flop per element says whether its valid bits, blank_until and tx_until
// were written since the start, so a start clears them at once), the low bits of the head's
// close tick in flops (compared every clock; IEL reads the whole tick from the head's slot);
// every per-element array has one read and one write port, at the element the engine state
// works on (ei), so the logic per element is a clock enable. A safety cancel clears the
// sensor's slots one element per clock (S_SAFE, NUM_CH clocks). Per sensor, due,
// next-evaluation and quiet ticks, pulse ids and counters have one write port (sensor si);
// the start initialises them one sensor per clock (S_INIT).
//
// Pipelining (for Fmax, docs/synthesis.md): every engine state spends need(state) clocks
// reading (ph_q counts them) and decides in its last clock (go); reads and arithmetic go
// through registered stages A-D (see ph_q below), so a decision never follows a RAM read, a
// second RAM read or more than one carry chain in the same clock. A state costs 1-6 clocks per
// item, except the slot scans (S_HEAD, S_CSLOT), which stream one slot per clock; lag_max_q (the engine's worst lateness) is measured by scripts/bench_sched_lag.py.
module ms_scheduler #(
  parameter int NUM_CH  = 24,   // ms_layout_pkg::NUM_CH, passed by the top (<= 32)
  parameter int NUM_VS  = 8,    // table entries (<= 8: 3-bit sensor id)
  parameter int DELAY_W = 16,
  parameter int LEAD    = 4096, // decision lead P, ticks (constants.DEVICE_DECISION_LEAD)
  parameter int WSLOTS  = 16,   // window slots per element (FastFiringModel win_slots)
  parameter int QDEPTH  = 32    // work-queue entries (ticks with edges/closes pending)
) (
  input  logic                           clk_i,
  input  logic                           rst_i,
  input  logic [31:0]                    tick_i,
  input  logic                           enable_i,
  input  logic                           apply_i,
  // the CSR's virtual-sensor table: word entry * 9 + register (TX_MASK 0, RX_MASK 1, MODE 2,
  // WINDOW 3, T_DEAD 4, MAX_TOF 5, XTALK 6, TRACK 7, PHASE 8; sonar_regs.rdl's field
  // positions), read data one clock after the address
  output logic                           vs_ren_o,   // vs_raddr_o is read in this clock
  output logic [6:0]                     vs_raddr_o,
  input  logic [31:0]                    vs_rdata_i,
  input  logic [15:0]                    burst_half_period_i,
  input  logic [7:0]                     glitch_min_i,
  input  logic [15:0]                    miss_gate_i,     // RX_FILTER.miss_gate, ticks (0 off), latched at apply
  output logic [7:0]                     delay_raddr_o,
  input  logic [DELAY_W-1:0]             delay_rdata_i,
  input  logic [NUM_CH-1:0]              rise_i,
  output logic                           trig_valid_o,
  output logic [4:0]                     trig_el_o,
  output logic [DELAY_W:0]               trig_delay_o,
  output logic [7:0]                     trig_burst_o,
  output logic                           pulse_o,
  output logic [2:0]                     pulse_vs_o,
  output logic [NUM_CH-1:0]              pulse_tx_o,     // the sensor's tx elements (for testbenches; unused by the core)
  output logic [7:0]                     pulse_seq_o,
  output logic [31:0]                    pulse_t0_o,
  output logic                           pulse_init_o,
  output logic                           evt_valid_o,
  output logic [63:0]                    evt_data_o,
  output logic                           running_o,
  output logic [3:0]                     cfg_error_o,
  output logic [3:0]                     cfg_error_vs_o,
  output logic                           overrun_o       // sticky: engine late or queue overflow
);
  localparam int RW  = 5;                  // element index width (event field)
  localparam int VW  = 3;                  // sensor index width (event field)
  localparam int KW  = $clog2(WSLOTS);     // slot index width
  localparam int QW  = 32 + 2 * NUM_CH;    // work-queue word {tick, edges, closes}
  localparam int DW  = 19;                 // T_dead / T_xtalk (VS_T_DEAD.ticks, VS_XTALK.t_xtalk)
  localparam int BW  = 20;                 // blank end offset width (delay + T_dead): 36-bit words
  localparam logic [31:0] LEAD32 = 32'(LEAD);
  localparam int MAX_ORDER = 8;            // highest fast-firing order (CAPS.max_order)
  localparam int OW  = 4;                  // order width (VS_MODE.order)
  localparam int RTW = 26;                 // conflict scan: retry t0 - candidate t0 (|x| < 2^25)
  // Sensor indices are VW bits wide everywhere (event fields, pulse_vs_o); the per-sensor
  // storage has NUM_VS entries, addressed by the low SW bits (si): a reduced build (NUM_VS
  // 4 on the 25F) only ever counts sensors up to NUM_VS - 1.
  localparam int SW  = $clog2(NUM_VS);
  if (NUM_VS < 2 || NUM_VS > 8) begin : g_bad_num_vs
    $error("ms_scheduler: NUM_VS = %0d, supported 2..8 (3-bit sensor ids)", NUM_VS);
  end
  if (WSLOTS < 2 || WSLOTS > 16) begin : g_bad_wslots
    $error("ms_scheduler: WSLOTS = %0d, supported 2..16", WSLOTS);
  end
  if (NUM_CH > 31) begin : g_bad_num_ch
    $error("ms_scheduler: NUM_CH = %0d, the pulse record's n_win holds 0..31", NUM_CH);
  end

  // ------------------------------------------------------------------ helpers
  // index of the lowest set bit (0 when none): the bit isolated by v & -v (a carry chain)
  // and encoded by OR trees, not a priority chain of one LUT level per bit
  function automatic logic [RW-1:0] lsb_ch(input logic [NUM_CH-1:0] v);
    logic [NUM_CH-1:0] oh;
    oh     = v & (~v + NUM_CH'(1));
    lsb_ch = '0;
    for (int i = 0; i < NUM_CH; i++) if (oh[i]) lsb_ch = lsb_ch | RW'(i);
  endfunction
  function automatic logic [KW-1:0] lsb_slot(input logic [WSLOTS-1:0] v);
    logic [WSLOTS-1:0] oh;
    oh       = v & (~v + WSLOTS'(1));
    lsb_slot = '0;
    for (int i = 0; i < WSLOTS; i++) if (oh[i]) lsb_slot = lsb_slot | KW'(i);
  endfunction
  function automatic logic [5:0] popcount(input logic [NUM_CH-1:0] v);
    popcount = '0;
    for (int i = 0; i < NUM_CH; i++) popcount = popcount + 6'(v[i]);
  endfunction
  function automatic logic [SW-1:0] si(input logic [VW-1:0] s);  // storage index of sensor s
    logic [VW-1:0] unused_s;  // the bits above SW are zero (sensors count to NUM_VS - 1)
    unused_s = s;
    si       = SW'(s);
  endfunction
  function automatic logic later(input logic [31:0] a, input logic [31:0] b);  // a > b mod 2^32
    later = $signed(a - b) > 0;
  endfunction

  // ------------------------------------------------------------------ shadow configuration
  // The table fields the engine reads for sensor s_q from S_SCHED on (masks, window, max ToF,
  // order, burst, re-init count) and its phase (S_INIT) are the applied table's words, kept in
  // the sensor RAM (SNS, the configuration words below) and fetched one per clock
  // into the s_* registers. Derived fields and those read by another sensor index (HIT,
  // CLOSE) live in distributed RAM (*_m: one write port, written by S_LOAD one sensor per
  // clock; each read index is a copy of the RAM). Flops hold what is read for all sensors.
  logic [NUM_CH-1:0] sh_xt_m    [NUM_VS];  // crosstalk neighbours (ms_sched_cfg)
  logic [23:0]       sh_dbl_m   [NUM_VS];  // blanking max(T_dead, T_xtalk) + max delay
  logic              sh_track_m [NUM_VS];  // mode == track
  logic [3:0]        sh_k_m     [NUM_VS];
  logic [15:0]       sh_vmax_m  [NUM_VS];
  logic [23:0]       sh_lo_m    [NUM_VS];  // prediction clamp: dbl + T_V
  logic [23:0]       sh_hi_m    [NUM_VS];  // ... and max ToF - T_N
  logic [NUM_VS-1:0]             sh_act_q;  // mode != off
  logic [NUM_CH-1:0]             sh_rxany_q;  // receivers of the active sensors
  logic [NUM_VS-1:0][NUM_VS-1:0] sh_share_q;
  logic [15:0]                   sh_gate_q;  // gated miss rule (0 off)
  // The sensor RAM (SNS, declared with the tracking state below) holds, besides the tracking
  // state, the blank interval offsets from t0 of each (sensor, element), [a, b) (tx: delay,
  // delay + T_dead; crosstalk neighbour: first, last tx delay within nb + T_xtalk), and the
  // applied table's words of each sensor as the load read them (sonar_regs.rdl's fields) in
  // word slots CW_*: table registers 0..3, 5, 7 in the slots of their number, PHASE (8) in
  // slot 4; T_DEAD and XTALK only feed derived fields and are not kept.
  typedef struct packed {
    logic [DELAY_W-1:0] a;
    logic [BW-1:0]      b;
  } blk_t;
  localparam int BA = SW + 6;  // SNS address: {0, sensor, receiver} / {0, sensor, CW_BASE + slot} /
                               // {1, sensor, element}
  localparam int CW_BASE = 24;
  localparam logic [2:0] CW_TX = 3'd0, CW_RX = 3'd1, CW_MODE = 3'd2, CW_WIN = 3'd3,
                         CW_PHASE = 3'd4, CW_RMAX = 3'd5, CW_TRACK = 3'd7;
  if (NUM_CH > CW_BASE) begin : g_bad_cw_base
    $error("ms_scheduler: NUM_CH = %0d, the table words sit at receiver %0d up", NUM_CH, CW_BASE);
  end
  function automatic logic [BA-1:0] cw_addr(input logic [VW-1:0] s, input logic [2:0] k);
    cw_addr = {1'b0, si(s), 5'(CW_BASE) + 5'(k)};
  endfunction
  // table register r (TX_MASK 0 .. PHASE 8): kept in SNS (not T_DEAD 4, XTALK 6), and its slot
  function automatic logic cw_kept(input logic [3:0] r);
    cw_kept = r != 4'd4 && r != 4'd6;
  endfunction
  function automatic logic [2:0] cw_slot(input logic [3:0] r);
    cw_slot = (r == 4'd8) ? CW_PHASE : r[2:0];
  endfunction

  // ------------------------------------------------------------------ sensor state
  // due, quiet (max ToF end of the last pulse) and next-evaluation ticks: distributed RAM,
  // one write port each (the per-sensor writes below), read by sensor index and registered
  logic [31:0] due_m [NUM_VS];
  logic [31:0] quiet_m [NUM_VS];
  logic [31:0] nxt_m [NUM_VS];  // as the t0 it decides for: next-evaluation tick + P
  logic [NUM_VS-1:0]       quiet_vld_q, tracking_q, in_init_q, epoch_q, wake_q, hold_q, any_trk_q;
  // pulse id (the events carry its low 8 bits, seq), windows of the init ping still open and
  // tracking pulses since the last init ping (saturating): distributed RAM, one write port
  // each, cleared by S_INIT one sensor per clock
  logic [15:0] seq_m [NUM_VS];
  logic [5:0]  open_m [NUM_VS];
  logic [7:0]  trk_m [NUM_VS];

  typedef struct packed {
    logic               trk;
    logic [23:0]        tof;
    logic [7:0]         seq;
    logic signed [16:0] v;
    logic [3:0]         miss;
    logic               init;
    logic               vel;   // v measured (last sample followed one of the previous pulse): gate on
  } rxs_t;
  // SNS: one block RAM (two DP16KD) for the tracking state of (sensor, receiver) at {0, sensor,
  // receiver}, the table words and the blank intervals (above); one read and one write port
  logic [$bits(rxs_t)-1:0] sns_q [2**BA];

  // ------------------------------------------------------------------ element state
  typedef struct packed {
    logic [31:0] t0;
    logic [23:0] ws;   // window start offset from t0
    logic [23:0] we;   // window end offset from t0 (exclusive)
    logic [7:0]  seq;
    logic        epoch;
    logic        init;
  } win_t;
  win_t win_q [NUM_CH * WSLOTS];
  // one read port per RAM (the address depends on the state), so both map to distributed RAM
  logic [$clog2(NUM_CH * WSLOTS)-1:0] win_ra;
  win_t                               win_rd;
  logic [BA-1:0]                      sns_ra;   // SNS read address (the state's)
  logic [BA-2:0]                      rxs_wa;   // tracking state written: {sensor, receiver}
  logic [$bits(rxs_t)-1:0]            sns_rd;   // SNS word at sns_ra of the clock before
  rxs_t                               rxs_rd;   // ... as tracking state
  logic [35:0]                        cb_raw;   // ... as a table word or blank interval
  assign rxs_rd = rxs_t'(sns_rd);
  assign cb_raw = sns_rd[35:0];
  blk_t                               cb;      // ... as the blank interval of (s_q, rel)
  assign cb = blk_t'(cb_raw);
  win_t                               win_c_q; // stage C copies of the WIN / tracking-state words
  rxs_t                               rxs_c_q;
  // Per-element state has one read and one write port, both at the element the state is
  // working on (ei below): head close ticks in flops (compared every clock), the rest in
  // distributed RAM (32 entries, one word per element) with a written-since-start flop per
  // element where a start must clear it at once (slot valid, blank_until, tx_until).
  logic [WSLOTS-1:0]                     wv_m [32];    // slot valid (when wv_ok_q[e])
  logic [NUM_CH-1:0]                     wv_ok_q;      // else no slot valid
  logic [WSLOTS-1:0]                     wh_m [32];    // slot saw its first edge
  logic [WSLOTS-1:0]                     wr_m [32];    // that edge failed the miss gate (counts as a miss)
  logic [WSLOTS-1:0][VW-1:0]             wsid_m [32];  // sensor of the window
  // blank_until and tx_until are the start tick until written (model: [now] * n): a start
  // tick is earlier than every candidate t0, so an unwritten word conflicts with nothing and
  // any t0 + b is later; the compares that read them are gated by the flags instead of
  // multiplexing the start tick into the words
  logic [31:0]                           bu_m [32];    // blank_until (when bu_ok_q[e])
  logic [NUM_CH-1:0]                     bu_ok_q;
  logic [31:0]                           tu_m [32];    // tx_until: end of the dead zone of the last trigger (when tu_ok_q[e])
  logic [NUM_CH-1:0]                     tu_ok_q;
  logic [NUM_CH-1:0]                     hd_vld_q;     // head: next window to close
  logic [KW-1:0]                         hd_slot_m [32];
  // Close tick of the element's head for close_eq_q: its low HCW bits (the engine reads the
  // full 32 bits from the head slot's WIN word). A head is written with a close tick at most
  // 2^24 (window
  // end offset) + LEAD + the engine's lag after the write tick, so tick_i reaches it within
  // 2^(HCW-1) ticks: the low bits match there first (checked in simulation below). A close
  // lost to a work-queue overflow would match again after 2^HCW ticks (1.4 s) instead of 2^32;
  // the overflow is reported as an overrun either way.
  // The HCW bits are split at LB: time runs in blocks of 2^LB ticks (tick_i[HCW-1:LB] is the
  // block). Each element keeps the low LB bits in flops (hd_lo_q) and two flags, "the head's
  // block is the current block" (blk_cur_q) and "... the next block" (blk_nxt_q); the high
  // bits are compared with one shared comparator, at the head write and by a scan that visits
  // element L in the clock with tick_i[LB-1:0] == L (so 2^LB > NUM_CH). At the end of a block
  // blk_cur_q takes blk_nxt_q. The per-clock compare per element is then LB bits and a flag
  // instead of HCW bits (24 x 26-bit compares were ~630 TRELLIS_COMB).
  localparam int HCW = 26;
  localparam int LB  = $clog2(NUM_CH + 1);
  localparam int HBW = HCW - LB;
  logic [NUM_CH-1:0][LB-1:0]             hd_lo_q;
  logic [NUM_CH-1:0]                     blk_cur_q, blk_nxt_q;
  logic [HBW-1:0]                        hd_hi_m [2**LB];      // close tick bits [HCW-1:LB], read by the scan

  // candidate pulse: per receiver predicted T_E and whether it gets a window
  logic [23:0]       cand_te_q [NUM_CH];
  logic              cand_act_m [NUM_CH];  // written for every receiver of s_q by S_CAND
  logic [4:0]        nwin_q;  // S_CAND: windows of the candidate pulse (its record's n_win)

  // ------------------------------------------------------------------ engine
  typedef enum logic [4:0] {
    S_OFF, S_CHECK, S_STOP, S_LOAD, S_START, S_SETTLE, S_IDLE, S_DISP,
    S_EDGE, S_HIT, S_CLOSE, S_HEAD, S_HWR, S_SCHED, S_NEXT, S_EDF, S_CAND, S_ORDER, S_CONF,
    S_CSLOT, S_CFULL, S_ISSUE, S_IEL, S_SAFE, S_INIT
  } state_t;
  state_t st_q;
  // Each engine state reads in its first clocks and decides in its last one (the go clock).
  // Every clock registers: stage A, the per-element words of the element the state works on
  // (and the per-sensor words of s_q / o_q); stage B, the WIN / SNS words addressed by
  // the state and stage A; stage C, window ticks and the prediction from stage B; stage D,
  // the compares on stage C. A state that needs stage X decides once its registers have been
  // stable long enough for X to hold its inputs (need), so no path runs from one RAM's output
  // into another RAM's address, and at most one add and one compare precede a decision.
  // Only the go clock changes state and writes; ph_q counts the clocks before it.
  logic [2:0] ph_q, need;
  logic       go;
  always_comb begin
    unique case (st_q)
      S_EDGE, S_HEAD, S_CSLOT, S_CAND:        need = 3'd0;  // streams: one slot / receiver per clock
      S_ISSUE:                                need = 3'd1;  // per-sensor words
      S_HWR, S_CFULL:                         need = 3'd1;  // the stream's result, registered
      S_STOP:                                 need = 3'd1;  // the miss gate latch's registered enable
      S_INIT:                                 need = 3'd2;  // the sensor's phase, then start + phase
      S_SCHED, S_EDF:                         need = 3'd2;  // per-sensor words, then their compares
      S_DISP, S_SAFE:                         need = 3'd2;  // stage A; two registered steps of arithmetic
      S_ORDER:                                need = 3'd4;  // four registered steps of arithmetic
      S_HIT:                                  need = 3'd6;  // prediction (stage D), gate, decision
      S_CLOSE, S_CONF, S_IEL:
                                              need = 3'd5;  // stage D: compares on stage C
      default:                                need = 3'd0;
    endcase
  end
  assign go = (ph_q == need);

  logic [31:0]       eng_tick_q, cur_tick_q, t_q, minclose_q, stop_at_q;
  logic [RTW-1:0]    retry_q;  // S_CONF .. S_CFULL: the retry t0 - t_q (see the conflict scan)
  logic              retry_vld_q, stop_req_q, started_q, ovr_q, found_q;
  logic [1:0]        stop_age_q;  // clocks since stop_at_q was set (= tick_i - stop_at_q), up to 3
  logic [3:0]        settle_q;   // clocks until td_q is valid again
  // outputs
  logic              evt_valid_q, trig_valid_q, pulse_q, pulse_init_q;
  logic [63:0]       evt_data_q;
  // element indices loaded from the lowest-set-bit encoders: not state machines, but Yosys'
  // fsm pass took trig_el_q for one in the whole system and enumerated 2^29 transitions
  (* fsm_encoding = "none" *) logic [RW-1:0] trig_el_q;
  logic [DELAY_W:0]  trig_delay_q;
  logic [7:0]        trig_burst_q, pulse_seq_q;
  logic [VW-1:0]     pulse_vs_q;
  logic [NUM_CH-1:0] pulse_tx_q;
  logic [31:0]       pulse_t0_q;
  logic [NUM_CH-1:0] edges_q, closes_q, rem_q;
  logic [WSLOTS-1:0] srem_q;
  logic [KW-1:0]     fslot_q;
  (* fsm_encoding = "none" *) logic [RW-1:0] sf_e_q;  // S_SAFE: element being swept
  logic [VW-1:0]     sf_s_q;   // S_SAFE: sensor whose windows are cancelled
  logic              sf_ret_q; // S_SAFE: a forced re-init from S_SCHED (back to S_SCHED), else a close (S_HEAD)
  (* fsm_encoding = "none" *) logic [RW-1:0] el_q;
  logic [VW-1:0]     s_q, o_q;
  logic              blk_on_q, win_on_q;
  logic [23:0]       te_min_q, te_max_q, period_q;
  logic [OW-1:0]     n_q;
  logic [7:0]        kseq_q;

  // configuration
  logic [3:0]        cfg_err_q, cfg_err_vs_q;
  logic              en_q, en_prev_q, apply_pend_q;  // enable_i registered here (it comes from the register block), and one clock later

  // detection latency L = 1 + max(glitch_min_i, 1), and L - 1, registered: glitch_min_i is a
  // configuration register (a change takes effect one clock later), and a registered operand
  // keeps the decode out of the 32-bit adders below
  logic [8:0] lat_q, latm1_q;
  always_ff @(posedge clk_i) begin
    latm1_q <= (glitch_min_i == 8'd0) ? 9'd1 : {1'b0, glitch_min_i};
    lat_q   <= 9'd1 + ((glitch_min_i == 8'd0) ? 9'd1 : {1'b0, glitch_min_i});
  end

  // ---- work queue: one word per tick with an edge (of a receiving element) or a close
  logic [NUM_CH-1:0] close_now, edge_now, rx_any;
  logic [31:0]       tick_prev;
  logic              q_push, q_pop, q_empty, q_ovf, running;
  logic [QW-1:0]     q_head;

  assign running   = started_q;
  // rise_i / closes of this cycle belong to tick_i - 1: tick_i one clock ago (tick_i counts every
  // clock), a register rather than a decrement before the 24 close-tick compares
  always_ff @(posedge clk_i) tick_prev <= tick_i;
  always_comb begin
    rx_any = '0;
    rx_any = sh_rxany_q;
  end
  // The 24 close-tick compares are registered per element: close_eq_q[r] is "the head's close
  // tick (low HCW bits) == tick_i" of the clock before, i.e. == tick_prev now, on the head of the clock before (with
  // tick_prev, fanned out to 768 compare inputs across the chip, they were the board top's
  // slowest path into q_push_q). The same as comparing the current head unless a head is
  // written in the clock before its close tick; every head is written long before it (a new
  // window's close is at least the lead ahead, a rescanned head is a later window of the
  // element), and the simulation check at the per-element writes below stops if one is not.
  logic [NUM_CH-1:0] close_eq_q;
  always_ff @(posedge clk_i)
    for (int r = 0; r < NUM_CH; r++) close_eq_q[r] <= blk_cur_q[r] && hd_lo_q[r] == tick_i[LB-1:0];
  assign close_now = hd_vld_q & close_eq_q;
  assign edge_now = rise_i & rx_any;
  assign q_push   = running && ((|edge_now) || (|close_now));
  // the push is registered (the 24 close compares and the OR of 48 bits do not reach the
  // queue RAM's write enable in the same clock): a word is at the queue head two clocks
  // after its tick's cycle, still within sched_go's three ticks of margin
  logic          q_push_q;
  logic [QW-1:0] q_data_q;
  always_ff @(posedge clk_i) begin
    q_push_q <= q_push;
    q_data_q <= {tick_prev, edge_now, close_now};
  end

  ms_sched_workq #(.WIDTH(QW), .DEPTH(QDEPTH)) u_workq (
    .clk_i     (clk_i),
    .rst_i     (rst_i || !running),
    .push_i    (q_push_q),
    .data_i    (q_data_q),
    .pop_i     (q_pop),
    .head_o    (q_head),
    .empty_o   (q_empty),
    .overflow_o(q_ovf)
  );
  logic [31:0]       qh_tick;
  logic [NUM_CH-1:0] qh_edges, qh_closes;
  assign {qh_tick, qh_edges, qh_closes} = q_head;

  // ---- next time-driven decision tick td = eng_tick + the least offset nxt - eng_tick (0 when
  // due, all-ones when the sensor is not armed) over the sensors, one sensor per clock: the scan
  // restarts at sensor 0 in S_SETTLE (td_s_q is 0 in every other state) and the running
  // minimum is complete NUM_VS + 2 clocks later (registered sensor words, offset, minimum).
  // Nothing changes a sensor's state in S_SETTLE / S_IDLE, so a later minimum still holds.
  // S_SETTLE waits TD_SETTLE clocks for td_q and the IDLE decisions registered from it.
  localparam logic [3:0] TD_SETTLE = 4'(NUM_VS + 3);
  logic [VW-1:0] td_s_q;
  logic          td_on_q, td_wake_q, td_first_q, td_first1_q;
  logic [31:0]   td_off_q, td_acc_q, td_q, engp_q;  // engp_q: eng_tick_q + P
  logic          armed_q;
  // nxt_m has one read port: the scan's sensor in S_SETTLE / S_IDLE, else s_q (S_SCHED reads
  // it); nxt_rd_q is the word one clock later
  logic [VW-1:0] nxt_ra;
  logic [31:0]   nxt_rd_q;
  assign nxt_ra = (st_q inside {S_SETTLE, S_IDLE}) ? td_s_q : s_q;
  always_ff @(posedge clk_i) begin
    td_s_q      <= (st_q inside {S_SETTLE, S_IDLE}) && td_s_q != VW'(NUM_VS - 1) ? td_s_q + 1'b1
                 : (st_q inside {S_SETTLE, S_IDLE}) ? td_s_q : '0;
    // the sensor's words
    td_on_q     <= sh_act_q[si(td_s_q)] && !in_init_q[si(td_s_q)] && (wake_q[si(td_s_q)] || !hold_q[si(td_s_q)]);
    td_wake_q   <= wake_q[si(td_s_q)];
    nxt_rd_q    <= nxt_m[si(nxt_ra)];
    td_first_q  <= st_q == S_SETTLE;  // sensor 0 of a new scan
    // its offset
    engp_q      <= eng_tick_q + LEAD32;  // eng_tick_q changes at least two clocks before a scan reads it
    td_off_q    <= !td_on_q ? 32'hFFFF_FFFF
                 : (td_wake_q || !later(nxt_rd_q, engp_q)) ? 32'd0 : nxt_rd_q - engp_q;
    td_first1_q <= td_first_q;
    // the running minimum, and td
    td_acc_q    <= (td_first1_q || td_off_q < td_acc_q) ? td_off_q : td_acc_q;
    td_q        <= eng_tick_q + td_acc_q;
    armed_q     <= td_acc_q != 32'hFFFF_FFFF;  // an armed sensor's offset is < 2^31
  end

  // IDLE's decisions are registered (one clock behind the queue head, td_q and tick_i), so its
  // go clock starts no compare chain: S_SETTLE waits one clock more for them (TD_SETTLE).
  // A word not yet at the queue head when they were computed (the push is registered too) has
  // tick >= tick_i - 2 > td_q (sched_go needs three ticks of margin), so a stale "queue empty"
  // never lets a decision tick pass a queued edge or close.
  logic take_c, sched_c, stop_c;
  logic take_q;  // IDLE: the queue head comes no later than the next time-driven decision
  assign take_c = !q_empty && (!armed_q || ($signed(qh_tick - td_q) <= 0))
                  && (!stop_req_q || $signed(qh_tick - stop_at_q) < 0);
  logic sched_go;  // IDLE: a time-driven decision tick whose edges and closes are all queued
  assign sched_c = armed_q && ($signed(tick_i - td_q) >= 3) && (q_empty || $signed(qh_tick - td_q) > 0)
                   && (!stop_req_q || $signed(td_q - stop_at_q) < 0);
  logic stop_ok;  // every logical tick before stop_at is done
  assign stop_c = stop_req_q && stop_age_q == 2'd3
                  && (q_empty || $signed(qh_tick - stop_at_q) >= 0)
                  && (!armed_q || $signed(td_q - stop_at_q) >= 0);
  // A dispatch is late when real time is P/2 or more ahead of the logical tick it starts: checked
  // in the clock after IDLE's go (disp_chk_q), where cur_tick_q holds that tick and tick_i is two
  // ticks past the decisions' clock, on one subtraction (tick_i counts by one every clock)
  logic disp_chk_q, lag_late;
  assign lag_late = disp_chk_q && $signed(tick_i - cur_tick_q) >= LEAD / 2 + 2;
  always_ff @(posedge clk_i) begin
    take_q   <= take_c;
    sched_go <= sched_c;
    stop_ok  <= stop_c;
  end
  assign q_pop  = (st_q == S_IDLE) && (settle_q == 4'd0) && !stop_ok && take_q;
  // engine headroom, for the benches (read through the hierarchy, no port): the largest
  // tick_i - cur_tick_q in any clock of engine work since the start, i.e. how late the engine
  // ever was with the work of a logical tick (a trigger is late beyond LEAD; overrun_o rises
  // when a dispatch lags LEAD / 2). How much slower a pipelined engine may be
  // (docs/synthesis.md) is read off this.
  logic        eng_busy;
  logic [31:0] lag_now, lag_max_q;
  assign eng_busy = started_q && !(st_q inside {S_OFF, S_CHECK, S_STOP, S_LOAD, S_START, S_INIT,
                                                 S_SETTLE, S_IDLE});
  assign lag_now  = tick_i - cur_tick_q;
  always_ff @(posedge clk_i) begin
    if (rst_i || st_q == S_START)
      lag_max_q <= '0;
    else if (eng_busy && $signed(lag_now - lag_max_q) > 0)
      lag_max_q <= lag_now;
  end

  // ---- stages C and D (see ph_q): registered every clock from stage B / C and the state
  logic [31:0]        w_start_c_q, w_end_c_q, w_close_c_q;  // WIN word: start, end, close tick
  logic signed [8:0]  gap_c_q;        // pulse gap (HIT: to the window's pulse, CAND: to seq_q)
  logic signed [26:0] pred_d_q;       // tof + gap * v (stage D: gap and multiply a clock each)
  logic [23:0]        lo_c_q, hi_c_q; // prediction clamp of the sensor (EDGE: the window's, else s_q)
  logic [23:0]        h_tof_c_q;      // HIT: the edge's time of flight in the window
  logic [23:0]        c_wso_c_q, c_weo_c_q;  // CONF / IEL: window offsets of receiver rel
  logic [31:0]        ta_c_q, tb_c_q;  // t0 + blank a / b (stage C)
  logic [31:0]        bu_rel_c_q;      // CONF: blank_until - t0 (stage C)
  logic [31:0]        tws_d_q, twe_d_q;  // t0 + window offsets (stage D)
  logic signed [24:0] h_dv_d_q;
  logic [24:0]        h_abs_d_q;
  logic [31:0]        iw_close_d_q;    // IEL: the new window's close tick, t_q + p_weo - 1 + L
  logic [31:0]        tl_q;            // t_q + L - 1
  logic               iw_first_d_q, bu_later_d_q, tu_later_d_q;
  logic [23:0]        te_d_q;          // CAND: the clamped prediction
  logic [31:0]        t_cand_q;        // cur_tick_q + P (the candidate t0 of a SCHED decision)
  logic [31:0]        due_isu_q, due_ini_q, quiet_isu_q;
  // per-sensor words: due of s_q; due of o_q in S_EDF, of c_s_q in S_CLOSE (due_x_q); quiet of
  // o_q in S_EDF, else of s_q (quiet_rd_q); one read port per address, the words one clock later
  logic [31:0]        due_s_q, due_x_q, quiet_rd_q;
  // engine registers and write strobes whose drivers follow further down (declared here,
  // before the views and the FSM that read them)
  logic [NUM_VS-1:0] reinit_due_q;
  logic [NUM_CH-1:0] s_tx_q, s_xt_q;
  logic              nx_go, ps_live, hit_go_q, cls_go_q, start_go_q;
  logic [NUM_VS-1:0] isu_go_q, sch_go_q, edf_go_q, ini_go_q, cnf_go_q;
  logic                      el_clr, wv_we, wh_we, wsid_we, bu_we, tu_we, hd_we, hdv_we, hdv_wd;
  logic [WSLOTS-1:0]         wv_wd, wh_wd, wr_wd, sid_mask;
  logic [WSLOTS-1:0][VW-1:0] wsid_wd;
  logic [31:0]               bu_wd, hd_close_wd;
  logic [KW-1:0]             hd_slot_wd;
  logic [VW-1:0]             sid_kill;

  // ---- per-element / per-slot views
  logic [RW-1:0] er, clr, rel;
  assign er  = lsb_ch(edges_q);
  assign clr = lsb_ch(closes_q);
  assign rel = lsb_ch(rem_q);
  logic [KW-1:0] sk;
  assign sk = lsb_slot(srem_q);
  // a state done with the lowest set bit of a work mask clears it as v & (v - 1): one carry
  // chain instead of a decoder per bit

  // element the state works on: read and write address of every per-element array
  logic [RW-1:0] ei;
  always_comb begin
    unique case (st_q)
      S_DISP, S_EDGE, S_HIT: ei = er;
      S_CLOSE:               ei = clr;
      S_HEAD, S_HWR, S_CSLOT, S_CFULL:
                             ei = el_q;
      S_SAFE:                ei = sf_e_q;
      default:               ei = rel;  // S_CONF, S_IEL
    endcase
  end
  logic [WSLOTS-1:0]         wv_e, wh_e, wr_e;
  logic [WSLOTS-1:0][VW-1:0] wsid_e;
  logic [31:0]               bu_e, tu_e;
  logic                      bu_ok_e, tu_ok_e;  // bu_e / tu_e written since the start
  logic [KW-1:0]             hd_slot_e;
  logic [NUM_CH-1:0]         s_rx_q;  // sensor s_q's receivers (registered with its words below)
  logic                      hd_vld_e, rel_tx_e, rel_xt_e, rel_act_e;
  logic [23:0]               rel_te_e;
  // stage A: the element index registered (ei_q, rel_q: valid from a state's second clock,
  // they only change after a go clock), then its words registered every clock (valid from
  // the state's third clock, after every earlier write). Writes use ei_q too.
  logic [RW-1:0] ei_q, rel_q;
  always_ff @(posedge clk_i) begin
    ei_q       <= ei;
    rel_q      <= rel;
    wv_e       <= wv_ok_q[ei_q] ? wv_m[ei_q] : '0;
    wh_e       <= wh_m[ei_q];
    wr_e       <= wr_m[ei_q];
    wsid_e     <= wsid_m[ei_q];
    bu_e       <= bu_m[ei_q];
    tu_e       <= tu_m[ei_q];
    bu_ok_e    <= bu_ok_q[ei_q];
    tu_ok_e    <= tu_ok_q[ei_q];
    hd_vld_e   <= hd_vld_q[ei_q];
    hd_slot_e  <= hd_slot_m[ei_q];
    rel_tx_e   <= s_tx_q[rel_q];  // receiver / element rel of sensor s_q (CAND, CONF, IEL)
    rel_xt_e   <= s_xt_q[rel_q];
    rel_act_e  <= s_rx_q[rel_q] && cand_act_m[rel_q];
    rel_te_e   <= cand_te_q[rel_q];
  end

  // EDGE: the stream's stage-C slot of receiver er holds the edge's timestamp n
  logic [31:0] n_edge, n_edge_q, e_ws, e_we;
  logic        e_match;
  assign n_edge  = n_edge_q;
  always_ff @(posedge clk_i) n_edge_q <= cur_tick_q - 32'(lat_q);  // cur_tick_q is set two clocks before any EDGE / HIT
  assign e_ws    = w_start_c_q;
  assign e_we    = w_end_c_q;
  assign e_match = ($signed(n_edge - e_ws) >= 0) && ($signed(n_edge - e_we) < 0);
  // gated miss rule, step 1 (HIT): the prediction for window fslot_q's pulse from its
  // sensor's tracking state of receiver er (model _predict(s, st, w.seq), signed pulse gap),
  // from the WIN and tracking-state words HIT reads (stages B-D), registered (g_te_q) for step 2
  rxs_t               grx;
  logic signed [7:0]  g_gap;
  logic signed [26:0] g_pred;
  logic [23:0]        g_lo, g_hi, g_te, g_te_q;
  assign grx    = rxs_rd;
  assign g_gap  = $signed(win_rd.seq - grx.seq);
  assign g_pred = pred_d_q;
  assign g_lo   = lo_c_q;
  assign g_hi   = hi_c_q;
  always_comb begin
    if (g_pred < $signed({3'd0, g_lo}))      g_te = g_lo;
    else if (g_pred > $signed({3'd0, g_hi})) g_te = g_hi;
    else                                     g_te = g_pred[23:0];
  end
  always_ff @(posedge clk_i) g_te_q <= g_te;  // in S_HIT final from its fourth clock (need)

  // HIT: window fslot_q of receiver er, its sensor's tracking state. The sensor h_s addresses
  // SNS (stage B); the decision reads only registers derived from it (h_*_q, one clock each
  // behind the window word, rxs word and h_dv_d_q), so no slot or sensor multiplexer feeds a
  // compare or a RAM's write data in the go clock.
  win_t        hw;
  logic [VW-1:0] h_s, h_s_q;
  rxs_t        hrx;
  logic [23:0] h_tof;
  logic [7:0]  h_gap_q;
  logic signed [24:0] h_dv;
  logic signed [16:0] h_v_q;
  logic [15:0] h_vmax_q;
  logic        h_wh_q, h_ep_q;   // the slot saw its first edge already; the window is of the current epoch
  assign hw     = win_c_q;
  assign h_s    = wsid_e[fslot_q];
  assign hrx    = rxs_c_q;
  assign h_tof  = h_tof_c_q;
  assign h_dv   = h_dv_d_q;
  // gated miss rule, step 2 (HIT): once the track's velocity is measured (vel), a tracking
  // window's first echo farther than the gate from the prediction is reported but neither
  // updates the track nor stops the window counting as a miss (model FastFiringModel miss_gate)
  logic [24:0]        h_abs;
  logic               h_rej_q;
  assign h_abs = h_abs_d_q;
  always_ff @(posedge clk_i) begin
    h_s_q    <= h_s;
    h_wh_q   <= wh_e[fslot_q];
    h_vmax_q <= sh_vmax_m[si(h_s_q)];
    h_ep_q   <= hw.epoch == epoch_q[si(h_s_q)];
    h_gap_q  <= hw.seq - hrx.seq;
    h_rej_q  <= (sh_gate_q != 16'd0) && !hw.init && hrx.trk && hrx.vel && (h_abs > {9'd0, sh_gate_q});
    if (h_dv > $signed({9'd0, h_vmax_q}))       h_v_q <= $signed({1'b0, h_vmax_q});
    else if (h_dv < -$signed({9'd0, h_vmax_q})) h_v_q <= -$signed({1'b0, h_vmax_q});
    else                                        h_v_q <= 17'(h_dv);
  end

  // CLOSE: head window of receiver clr
  logic [KW-1:0] c_slot;
  win_t          cw;
  logic [VW-1:0] c_s, c_s_q;
  rxs_t          crx;
  logic          c_valid;
  logic [3:0]    c_miss;
  assign c_slot  = hd_slot_e;
  assign cw      = win_c_q;
  assign c_s     = wsid_e[c_slot];
  assign crx     = rxs_c_q;
  assign c_miss  = (crx.miss == 4'hF) ? 4'hF : crx.miss + 4'd1;
  // The decision reads registers one clock behind the words they come from (c_*_q; CLOSE
  // waits one clock more than its stage-C reads for them), so neither the slot multiplexers
  // nor the close-tick compare feed a write in the go clock.
  logic c_wv_q, c_eq_q, c_empty_q, c_ep_q, c_kmiss_q, c_trk_q;
  logic [5:0] c_open_q;   // open_m[si(c_s_q)]: windows of the init ping still open
  logic       c_last_q;   // ... and this close is its last (c_open_q == 1)
  logic       c_trk_nx_q; // the tracking flag the sensor gets when its init ping completes
  always_ff @(posedge clk_i) begin
    c_s_q     <= c_s;
    c_open_q   <= open_m[si(c_s_q)];
    c_last_q   <= open_m[si(c_s_q)] == 6'd1;
    c_trk_nx_q <= sh_track_m[si(c_s_q)] && any_trk_q[si(c_s_q)];
    c_wv_q    <= wv_e[c_slot];
    c_empty_q <= !wh_e[c_slot] || wr_e[c_slot];  // a miss: no echo, or the first one failed the miss gate
    c_eq_q    <= w_close_c_q == cur_tick_q;
    c_ep_q    <= cw.epoch == epoch_q[si(c_s_q)];
    c_kmiss_q <= c_miss >= sh_k_m[si(c_s_q)];
    c_trk_q   <= tracking_q[si(c_s_q)];
  end
  assign c_valid = c_wv_q && c_eq_q;
  logic c_empty;
  assign c_empty  = c_empty_q;
  // K empty windows in a row: every window of sensor c_s is cancelled. Registered as one flop
  // from the inputs of the seven flops it ANDs (the same value in every clock, by construction):
  // it selects the slot-valid write data, which fans out to every element.
  logic c_safety, c_safety_q;
  always_ff @(posedge clk_i)
    c_safety_q <= wv_e[c_slot] && w_close_c_q == cur_tick_q && (!wh_e[c_slot] || wr_e[c_slot])
                  && !win_rd.init && cw.epoch == epoch_q[si(c_s_q)] && c_miss >= sh_k_m[si(c_s_q)] && tracking_q[si(c_s_q)];
  assign c_safety = c_safety_q;
`ifndef SYNTHESIS
  always_ff @(posedge clk_i)
    if (!rst_i && c_safety_q != (c_valid && c_empty && !cw.init && c_ep_q && c_kmiss_q && c_trk_q))
      $error("ms_scheduler: registered c_safety differs from its terms");
`endif

  // ---- slot stream (S_EDGE, S_HEAD, S_CSLOT): one valid slot of the element per clock. The
  // slot sk (lowest bit of srem_q) addresses WIN in the clock it leaves srem_q; its word passes
  // stages B, C and D (sv_*_q: a slot's word is in that stage) and the state folds it into its
  // result in the clock its stage-D flags are valid: the window holding the edge (EDGE, which
  // stops there), the earliest close tick (minclose_q, its slot hk_q; found_q: any slot) and,
  // in S_CSLOT, the conflicts' retry. No slot's result changes another slot's reads, so the
  // reads go one per clock; a stream ends four clocks after its last slot (sv_idle).
  logic              sv_b_q, sv_c_q, sv_d_q, sv_idle;
  logic [KW-1:0]     sk_b_q, sk_c_q, sk_d_q, hk_q;
  logic [31:0]       w_close_d_q;
  logic              em_d_q;    // S_EDGE: the stage-D slot's window holds the edge
  logic              sw_first;  // the stage-D slot closes before every slot folded so far
  always_ff @(posedge clk_i) begin
    sv_b_q      <= (st_q inside {S_EDGE, S_HEAD, S_CSLOT}) && srem_q != '0;
    sk_b_q      <= sk;
    sv_c_q      <= sv_b_q;
    sk_c_q      <= sk_b_q;
    sv_d_q      <= sv_c_q;
    sk_d_q      <= sk_c_q;
    w_close_d_q <= w_close_c_q;
    em_d_q      <= sv_c_q && e_match;
  end
  assign sv_idle  = srem_q == '0 && !sv_b_q && !sv_c_q && !sv_d_q;
  assign sw_first = !found_q || $signed(w_close_d_q - minclose_q) < 0;

  // SCHED: sensor s_q at logical tick cur_tick_q, candidate t0 = cur + P. The sensor's flags
  // and compares are registered (sc_*_q, one and two clocks after s_q; need 2), so the go
  // clock is only the AND-OR of them into the next state and the nxt write.
  logic [31:0] t_cand;
  logic        s_eval;
  assign t_cand = t_cand_q;
  logic sc_act_q, sc_init_q, sc_wake_q, sc_hold_q, sc_trk_q, sc_qv_q, sc_reinit_q;
  logic sc_nxt_q, sc_early_q, sc_quiet_q;
  always_ff @(posedge clk_i) begin
    sc_act_q    <= sh_act_q[si(s_q)];
    sc_init_q   <= in_init_q[si(s_q)];
    sc_wake_q   <= wake_q[si(s_q)];
    sc_hold_q   <= hold_q[si(s_q)];
    sc_trk_q    <= tracking_q[si(s_q)];
    sc_qv_q     <= quiet_vld_q[si(s_q)];
    sc_reinit_q <= reinit_due_q[si(s_q)];
    // nxt_rd_q, due_s_q, quiet_rd_q: one clock after s_q
    sc_nxt_q    <= $signed(t_cand - nxt_rd_q) >= 0;
    sc_early_q  <= $signed(t_cand - due_s_q) < 0;
    sc_quiet_q  <= $signed(t_cand - quiet_rd_q) < 0;
  end
  // reinit_every reached (reinit_due_q[s], flops): set by ISSUE with the sensor's new pulse
  // count, long before its next SCHED (the per-sensor writes)
  assign s_eval = sc_act_q && !sc_init_q && (sc_wake_q || (!sc_hold_q && sc_nxt_q));
  // sensor s_q's tracking flag and receiver count for the states after SCHED (s_q and its
  // tracking flag do not change between SCHED and the end of IEL)
  // The rest of the sensor's words the go clocks of EDF .. IEL write or copy, registered the
  // same way, so no write in a go clock follows a multiplexer of eight sensors (in context the
  // eight words lie far apart); ISSUE's writes of seq / epoch / pulse count are seen again
  // by IEL, which waits need(S_IEL) clocks after ISSUE.
  logic              s_trk_q;
  logic [NUM_CH-1:0] s_all_q;  // every element the pulse touches (tx | xt | rx)
  logic [5:0]        s_nrx_q;   // two clocks after s_q: the mask, then its popcount
  logic [OW-1:0]     s_order_q;
  logic [23:0]       s_rmax_q, s_dbl_q, s_tvd_q;  // s_tvd_q = T_V + D (two clocks after s_dbl_q)
  logic [15:0]       s_tv_q, s_tn_q;
  logic [31:0]       s_rmd_q;   // max ToF - D, 32-bit (two clocks after s_q)
  logic [7:0]        s_burst_q, s_tpc_q, s_rein_q;
  logic              s_rdue_q;
  logic [15:0]       s_pid_q;   // the sensor's pulse id (seq_m)
  logic [7:0]        s_seq_q;
  assign s_seq_q = s_pid_q[7:0];
  logic              s_ep_q;
  // The table words of s_q: S_SCHED and S_EDF address word cw_rd_q (0 .. CW_TRACK, one per
  // clock from their first clock), SNS returns it a clock later (cw_v_q, cw_w_q) and
  // its fields are registered from there, so the last arrives 9 clocks after SCHED's first
  // and the words derived from them two clocks later. Their first reader, EDF's last go
  // (s_rx_q, word 1), comes 3 + 3 NUM_VS >= 9 clocks after SCHED's first; ORDER, CONF, ISSUE
  // and IEL come after CAND and ORDER (5 clocks each at least). s_q and these registers do
  // not change from SCHED to the end of IEL.
  logic [2:0] cw_rd_q, cw_w_q;
  logic       cw_v_q;
  always_ff @(posedge clk_i) begin
    if (!(st_q inside {S_SCHED, S_EDF})) cw_rd_q <= CW_TX;
    else if (cw_rd_q != CW_TRACK)        cw_rd_q <= cw_rd_q + 3'd1;
    cw_v_q <= st_q inside {S_SCHED, S_EDF};
    cw_w_q <= cw_rd_q;
    if (cw_v_q) begin
      unique case (cw_w_q)
        CW_TX:    s_tx_q                <= cb_raw[NUM_CH-1:0];
        CW_RX:    s_rx_q                <= cb_raw[NUM_CH-1:0];
        CW_MODE:  {s_rein_q, s_order_q} <= {cb_raw[19:12], cb_raw[7:4]};
        CW_WIN:   {s_tn_q, s_tv_q}      <= cb_raw[31:0];
        CW_RMAX:  s_rmax_q              <= cb_raw[23:0];
        CW_TRACK: s_burst_q             <= cb_raw[23:16];
        default: ;  // PHASE (S_INIT), slot 6 unused
      endcase
    end
  end
  always_ff @(posedge clk_i) begin
    s_trk_q   <= tracking_q[si(s_q)];
    s_xt_q    <= sh_xt_m[si(s_q)];
    s_dbl_q   <= sh_dbl_m[si(s_q)];
    s_tvd_q   <= 24'(s_tv_q) + s_dbl_q;
    s_rmd_q   <= 32'(s_rmax_q) - 32'(s_dbl_q);
    s_nrx_q   <= popcount(s_rx_q);
    s_all_q   <= s_tx_q | s_rx_q | s_xt_q;
    s_pid_q   <= seq_m[si(s_q)];
    s_tpc_q   <= trk_m[si(s_q)];
    // ISSUE of a tracking pulse reaches reinit_every (the count saturates at 255 >= any M)
    s_rdue_q  <= s_rein_q != 8'd0 && 9'(s_tpc_q) + 9'd1 >= 9'(s_rein_q);
    s_ep_q    <= epoch_q[si(s_q)];
  end
  logic s_early, s_quiet;  // not due yet / still quiet: wait (nxt_m = due / quiet, as t0)
  assign s_early = s_eval && sc_early_q;
  assign s_quiet = s_eval && !s_early && !sc_trk_q && sc_qv_q && sc_quiet_q;
  logic s_reinit;  // forced re-initialisation (RX_FILTER.reinit_every): cancel, then evaluate as an init ping
  assign s_reinit = s_eval && !s_early && sc_trk_q && sc_reinit_q;
  // EDF: is sensor o_q pending with an earlier (due, id)? Registered like SCHED (eo_*_q; need 2).
  logic o_elig, o_first;
  logic eo_share_q, eo_act_q, eo_init_q, eo_trk_q, eo_qv_q, eo_idlt_q, eo_due_q, eo_quiet_q, eo_lt_q, eo_eq_q;
  always_ff @(posedge clk_i) begin
    eo_share_q <= o_q != s_q && sh_share_q[si(s_q)][si(o_q)];
    eo_act_q   <= sh_act_q[si(o_q)];
    eo_init_q  <= in_init_q[si(o_q)];
    eo_trk_q   <= tracking_q[si(o_q)];
    eo_qv_q    <= quiet_vld_q[si(o_q)];
    eo_idlt_q  <= o_q < s_q;
    eo_due_q   <= $signed(t_cand - due_x_q) >= 0;  // due_x_q, quiet_rd_q: one clock after o_q
    eo_quiet_q <= $signed(t_cand - quiet_rd_q) >= 0;
    eo_lt_q    <= $signed(due_x_q - due_s_q) < 0;
    eo_eq_q    <= due_x_q == due_s_q;
  end
  assign o_elig  = eo_act_q && !eo_init_q && eo_due_q && (eo_trk_q || !eo_qv_q || eo_quiet_q);
  assign o_first = eo_lt_q || (eo_eq_q && eo_idlt_q);

  // CAND: prediction for receiver rel of sensor s_q's pulse seq_q[si(s_q)], a receiver stream
  // like the slot streams: receiver rel reads SNS in the clock it leaves rem_q, its
  // prediction (te_d_q) is ready four clocks later (cv_*_q: stages B-E), where S_CAND folds it
  // into the candidate (receivers never depend on one another)
  logic          cv_b_q, cv_c_q, cv_d_q, cv_e_q, ct_d_q, ct_e_q;
  logic [RW-1:0] rl_b_q, rl_c_q, rl_d_q, rl_e_q;
  always_ff @(posedge clk_i) begin
    cv_b_q <= st_q == S_CAND && rem_q != '0;
    cv_c_q <= cv_b_q;
    cv_d_q <= cv_c_q;
    cv_e_q <= cv_d_q;
    rl_b_q <= rel;
    rl_c_q <= rl_b_q;
    rl_d_q <= rl_c_q;
    rl_e_q <= rl_d_q;
    ct_d_q <= rxs_c_q.trk;  // the receiver is tracked (stage C of its tracking-state word)
    ct_e_q <= ct_d_q;
  end
  rxs_t        irx;
  logic [7:0]  i_gap;
  logic signed [26:0] i_pred;
  logic [23:0] i_lo, i_hi, i_te;
  assign irx    = rxs_rd;

  // ---- the single read port of WIN and SNS, addressed by the state using it
  always_comb begin
    unique case (st_q)
      S_EDGE:  win_ra = $bits(win_ra)'(int'(er) * WSLOTS + int'(sk));
      S_HIT:   win_ra = $bits(win_ra)'(int'(er) * WSLOTS + int'(fslot_q));
      S_CLOSE: win_ra = $bits(win_ra)'(int'(clr) * WSLOTS + int'(c_slot));
      S_IEL:   win_ra = $bits(win_ra)'(int'(rel) * WSLOTS + int'(hd_slot_e));  // the head's close
      default: win_ra = $bits(win_ra)'(int'(el_q) * WSLOTS + int'(sk));  // S_HEAD, S_CSLOT
    endcase
    unique case (st_q)
      S_HIT:   rxs_wa = {si(h_s), er};
      S_CLOSE: rxs_wa = {si(c_s), clr};
      default: rxs_wa = {si(s_q), rel};  // S_CAND (read), S_IEL (write)
    endcase
    unique case (st_q)
      S_HIT, S_CLOSE, S_CAND: sns_ra = {1'b0, rxs_wa};           // tracking state
      S_SCHED, S_EDF:         sns_ra = cw_addr(s_q, cw_rd_q);     // the sensor's words, a clock each
      S_INIT:                 sns_ra = cw_addr(s_q, CW_PHASE);
      default:                sns_ra = {1'b1, si(s_q), rel};      // S_CONF, S_IEL: blank intervals
    endcase
  end
  // stage B: registered every clock, addressed by the state and the stage-A words; stage C
  // keeps a copy for the decisions (a block RAM's output has no time left for logic after it)
  always_ff @(posedge clk_i) begin
    win_rd  <= win_q[win_ra];
    sns_rd  <= sns_q[sns_ra];
    win_c_q <= win_rd;
    rxs_c_q <= rxs_rd;
  end
  assign i_gap  = s_seq_q - irx.seq;  // seq_q[si(s_q)]
  assign i_pred = pred_d_q;
  assign i_lo   = lo_c_q;
  assign i_hi   = hi_c_q;
  always_comb begin
    if (i_pred < $signed({3'd0, i_lo}))      i_te = i_lo;
    else if (i_pred > $signed({3'd0, i_hi})) i_te = i_hi;
    else                                     i_te = i_pred[23:0];
  end

  // ORDER: T_s = floor((te_min - T_V - D) / n), feasible if T_s > 0 and (n+1) T_s >= te_max + T_N
  // floor(x / n) for x < 2^24 is floor(x * m_n / 2^27) with m_n = ceil(2^27 / n), exact for every
  // n <= 8 (m_n n - 2^27 < n <= 2^(27 - 24)); n = 1, 2, 4, 8 are shifts
  logic [23:0] o_x, o_ts, o_x_q, o_ts_q, o_div_q;
  logic [25:0] o_rcp, o_rcp_q;
  logic [49:0] o_mul;
  logic [26:0] o_lhs_q, o_rhs_q;
  logic        o_feas;
  assign o_x   = te_min_q - s_tvd_q;  // te_min - T_V - D
  always_comb begin
    unique case (n_q)
      4'd3:    o_rcp = 26'd44739243;  // ceil(2^27 / 3)
      4'd5:    o_rcp = 26'd26843546;
      4'd6:    o_rcp = 26'd22369622;
      4'd7:    o_rcp = 26'd19173962;
      default: o_rcp = '0;            // a shift
    endcase
  end
  assign o_mul = 50'(o_x_q) * 50'(o_rcp_q);
  always_comb begin
    unique case (n_q)
      4'd1:    o_ts = o_x_q;
      4'd2:    o_ts = o_x_q >> 1;
      4'd4:    o_ts = o_x_q >> 2;
      4'd8:    o_ts = o_x_q >> 3;
      default: o_ts = o_div_q;  // 3, 5, 6, 7
    endcase
  end
  // registered: o_x and the reciprocal in the state's first clock, x / n (the multiplier and
  // its adders) in its second, o_ts in its third, (n + 1) o_ts in its fourth; o_x does not
  // depend on n, and n_q holds for the whole try
  always_ff @(posedge clk_i) begin
    o_x_q   <= o_x;
    o_rcp_q <= o_rcp;
    o_div_q <= 24'(o_mul[49:27]);  // < 2^23: n >= 3
    o_ts_q  <= o_ts;
  end
  always_ff @(posedge clk_i) begin  // fourth clock: (n + 1) T_s and T_max + T_N, then the decision
    // (n + 1) T_s <= 2 x < 2^25: the validated orders keep it within 27 bits
    o_lhs_q <= 27'(o_ts_q) * 27'({1'b0, n_q} + 5'd1);
    o_rhs_q <= 27'(te_max_q) + 27'(s_tn_q);
  end
  assign o_feas = (o_ts_q != 24'd0) && (o_lhs_q >= o_rhs_q);

  // CONF / IEL: element rel of the candidate (blank interval from SNS, window from CAND)
  logic        c_blk, c_win;
  logic [23:0] c_wso, c_weo;
  assign c_blk = rel_tx_e || rel_xt_e;
  assign c_win = rel_act_e;
  assign c_wso = c_wso_c_q;
  assign c_weo = c_weo_c_q;
  logic [KW-1:0] free_slot;
  assign free_slot = lsb_slot(~wv_e);
  logic [31:0] iw_close;
  assign iw_close = iw_close_d_q;
  logic [31:0] trig_dly;
  assign trig_dly = ta_c_q + ~tick_i;  // t0 + delay - tick_i - 1

  // the miss gate (not in the VS table) is latched in S_STOP's go clock (its second)
  logic stop_ld_q;
  always_ff @(posedge clk_i) stop_ld_q <= !rst_i && st_q == S_STOP && ph_q == 3'd0;

  // conflict scan: the latest retry t0 among the conflicts seen (model _conflict). Each
  // CONF / CSLOT step offers at most two retries, x and y, registered with their flags in
  // stage D; the new retry is the latest of x, y and retry_q, picked from three compares made
  // side by side. Retries are kept relative to the candidate t0 (t_q): a conflict's retry is
  // the end of what it overlaps minus the candidate's start of it, so the subtraction that
  // gives the retry also says whether there is a conflict (> 0), and a retry lies within
  // 2^24 + 2^9 ticks of t_q (a window ends at most 2^24 after its t0, which is <= t_q; a
  // blank_until or tx_until at most 2^20 after t_q), so RTW bits hold it.
  //   S_CONF  x: a tx element's trigger before its tx_until (rule 5: no burst over a burst),
  //           y: a window start before the element's blank_until (an element is one or the
  //              other for a sensor whose rx and tx differ, both when it is in both);
  //   S_CSLOT x: the blank interval overlapping a reserved window,
  //           y: the window overlapping one, or (after the last slot) every slot taken.
  logic           rx_on, ry_on, rz_on, r_xy, r_xz, r_yz, rv_new;
  logic [RTW-1:0] rn_new;
  logic           rx_on_d_q, ry_on_d_q;
  logic [RTW-1:0] rx_d_q, ry_d_q;
  logic [31:0]    rx_dif, ry_dif, rxs_dif, rys_dif;  // CONF / CSLOT: retry - t_q, 32 bits
  always_comb begin
    // S_CSLOT folds a slot's flags in its stage-D clock only (its first clock still sees S_CONF's)
    rx_on  = (st_q == S_CONF || (st_q == S_CSLOT && sv_d_q)) && rx_on_d_q;
    ry_on  = (st_q == S_CONF || (st_q == S_CSLOT && sv_d_q) || st_q == S_CFULL) && ry_on_d_q;
    rz_on  = retry_vld_q;
    r_xy   = $signed(rx_d_q) >= $signed(ry_d_q);   // x >= y
    r_xz   = $signed(rx_d_q) >= $signed(retry_q);  // x >= retry
    r_yz   = $signed(ry_d_q) >= $signed(retry_q);  // y >= retry
    rv_new = rx_on || ry_on || rz_on;
    if (rx_on && (!ry_on || r_xy) && (!rz_on || r_xz)) rn_new = rx_d_q;
    else if (ry_on && (!rz_on || r_yz))                 rn_new = ry_d_q;
    else                                               rn_new = retry_q;
  end


  logic signed [8:0]  p_gap;
  logic [VW-1:0]      p_s, p_s_q;
  logic               c_due_lt_q;
  logic [23:0]        p_te, p_wso, p_weo;
  assign p_gap = (st_q == S_HIT) ? 9'(g_gap) : $signed({1'b0, i_gap});
  assign p_s   = (st_q == S_HIT) ? h_s : s_q;
  assign p_te  = rel_te_e;
  // the candidate's t0 (t_q, fixed from SCHED to IEL) plus the window's close latency,
  // registered long before IEL reads it
  // and the retry of a deferral as a t0 (nxt_m's write one clock after CONF's last go)
  logic [31:0] retry_t0_q;
  always_ff @(posedge clk_i) begin
    tl_q       <= t_q + 32'(latm1_q);
    retry_t0_q <= t_q + 32'($signed(retry_q));
  end
  assign p_wso = !s_trk_q ? s_dbl_q : p_te - 24'(s_tv_q);
  // the retries relative to t0 (see the conflict scan): CONF's x = tx_until - (t0 + a), its
  // y = blank_until - (t0 + window start); CSLOT's x = window end - (t0 + a), its y = window
  // end - (t0 + window start)
  assign rx_dif  = tu_e - ta_c_q;
  assign ry_dif  = bu_rel_c_q - 32'(c_wso_c_q);
  assign rxs_dif = w_end_c_q - ta_c_q;
  assign rys_dif = w_end_c_q - tws_d_q;
  assign p_weo = !s_trk_q ? s_rmax_q : p_te + 24'(s_tn_q);
  always_ff @(posedge clk_i) begin
    due_s_q     <= due_m[si(s_q)];
    due_x_q     <= due_m[si(st_q == S_CLOSE ? c_s_q : o_q)];
    quiet_rd_q  <= quiet_m[si(st_q == S_EDF ? o_q : s_q)];
    w_start_c_q <= win_rd.t0 + 32'(win_rd.ws);
    w_end_c_q   <= win_rd.t0 + 32'(win_rd.we);
    w_close_c_q <= win_rd.t0 + (32'(win_rd.we) + 32'(latm1_q));
    gap_c_q     <= p_gap;
    p_s_q       <= p_s;  // (stage B) the sensor's clamp bounds one clock later
    lo_c_q      <= sh_lo_m[si(p_s_q)];
    hi_c_q      <= sh_hi_m[si(p_s_q)];
    c_due_lt_q  <= $signed(cur_tick_q - due_x_q) < 0;  // CLOSE: a safety moves due earlier
    h_tof_c_q   <= 24'(n_edge - win_rd.t0);
    c_wso_c_q   <= p_wso;
    c_weo_c_q   <= p_weo;
    ta_c_q      <= t_q + 32'(cb.a);
    tb_c_q      <= t_q + 32'(cb.b);
    bu_rel_c_q  <= bu_e - t_q;
    // stage D: the window of element rel (te >= T_V, te + T_N < 2^24: CAND's clamp); CSLOT
    // reads them and ta_c_q / tb_c_q for the element CONF chose (rel does not change there)
    tws_d_q     <= t_q + 32'(c_wso_c_q);
    twe_d_q     <= t_q + 32'(c_weo_c_q);
    // stage D
    pred_d_q     <= $signed({3'd0, rxs_c_q.tof}) + gap_c_q * rxs_c_q.v;
    h_dv_d_q     <= $signed({1'b0, h_tof_c_q}) - $signed({1'b0, rxs_rd.tof});
    h_abs_d_q    <= ($signed({1'b0, h_tof_c_q}) < $signed({1'b0, g_te_q})) ? 25'(g_te_q) - 25'(h_tof_c_q)
                                                                         : 25'(h_tof_c_q) - 25'(g_te_q);
    if (st_q == S_CONF) begin
      rx_on_d_q <= (rem_q != '0) && rel_tx_e && tu_ok_e && $signed(rx_dif) > 0;
      rx_d_q    <= RTW'(rx_dif);
      ry_on_d_q <= (rem_q != '0) && c_win && bu_ok_e && $signed(ry_dif) > 0;
      ry_d_q    <= RTW'(ry_dif);
    end else if (st_q == S_CFULL) begin  // after the element's slots: every slot taken
      rx_on_d_q <= 1'b0;
      rx_d_q    <= RTW'(rxs_dif);
      ry_on_d_q <= win_on_q && (&wv_e);
      ry_d_q    <= RTW'(minclose_q - t_q);
    end else begin  // S_CSLOT: the stage-C slot of the stream (don't-care elsewhere)
      rx_on_d_q <= sv_c_q && blk_on_q && $signed(rxs_dif) > 0 && $signed(w_start_c_q - tb_c_q) < 0;
      rx_d_q    <= RTW'(rxs_dif);
      ry_on_d_q <= sv_c_q && win_on_q && $signed(rys_dif) > 0 && $signed(w_start_c_q - twe_d_q) < 0;
      ry_d_q    <= RTW'(rys_dif);
    end
    iw_close_d_q <= tl_q + 32'(c_weo_c_q);  // t0 + p_weo - 1 + L
    // IEL's per-element write enables: compares on stage D against the head slot's WIN word
    // (stage C), so no write enable follows a carry chain
    iw_first_d_q <= !hd_vld_e || $signed(iw_close_d_q - w_close_c_q) < 0;
    bu_later_d_q <= !bu_ok_e || later(tb_c_q, bu_e);
    tu_later_d_q <= !tu_ok_e || later(tb_c_q, tu_e);
    te_d_q       <= i_te;
    // per-sensor ticks written by SCHED / CONF / ISSUE / INIT, computed while the state reads
    t_cand_q     <= cur_tick_q + LEAD32;
    due_isu_q    <= t_q + 32'(period_q);
    quiet_isu_q  <= t_q + s_rmd_q;  // t_q + max ToF - D
    due_ini_q    <= eng_tick_q + 32'(cb_raw[23:0]);  // S_INIT: the phase word (go 2 clocks on)
  end

  // ------------------------------------------------------------------ main FSM
  logic cand_clr_q;  // S_EDF moved to S_CAND in the last clock
  // ---- configuration check and load (ms_sched_cfg): S_CHECK and S_LOAD start it (cfg_chk_q /
  // cfg_ld_q, one clock) and wait for cfg_done; a stop while checking aborts it. The load
  // writes the per-sensor state below, the share matrix and SNS (the FSM).
  logic              cfg_chk_q, cfg_ld_q, cfg_busy, cfg_done;
  logic [3:0]        cfg_err, cfg_err_vs;
  logic              ld_we, ld_act, ld_track;
  logic [2:0]        ld_vs;
  logic [NUM_CH-1:0] ld_tx, ld_rx, ld_xt, ld_use;
  logic [OW-1:0]     ld_order;
  logic [3:0]        ld_k;
  logic [7:0]        ld_reinit, ld_burst;
  logic [15:0]       ld_tv, ld_tn, ld_vmax;
  logic [23:0]       ld_rmax, ld_phase, ld_dbl, ld_lo, ld_hi;
  logic              cfg_blk_we, cfg_share_we, cfg_share, cfg_word_we;
  logic [3:0]        cfg_word;
  logic [7:0]        cfg_blk_addr;
  logic [DELAY_W-1:0] cfg_blk_a;
  logic [BW-1:0]     cfg_blk_b;
  logic [2:0]        cfg_share_a, cfg_share_b;
  ms_sched_cfg #(
    .NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .DELAY_W(DELAY_W), .LEAD(LEAD), .MAX_ORDER(MAX_ORDER),
    .DW(DW), .BW(BW), .OW(OW)
  ) u_cfg (
    .clk_i              (clk_i),
    .rst_i              (rst_i),
    .check_i            (cfg_chk_q),
    .load_i             (cfg_ld_q),
    .abort_i            (!en_q && started_q),
    .busy_o             (cfg_busy),
    .done_o             (cfg_done),
    .err_o              (cfg_err),
    .err_vs_o           (cfg_err_vs),
    .vs_ren_o           (vs_ren_o),
    .vs_raddr_o         (vs_raddr_o),
    .vs_rdata_i         (vs_rdata_i),
    .delay_raddr_o      (delay_raddr_o),
    .delay_rdata_i      (delay_rdata_i),
    .burst_half_period_i(burst_half_period_i),
    .ld_we_o            (ld_we),
    .ld_vs_o            (ld_vs),
    .ld_tx_o            (ld_tx),
    .ld_rx_o            (ld_rx),
    .ld_xt_o            (ld_xt),
    .ld_use_o           (ld_use),
    .ld_act_o           (ld_act),
    .ld_track_o         (ld_track),
    .ld_order_o         (ld_order),
    .ld_k_o             (ld_k),
    .ld_reinit_o        (ld_reinit),
    .ld_tv_o            (ld_tv),
    .ld_tn_o            (ld_tn),
    .ld_vmax_o          (ld_vmax),
    .ld_rmax_o          (ld_rmax),
    .ld_phase_o         (ld_phase),
    .ld_dbl_o           (ld_dbl),
    .ld_lo_o            (ld_lo),
    .ld_hi_o            (ld_hi),
    .ld_burst_o         (ld_burst),
    .word_we_o          (cfg_word_we),
    .word_o             (cfg_word),
    .blk_we_o           (cfg_blk_we),
    .blk_addr_o         (cfg_blk_addr),
    .blk_a_o            (cfg_blk_a),
    .blk_b_o            (cfg_blk_b),
    .share_we_o         (cfg_share_we),
    .share_a_o          (cfg_share_a),
    .share_b_o          (cfg_share_b),
    .share_o            (cfg_share)
  );
  always_ff @(posedge clk_i) begin
    if (stop_ld_q) sh_gate_q <= miss_gate_i;
    if (ld_we) begin
      sh_xt_m[si(ld_vs)]     <= ld_xt;
      sh_dbl_m[si(ld_vs)]    <= ld_dbl;
      sh_track_m[si(ld_vs)]  <= ld_track;
      sh_k_m[si(ld_vs)]      <= ld_k;
      sh_vmax_m[si(ld_vs)]   <= ld_vmax;
      sh_lo_m[si(ld_vs)]     <= ld_lo;
      sh_hi_m[si(ld_vs)]     <= ld_hi;
      sh_rxany_q <= ((ld_vs == '0) ? '0 : sh_rxany_q) | (ld_act ? ld_rx : '0);
    end
    if (cfg_share_we) begin
      sh_share_q[si(cfg_share_a)][si(cfg_share_b)] <= cfg_share;
      sh_share_q[si(cfg_share_b)][si(cfg_share_a)] <= cfg_share;
    end
  end
  // The load's writes to SNS: ms_sched_cfg's blank intervals, and each table word the load
  // reads (cfg_word_we) that the engine uses. The load reads an entry's words before it writes
  // the entry's blank intervals, and the previous entry's are written by then, so the two
  // never meet; the engine's tracking-state writes (below) come only from running states
  // (checked below).
  logic              blk_we;
  logic [BA-1:0]     blk_wa;
  logic [35:0]       blk_wd;
  always_comb begin
    blk_we = cfg_blk_we || (cfg_word_we && cw_kept(cfg_word));
    blk_wa = cfg_blk_we ? {1'b1, cfg_blk_addr[SW+4:0]} : cw_addr(ld_vs, cw_slot(cfg_word));
    blk_wd = cfg_blk_we ? {cfg_blk_a, cfg_blk_b} : {4'd0, vs_rdata_i};
  end
`ifndef SYNTHESIS
  // for the testbench's check of the per-sensor state against the table (ms_scheduler_tb.sv):
  // the clock after the load's done, every sensor, share pair and blank interval written
  logic dbg_loaded;
  always_ff @(posedge clk_i) dbg_loaded <= !rst_i && st_q == S_LOAD && cfg_done;
  always_ff @(posedge clk_i) begin
    if (!rst_i && (cfg_chk_q || cfg_ld_q) && cfg_busy) $error("ms_scheduler: ms_sched_cfg started while busy");
    if (!rst_i && cfg_blk_we && cfg_word_we)
      $error("ms_scheduler: blank interval and table word written in one clock");
  end
`endif

  always_ff @(posedge clk_i) begin
    evt_valid_q  <= 1'b0;
    trig_valid_q <= 1'b0;
    pulse_q      <= 1'b0;
    disp_chk_q   <= 1'b0;  // S_IDLE's dispatch sets it
    if (stop_age_q != 2'd3) stop_age_q <= stop_age_q + 2'd1;  // S_CHECK restarts it
    // S_CAND's first clock clears the candidate set from a flop (S_EDF's go only sets
    // cand_clr_q), so the clear is not behind EDF's decision logic; S_CAND's stream writes it
    // from its fifth clock on
    cand_clr_q   <= 1'b0;
    if (cand_clr_q) begin
      nwin_q     <= '0;
      te_min_q   <= '1;
      te_max_q   <= '0;
    end
    if (rst_i) begin
      st_q         <= S_OFF;
      ph_q         <= '0;
      started_q    <= 1'b0;
      ovr_q        <= 1'b0;
      cfg_err_q    <= '0;
      cfg_err_vs_q <= '0;
      en_q         <= 1'b0;
      en_prev_q    <= 1'b0;
      apply_pend_q <= 1'b0;
      stop_req_q   <= 1'b0;
      sh_act_q     <= '0;
      start_go_q   <= 1'b0;
      cfg_chk_q    <= 1'b0;
      cfg_ld_q     <= 1'b0;
    end else begin
      en_q       <= enable_i;
      en_prev_q  <= en_q;
      start_go_q <= 1'b0;  // S_LOAD sets it with its move to S_START
      cfg_chk_q  <= 1'b0;  // set with the move to S_CHECK / S_LOAD
      cfg_ld_q   <= 1'b0;
      if (q_ovf || lag_late) ovr_q <= 1'b1;
      if (apply_i || (en_q && !en_prev_q)) apply_pend_q <= 1'b1;
      if (go) begin
        retry_q     <= rn_new;
        retry_vld_q <= rv_new;
      end
      if (ld_we) sh_act_q[si(ld_vs)] <= ld_act;  // the load's records; sh_act_q alone has a reset

      if (!en_q && started_q) begin  // stop: windows dropped, armed triggers still fire
        st_q       <= S_OFF;
        started_q  <= 1'b0;
        stop_req_q <= 1'b0;
        ph_q       <= '0;
      end else if (!go) begin
        ph_q <= ph_q + 3'd1;  // the state's reads are still on their way through the stages
      end else begin
        ph_q <= '0;
        unique case (st_q)
          // ------------------------------------------------ configuration
          S_OFF: begin
            if (apply_pend_q) begin
              apply_pend_q <= 1'b0;
              cfg_chk_q    <= 1'b1;
              st_q         <= S_CHECK;
            end
          end
          S_CHECK: begin  // ms_sched_cfg checks the table; a refused one changes nothing
            if (cfg_done) begin
              cfg_err_q    <= cfg_err;
              cfg_err_vs_q <= cfg_err_vs;
              if (cfg_err != 4'd0) begin
                st_q <= started_q ? S_SETTLE : S_OFF;
              end else if (started_q) begin
                stop_req_q <= 1'b1;
                stop_at_q  <= tick_i;
                stop_age_q <= 2'd1;  // tick_i - stop_at_q, saturating at 3
                st_q       <= S_SETTLE;  // the engine finishes every tick before stop_at
              end else begin
                st_q <= S_STOP;
              end
            end
          end
          S_STOP: begin  // latch the miss gate (stop_ld_q above), then load the per-sensor state
            started_q  <= 1'b0;
            stop_req_q <= 1'b0;
            cfg_ld_q   <= 1'b1;
            st_q       <= S_LOAD;
          end
          S_LOAD: begin  // ms_sched_cfg writes the per-sensor state, shares and blank intervals
            if (cfg_done) begin
              st_q       <= en_q ? S_START : S_OFF;
              start_go_q <= en_q;
            end
          end
          S_START: begin  // start tick S = tick_i (model start_tick); due and nxt in S_INIT
            started_q  <= 1'b1;
            eng_tick_q <= tick_i;
            s_q        <= '0;   // per-sensor state cleared: see the per-sensor writes
            st_q       <= S_INIT;  // element state: see the per-element writes
          end
          S_INIT: begin  // due = S + phase, one sensor per clock (per-sensor writes)
            s_q <= s_q + 1'b1;
            if (s_q == VW'(NUM_VS - 1)) st_q <= S_SETTLE;
          end
          // ------------------------------------------------ engine
          S_SETTLE: begin  // td_q follows the state changed before, TD_SETTLE clocks later
            settle_q <= TD_SETTLE;
            st_q     <= S_IDLE;
            if (apply_pend_q && !stop_req_q) begin
              apply_pend_q <= 1'b0;
              cfg_chk_q    <= 1'b1;
              st_q         <= S_CHECK;  // check while the schedule's state is kept
            end
          end
          S_IDLE: begin
            if (settle_q != 4'd0) begin
              settle_q <= settle_q - 4'd1;
            end else if (stop_ok) begin
              st_q <= S_STOP;
            end else if (take_q || sched_go) begin
              disp_chk_q <= 1'b1;  // lag_late: closes could be missed
              cur_tick_q <= take_q ? qh_tick : td_q;
              edges_q    <= take_q ? qh_edges : '0;
              closes_q   <= take_q ? qh_closes : '0;
              st_q       <= S_DISP;
            end else if (apply_pend_q && !stop_req_q) begin
              st_q <= S_SETTLE;
            end
          end
          S_DISP: begin
            s_q <= '0;
            if (edges_q != '0) begin
              srem_q <= wv_e;
              st_q   <= S_EDGE;
            end else if (closes_q != '0) begin
              st_q <= S_CLOSE;
            end else begin
              st_q <= S_SCHED;
            end
          end
          S_EDGE: begin  // the live window of receiver er holding n (slot stream; windows never overlap)
            if (srem_q != '0) srem_q <= srem_q & (srem_q - 1'b1);
            if (sv_d_q && em_d_q) begin
              fslot_q <= sk_d_q;
              st_q    <= S_HIT;  // the slots still in the stream are dropped
            end else if (sv_idle) begin
              edges_q <= edges_q & (edges_q - 1'b1);  // outside every window: gated
              st_q    <= S_DISP;
            end
          end
          S_HIT: begin
            edges_q <= edges_q & (edges_q - 1'b1);
            st_q        <= S_DISP;
            if (!h_wh_q) begin  // max_echoes_per_window = 1 (wh: per-element writes)
              evt_valid_q <= 1'b1;
              evt_data_q  <= {20'd0, hw.init, 1'b0, 1'b1, 1'b1, h_s_q, hw.seq, er, h_tof};
              // h_ep_q: wake, any_trk (per-sensor writes); tracking state: the SNS writes below
            end
          end
          S_CLOSE: begin
            closes_q <= closes_q & (closes_q - 1'b1);
            el_q          <= clr;
            srem_q        <= wv_wd;  // the slots left after this close (and a safety cancel)
            found_q       <= 1'b0;   // the head is cleared and rescanned in S_HEAD
            st_q          <= c_safety ? S_SAFE : S_HEAD;
            sf_e_q        <= '0;
            sf_s_q        <= c_s_q;
            sf_ret_q      <= 1'b0;
            if (c_valid) begin  // wake, tracking, init_open, in_init: per-sensor writes
              if (!wh_e[c_slot]) begin
                evt_valid_q <= 1'b1;
                evt_data_q  <= {20'd0, cw.init, 1'b1, 1'b0, 1'b0, c_s_q, cw.seq, clr, cw.we};
              end
              // c_safety (empty, missed too often while tracking): re-initialise now; every
              // window of the sensor is cancelled (the slots of every element by S_SAFE, one
              // element per clock); due = min(due, now): per-sensor writes
            end
          end
          S_SAFE: begin  // safety cancel: element sf_e_q's windows of sensor sf_s_q (per-element writes)
            sf_e_q <= sf_e_q + 1'b1;
            if (sf_e_q == '0) begin  // the cancel record (docs/fast_firing.md section 6)
              evt_valid_q <= 1'b1;
              evt_data_q  <= {2'b01, 1'b1, 16'd0, 1'b0, 1'b0, 3'b000, 3'(sf_s_q), 5'd0, cur_tick_q};
            end
            if (sf_e_q == RW'(NUM_CH - 1)) st_q <= sf_ret_q ? S_SCHED : S_HEAD;
          end
          S_HEAD: begin  // next window of element el_q to close: the earliest close (slot stream)
            if (srem_q != '0) srem_q <= srem_q & (srem_q - 1'b1);
            if (sv_d_q) begin
              found_q <= 1'b1;
              if (sw_first) begin
                minclose_q <= w_close_d_q;
                hk_q       <= sk_d_q;
              end
            end
            if (sv_idle) st_q <= S_HWR;
          end
          S_HWR: st_q <= S_DISP;  // the head: slot hk_q if found_q (per-element writes)
          // ------------------------------------------------ SCHED phase: sensors ascending
          S_SCHED: begin
            // wake, hold, tracking: per-sensor writes
            if (s_reinit) begin  // (model reinit_every) the same sensor again after the cancel, as untracked
              sf_e_q          <= '0;
              sf_s_q          <= s_q;
              sf_ret_q        <= 1'b1;
              st_q            <= S_SAFE;
            end else if (s_early || s_quiet) begin  // nxt: per-sensor writes
              st_q       <= S_NEXT;
            end else if (s_eval) begin
              o_q  <= '0;
              t_q  <= t_cand;
              st_q <= S_EDF;
            end else begin
              st_q <= S_NEXT;
            end
          end
          S_NEXT: begin
            if (s_q == VW'(NUM_VS - 1)) begin
              eng_tick_q <= cur_tick_q + 32'd1;
              st_q       <= S_SETTLE;
            end else begin
              s_q  <= s_q + 1'b1;
              st_q <= S_SCHED;
            end
          end
          S_EDF: begin  // earliest due first among sensors sharing an element
            if (eo_share_q && o_elig && o_first) begin  // hold: per-sensor writes
              st_q        <= S_NEXT;
            end else if (o_q == VW'(NUM_VS - 1)) begin
              rem_q      <= s_rx_q;
              cand_clr_q <= 1'b1;  // candidates and te_min / te_max cleared in S_CAND's first clock
              st_q       <= S_CAND;
            end else begin
              o_q <= o_q + 1'b1;
            end
          end
          S_CAND: begin  // one receiver per clock (stream): does it get a window, where
            if (rem_q != '0) rem_q <= rem_q & (rem_q - 1'b1);
            if (cv_e_q) begin
              cand_act_m[rl_e_q] <= !s_trk_q || ct_e_q;
              if (!s_trk_q) begin
                nwin_q <= nwin_q + 5'd1;
              end else if (ct_e_q) begin
                nwin_q            <= nwin_q + 5'd1;
                cand_te_q[rl_e_q] <= te_d_q;
                if (te_d_q < te_min_q) te_min_q <= te_d_q;
                if (te_d_q > te_max_q) te_max_q <= te_d_q;
              end
            end
            if (rem_q == '0 && !cv_b_q && !cv_c_q && !cv_d_q && !cv_e_q) begin
              n_q  <= s_order_q;
              st_q <= S_ORDER;
            end
          end
          S_ORDER: begin  // effective order: n = N, N-1, ..., 1, else 0 (one try per clock)
            rem_q       <= s_all_q;
            retry_vld_q <= 1'b0;
            if (!s_trk_q) begin
              period_q <= s_rmax_q;
              st_q     <= S_CONF;
            end else if (n_q == '0) begin
              period_q <= o_rhs_q[23:0];  // te_max + T_N
              st_q     <= S_CONF;
            end else if (o_feas) begin
              period_q <= o_ts_q;
              st_q     <= S_CONF;
            end else begin
              n_q <= n_q - OW'(1);
            end
          end
          S_CONF: begin  // next element the candidate touches: blank_until, then its slots
            if (rem_q == '0) begin
              if (retry_vld_q) begin
                st_q       <= S_NEXT;  // deferred: nxt = retry - P (per-sensor writes)
              end else begin
                st_q <= S_ISSUE;
              end
            end else begin
              el_q     <= rel;
              blk_on_q <= c_blk;
              win_on_q <= c_win;
              srem_q   <= wv_e;
              found_q  <= 1'b0;
              st_q     <= S_CSLOT;
            end
          end
          S_CSLOT: begin  // the reserved windows of element el_q (slot stream; retry: rn_new)
            if (srem_q != '0) srem_q <= srem_q & (srem_q - 1'b1);
            if (sv_d_q) begin
              found_q <= 1'b1;
              if (sw_first) minclose_q <= w_close_d_q;
            end
            if (sv_idle) st_q <= S_CFULL;
          end
          S_CFULL: begin  // every slot taken: retry at the earliest close (rn_new)
            rem_q <= rem_q & (rem_q - 1'b1);
            st_q  <= S_CONF;
          end
          S_ISSUE: begin  // the pulse goes: sensor state now, then element by element
            kseq_q           <= s_seq_q;
            // seq, quiet, epoch, ... and due, nxt: per-sensor writes
            pulse_q      <= 1'b1;
            pulse_vs_q   <= s_q;
            pulse_tx_q   <= s_tx_q;
            pulse_seq_q  <= s_seq_q;
            pulse_t0_q   <= t_q;
            pulse_init_q <= !s_trk_q;
            // the pulse record (docs/fast_firing.md section 6) goes ahead of the pulse's events
            evt_valid_q  <= 1'b1;
            evt_data_q   <= {2'b01, 1'b0, s_pid_q, 1'b0, !s_trk_q, 3'b000, 3'(s_q), nwin_q, t_q};
            rem_q        <= s_all_q;
            st_q         <= S_IEL;
          end
          S_IEL: begin  // element rel: blank_until, trigger, window slot
            if (rem_q == '0) begin
              st_q <= S_NEXT;
            end else begin
              rem_q <= rem_q & (rem_q - 1'b1);  // blank_until, window slot, head: per-element writes
              if (rel_tx_e) begin
                trig_valid_q <= 1'b1;
                trig_el_q    <= rel;
                trig_delay_q <= (DELAY_W + 1)'(trig_dly);
                trig_burst_q <= s_burst_q;
                if (trig_dly[31:DELAY_W+1] != '0) ovr_q <= 1'b1;  // negative or too far: engine late
              end
              if (c_win)
                win_q[int'(rel) * WSLOTS + int'(free_slot)] <= '{t0: t_q, ws: c_wso, we: c_weo, seq: kseq_q,
                                                                  epoch: s_ep_q, init: !s_trk_q};
            end
          end
          default: st_q <= S_OFF;
        endcase
      end
    end
  end

  // ---- tracking-state writes to SNS (rxs_wa, the read address in HIT and CLOSE): samples
  // (HIT), miss counts (CLOSE), reset of a sensor's receivers by its init ping (IEL)
  logic run_ok;   // the FSM's case statement runs in this cycle
  logic rxs_we;
  rxs_t rxs_wd;
  // no rst_i here (it would put the reset net into every write enable): in reset the FSM
  // goes to S_OFF, and what a state writes in the reset clock is cleared or rewritten by the
  // start (valid bits, S_INIT, the init pings) before anything reads it
  assign run_ok = !(!en_q && started_q) && go;
  always_comb begin
    rxs_we = 1'b0;
    rxs_wd = rxs_c_q;
    unique case (st_q)
      S_HIT: begin
        if (!h_wh_q && h_ep_q) begin
          if (hw.init) begin
            rxs_we = 1'b1;
            rxs_wd = '{trk: 1'b1, tof: h_tof, seq: hw.seq, v: 17'sd0, miss: 4'd0, init: 1'b1, vel: 1'b0};
          end else if (hrx.trk && h_gap_q != 8'd0 && !h_gap_q[7] && !h_rej_q) begin
            rxs_we = 1'b1;
            rxs_wd = '{trk: 1'b1, tof: h_tof, seq: hw.seq, v: (h_gap_q == 8'd1 && !hrx.init) ? h_v_q : 17'sd0,
                       miss: 4'd0, init: 1'b0, vel: h_gap_q == 8'd1 && !hrx.init};
          end
        end
      end
      S_CLOSE: begin
        if (c_valid && c_empty && !cw.init && c_ep_q) begin
          rxs_we = 1'b1;
          rxs_wd = '{trk: crx.trk, tof: crx.tof, seq: crx.seq, v: crx.v, miss: c_miss, init: crx.init, vel: crx.vel};
        end
      end
      S_IEL: begin
        if (rem_q != '0 && c_win && !s_trk_q) begin
          rxs_we = 1'b1;
          rxs_wd = '0;
        end
      end
      default: ;
    endcase
  end
  always_ff @(posedge clk_i) begin
    if (blk_we)                sns_q[blk_wa]          <= $bits(rxs_t)'(blk_wd);
    else if (run_ok && rxs_we) sns_q[{1'b0, rxs_wa}] <= rxs_wd;
  end
`ifndef SYNTHESIS
  always_ff @(posedge clk_i)
    if (!rst_i && blk_we && run_ok && rxs_we)
      $error("ms_scheduler: a load write and a tracking-state write in one clock");
`endif

  // ---- per-sensor due, next-evaluation (written as tick - P, precomputed in stage D) and quiet
  // ticks: one sensor per clock, in the go clocks of S_INIT, S_CLOSE, S_SCHED, S_CONF and
  // S_ISSUE, with registered state strobes (*_any_q, like the per-sensor strobes below). s_q is
  // stable through these states; S_CLOSE writes sensor c_s_q. The strobes are exclusive (each
  // decodes st_q; checked below), so each array has one write port: one address, one data
  // multiplexer selected by the strobes, one enable.
  logic        isu_any_q, cnf_any_q, sch_any_q, ini_any_q;
  logic        due_we, nxt_we;
  logic [VW-1:0] due_wa;
  logic [31:0] due_wd, nxt_wd;
  always_ff @(posedge clk_i) begin
    isu_any_q <= !rst_i && nx_go && st_q == S_ISSUE;
    cnf_any_q <= !rst_i && nx_go && st_q == S_CONF;
    sch_any_q <= !rst_i && nx_go && st_q == S_SCHED;
    ini_any_q <= !rst_i && nx_go && st_q == S_INIT;
  end
  always_comb begin
    // nxt_m holds the t0 of the next evaluation (its tick + P)
    if (isu_any_q)      nxt_wd = due_isu_q;    // t0 + period
    else if (cnf_any_q) nxt_wd = retry_t0_q;
    else if (sch_any_q) nxt_wd = s_early ? due_s_q : quiet_rd_q;
    else                nxt_wd = due_ini_q;    // start tick + phase
    nxt_we = ps_live && (ini_any_q || (sch_any_q && (s_early || s_quiet)) || (cnf_any_q && rem_q == '0 && retry_vld_q)
                         || isu_any_q);
    if (ini_any_q)      due_wd = due_ini_q;
    else if (isu_any_q) due_wd = due_isu_q;
    else                due_wd = cur_tick_q;  // S_CLOSE: a safety cancel, due = min(due, now)
    due_wa = cls_go_q ? c_s_q : s_q;
    due_we = ps_live && (ini_any_q || isu_any_q || (cls_go_q && c_safety && c_due_lt_q));
  end
  always_ff @(posedge clk_i) begin
    if (due_we) due_m[si(due_wa)] <= due_wd;
    if (nxt_we) nxt_m[si(s_q)] <= nxt_wd;
    if (ps_live && isu_any_q) quiet_m[si(s_q)] <= quiet_isu_q;  // t0 + max ToF - D
    // pulse id, pulse count: S_INIT clears, ISSUE counts; init-ping windows open: S_INIT
    // clears, ISSUE of an init ping sets (one per receiver), each of its closes counts down
    if (ps_live && (ini_any_q || isu_any_q)) begin
      seq_m[si(s_q)] <= ini_any_q ? 16'd0 : s_pid_q + 16'd1;
      trk_m[si(s_q)] <= (ini_any_q || !s_trk_q) ? 8'd0 : s_tpc_q + 8'(s_tpc_q != 8'hFF);
    end
    if (ps_live && cls_go_q && c_valid && cw.init && c_ep_q)
      open_m[si(c_s_q)] <= c_open_q - 6'd1;
    else if (ps_live && (ini_any_q || (isu_any_q && !s_trk_q)))
      open_m[si(s_q)] <= ini_any_q ? 6'd0 : s_nrx_q;
  end
`ifndef SYNTHESIS
  always_ff @(posedge clk_i) begin
    if (!rst_i && !$onehot0({isu_go_q, cnf_go_q, sch_go_q, ini_go_q}))
      $error("ms_scheduler: go strobes of two sensor states in one clock: %b", {isu_go_q, cnf_go_q, sch_go_q, ini_go_q});
    if (!rst_i && !$onehot0({isu_any_q, cnf_any_q, sch_any_q, ini_any_q, cls_go_q}))
      $error("ms_scheduler: two writers of the per-sensor ticks in one clock");
    // the shared strobes name the sensor of the per-sensor ones (s_q unchanged since)
    if (!rst_i && ({isu_any_q, cnf_any_q, sch_any_q, ini_any_q} != {|isu_go_q, |cnf_go_q, |sch_go_q, |ini_go_q}
                   || ((|{isu_go_q, cnf_go_q, sch_go_q, ini_go_q}) && !(isu_go_q[si(s_q)] || cnf_go_q[si(s_q)] || sch_go_q[si(s_q)] || ini_go_q[si(s_q)]))))
      $error("ms_scheduler: per-sensor write strobes disagree with s_q");
  end
`endif

  // ---- per-sensor state (seq, quiet, wake, hold, tracking, ...): written in the go clocks of
  // S_START, S_HIT, S_CLOSE, S_SCHED, S_EDF and S_ISSUE, as the FSM above says. The state (and,
  // where the sensor index is stable through the state, the sensor) part of each write enable
  // is registered the clock before the go clock, so no write enable waits for the st_q / ph_q
  // decode (in context that decode fanned out to 8 x 32 CE pins and was the slowest path at
  // 48 MHz). nx_go: the next clock is this state's go clock (need >= 1; S_START, need 0, is
  // entered only from S_LOAD, which sets start_go_q). ps_live is the FSM's stop guard: no write
  // in the stop clock, where the FSM's case statement does not run. The strobes are cleared in
  // reset; the reset net itself stays out of these enables (it crosses the chip): a strobe of
  // the clock before a reset may still write in the reset's first clock, and S_START writes
  // every sensor's state (quiet_q behind quiet_vld_q) before the engine reads any of it.
  assign nx_go   = !go && (ph_q + 3'd1 == need);
  assign ps_live = !(!en_q && started_q);
  always_ff @(posedge clk_i) begin
    for (int s = 0; s < NUM_VS; s++) begin
      isu_go_q[s] <= !rst_i && nx_go && st_q == S_ISSUE && s_q == VW'(s);
      sch_go_q[s] <= !rst_i && nx_go && st_q == S_SCHED && s_q == VW'(s);
      edf_go_q[s] <= !rst_i && nx_go && st_q == S_EDF && s_q == VW'(s);
      ini_go_q[s] <= !rst_i && nx_go && st_q == S_INIT && s_q == VW'(s);
      cnf_go_q[s] <= !rst_i && nx_go && st_q == S_CONF && s_q == VW'(s);
    end
    hit_go_q <= !rst_i && nx_go && st_q == S_HIT;
    cls_go_q <= !rst_i && nx_go && st_q == S_CLOSE;
  end
  always_ff @(posedge clk_i) begin
    if (ps_live) begin
      if (start_go_q) begin  // S_START: every sensor's state from scratch
        quiet_vld_q  <= '0;
        tracking_q   <= '0;
        in_init_q    <= '0;
        epoch_q      <= '0;
        wake_q       <= '0;
        hold_q       <= '0;
        any_trk_q    <= '0;
        reinit_due_q <= '0;
      end
      if (hit_go_q && !h_wh_q && h_ep_q) begin  // S_HIT: a first echo of the current epoch
        wake_q[si(h_s_q)] <= 1'b1;
        if (hw.init) any_trk_q[si(h_s_q)] <= 1'b1;
      end
      if (cls_go_q && c_valid) begin  // S_CLOSE
        wake_q[si(c_s_q)] <= 1'b1;
        if (c_empty && !cw.init && c_ep_q && c_kmiss_q && c_trk_q) begin
          tracking_q[si(c_s_q)] <= 1'b0;  // safety re-initialisation: every sensor re-evaluates
          wake_q            <= '1;
        end
        if (cw.init && c_ep_q) begin  // open_m: below
          if (c_last_q) begin
            in_init_q[si(c_s_q)]  <= 1'b0;
            tracking_q[si(c_s_q)] <= c_trk_nx_q;  // any_trk may include this tick's samples (EDGE before CLOSE)
          end
        end
      end
      for (int s = 0; s < NUM_VS; s++) begin
        if (sch_go_q[s]) begin  // S_SCHED
          if (s_eval && !s_reinit) begin
            wake_q[s] <= 1'b0;
            hold_q[s] <= 1'b0;
          end
          if (s_reinit) tracking_q[s] <= 1'b0;
        end
        if (edf_go_q[s] && eo_share_q && o_elig && o_first) hold_q[s] <= 1'b1;  // S_EDF: deferred
        if (isu_go_q[s]) begin  // S_ISSUE: the pulse goes
          quiet_vld_q[s]  <= 1'b1;
          reinit_due_q[s] <= s_trk_q && s_rdue_q;
          if (!s_trk_q) begin  // init ping: new epoch, every receiver untracked
            epoch_q[s]     <= !s_ep_q;
            in_init_q[s]   <= 1'b1;
            any_trk_q[s]   <= 1'b0;
          end
        end
        if ((|isu_go_q) && !isu_go_q[s]) wake_q[s] <= 1'b1;  // S_ISSUE: the other sensors re-evaluate
      end
    end
  end

  // ---- per-element arrays: one write per clock, at element ei (the FSM's states above say
  // when); valid bits and heads are cleared at once by reset, stop, S_STOP and S_START
  assign el_clr = rst_i || (!en_q && started_q) || (st_q == S_STOP) || (st_q == S_START);
  // ew_q[e]: the next clock is the go clock of a state working on element e (ei_q is valid
  // from a state's second clock and stable to its go clock; the states that write these
  // arrays, HIT, CLOSE, SAFE and IEL, all need >= 2, and HWR follows HEAD on the same element),
  // so a per-element write enable is a flop and the state's write flag, not the go / st_q
  // decode and a 5-bit compare
  logic [NUM_CH-1:0] ew_q;
  always_ff @(posedge clk_i)
    for (int e = 0; e < NUM_CH; e++) ew_q[e] <= nx_go && ei_q == RW'(e);
  // The head's write enables (hd_lo_q and the block flags: 24 x 7 CE pins, hd_vld_q) are
  // registered per element in the clock before the go clock too, with their data conditions
  // taken from registers that hold their final values from that clock (w_close_c_q,
  // iw_close_d_q: the compare iw_first_d_q registers, one clock earlier; stage A). (From the
  // stage-D flops through the state decode, hd_we fanned out to 768 CE pins: the slowest
  // scheduler path of the board top at 62.4 MHz.) hd_we / hdv_we still drive the head's slot
  // RAM write and the simulation check below.
  // The slot-valid RAM's write enable and its per-element valid flags (wv_ok_q) likewise:
  // S_CLOSE's c_valid one clock early is what c_wv_q / c_eq_q register at the go edge.
  logic              hd_we_nx, hdv_we_nx, wv_we_nx;
  logic [NUM_CH-1:0] hdw_q, hdvw_q, wvw_q;
  logic              hdw_any_q;  // some hdw_q[e]: the hd_close_m write
  always_comb begin
    hd_we_nx  = 1'b0;
    hdv_we_nx = 1'b0;
    wv_we_nx  = 1'b0;
    unique case (st_q)
      S_CLOSE: begin
        hdv_we_nx = 1'b1;
        wv_we_nx  = wv_e[c_slot] && w_close_c_q == cur_tick_q;
      end
      S_SAFE: wv_we_nx = 1'b1;
      S_HWR: begin
        hdv_we_nx = 1'b1;
        hd_we_nx  = found_q;
      end
      S_IEL: begin
        hd_we_nx  = rem_q != '0 && c_win && (!hd_vld_e || $signed(iw_close_d_q - w_close_c_q) < 0);
        hdv_we_nx = hd_we_nx;
        wv_we_nx  = rem_q != '0 && c_win;
      end
      default: ;
    endcase
  end
  always_ff @(posedge clk_i)
    for (int e = 0; e < NUM_CH; e++) begin
      hdw_q[e]  <= nx_go && ei_q == RW'(e) && hd_we_nx;
      hdvw_q[e] <= nx_go && ei_q == RW'(e) && hdv_we_nx;
      wvw_q[e]  <= nx_go && ei_q == RW'(e) && wv_we_nx;
    end
  logic wvw_any_q;  // some wvw_q[e]: the wv_m write
  always_ff @(posedge clk_i) begin
    hdw_any_q <= nx_go && hd_we_nx;
    wvw_any_q <= nx_go && wv_we_nx;
  end
`ifndef SYNTHESIS
  // every head's whole close tick, for the checks below (the engine reads it from WIN)
  logic [31:0] hd_close_m [NUM_CH];
  always_ff @(posedge clk_i) if (ps_live && hdw_any_q) hd_close_m[ei_q] <= hd_close_wd;
  // simulation checks (the scoreboards run with them): the early enables are the go clock's,
  // and a head is written with a close tick in the future and never over one closing now
  // (close_eq_q compares the head of one clock before)
  always_ff @(posedge clk_i) begin
    if (!rst_i && (hdw_q != (ew_q & {NUM_CH{hd_we}}) || hdvw_q != (ew_q & {NUM_CH{hdv_we}})))
      $error("ms_scheduler: early head write enables %h/%h, go clock's %h/%h (state %0d)",
             hdw_q, hdvw_q, ew_q & {NUM_CH{hd_we}}, ew_q & {NUM_CH{hdv_we}}, st_q);
    if (!rst_i && wvw_q != (ew_q & {NUM_CH{wv_we}}))
      $error("ms_scheduler: early slot-valid write enables %h, go clock's %h (state %0d)",
             wvw_q, ew_q & {NUM_CH{wv_we}}, st_q);
    if (!rst_i && hdw_any_q != (|hdw_q))
      $error("ms_scheduler: head RAM write %b, head flop writes %h", hdw_any_q, hdw_q);
    if (!rst_i && hd_vld_q[ei_q] && hd_close_m[ei_q][LB-1:0] != hd_lo_q[ei_q])
      $error("ms_scheduler: element %0d's head RAM %0d, flops %0d", ei_q, hd_close_m[ei_q], hd_lo_q[ei_q]);
    // the block flags of every valid head say whether its close tick is in tick_i's block
    for (int e = 0; e < NUM_CH; e++)
      if (!rst_i && hd_vld_q[e] && blk_cur_q[e] != (hd_close_m[e][HCW-1:LB] == tick_i[HCW-1:LB]))
        $error("ms_scheduler: element %0d's head closes at %0d, block flag %b at tick %0d",
               e, hd_close_m[e], blk_cur_q[e], tick_i);
    for (int e = 0; e < NUM_CH; e++)
      if (!rst_i && ps_live && hdw_q[e]
          && ($signed(hd_close_wd - tick_i) <= 0 || (hd_close_wd - tick_i) >= 32'(1) << (HCW - 1)
              || (hd_vld_q[e] && hd_close_m[e][HCW-1:0] == tick_i[HCW-1:0])))
        $error("ms_scheduler: element %0d's head written at tick %0d with close tick %0d over %0d (low %0d bits)",
               e, tick_i, hd_close_wd, hd_close_m[e], HCW);
  end
`endif
  always_comb begin
    sid_kill = (st_q == S_SAFE) ? sf_s_q : c_s_q;
    for (int k = 0; k < WSLOTS; k++) sid_mask[k] = (wsid_e[k] == sid_kill);
    wv_we       = 1'b0;
    wv_wd       = wv_e;
    wh_we       = 1'b0;
    wh_wd       = wh_e;
    wr_wd       = wr_e;  // written with wh (same enable)
    wsid_we     = 1'b0;
    wsid_wd     = wsid_e;
    bu_we       = 1'b0;
    bu_wd       = tb_c_q;  // t0 + b
    tu_we       = 1'b0;
    hd_we       = 1'b0;
    hd_close_wd = (st_q == S_IEL) ? iw_close : minclose_q;  // else S_HWR
    hd_slot_wd  = (st_q == S_IEL) ? free_slot : hk_q;
    hdv_we      = 1'b0;
    hdv_wd      = 1'b0;
    unique case (st_q)
      S_HIT: begin
        if (!h_wh_q) begin
          wh_we          = 1'b1;
          wh_wd[fslot_q] = 1'b1;
          wr_wd[fslot_q] = h_ep_q && h_rej_q;
        end
      end
      S_CLOSE: begin
        hdv_we = 1'b1;  // rescanned in S_HEAD
        if (c_valid) begin
          wv_we          = 1'b1;
          wv_wd[c_slot]  = 1'b0;
          if (c_safety) wv_wd = wv_wd & ~sid_mask;
        end
      end
      S_SAFE: begin
        wv_we = 1'b1;
        wv_wd = wv_e & ~sid_mask;
      end
      S_HWR: begin  // the earliest close of the element's slots, or no head
        hdv_we = 1'b1;
        hdv_wd = found_q;
        hd_we  = found_q;
      end
      S_IEL: begin
        if (rem_q != '0) begin
          bu_we = c_blk && bu_later_d_q;     // later(bu_wd, bu_e)
          tu_we = rel_tx_e && tu_later_d_q;  // later(bu_wd, tu_e): a tx element's blank is its dead zone
          if (c_win) begin
            wv_we              = 1'b1;
            wv_wd              = wv_e | (wv_e + 1'b1);  // bit free_slot (the lowest free) set, as a carry chain
            wh_we              = 1'b1;
            wh_wd[free_slot]   = 1'b0;
            wr_wd[free_slot]   = 1'b0;
            wsid_we            = 1'b1;
            wsid_wd[free_slot] = s_q;
            if (iw_first_d_q) begin  // !hd_vld_e || iw_close earlier than hd_close_e
              hd_we  = 1'b1;
              hdv_we = 1'b1;
              hdv_wd = 1'b1;
            end
          end
        end
      end
      default: ;
    endcase
  end
  always_ff @(posedge clk_i) begin
    for (int e = 0; e < NUM_CH; e++) begin
      if (el_clr)                        wv_ok_q[e] <= 1'b0;
      else if (ps_live && wvw_q[e])       wv_ok_q[e] <= 1'b1;
      if (el_clr)                     hd_vld_q[e] <= 1'b0;
      else if (ps_live && hdvw_q[e])  hd_vld_q[e] <= hdv_wd;
      if (ps_live && hdw_q[e])        hd_lo_q[e] <= hd_close_wd[LB-1:0];
      if (rst_i || (run_ok && st_q == S_START)) bu_ok_q[e] <= 1'b0;
      else if (ps_live && ew_q[e] && bu_we)     bu_ok_q[e] <= 1'b1;
      if (rst_i || (run_ok && st_q == S_START)) tu_ok_q[e] <= 1'b0;
      else if (ps_live && ew_q[e] && tu_we)     tu_ok_q[e] <= 1'b1;
    end
  end
  always_ff @(posedge clk_i) begin
    if (ps_live && wvw_any_q) wv_m[ei_q]   <= wv_wd;  // as wv_ok_q[ei_q] (wvw_q)
    if (run_ok && wh_we)   wh_m[ei_q]      <= wh_wd;
    if (run_ok && wh_we)   wr_m[ei_q]      <= wr_wd;
    if (run_ok && wsid_we) wsid_m[ei_q]    <= wsid_wd;
    if (run_ok && bu_we)   bu_m[ei_q]      <= bu_wd;
    if (run_ok && tu_we)   tu_m[ei_q]      <= bu_wd;
    if (run_ok && hd_we)   hd_slot_m[ei_q] <= hd_slot_wd;
    if (ps_live && hdw_any_q) hd_hi_m[ei_q]    <= hd_close_wd[HCW-1:LB];
  end

  // Block flags of the heads' close ticks (see hd_lo_q). In the clock with tick_i = T:
  // blk_cur_q[e] == (head e's close block == block(T)) for every head written since reset, and
  // blk_nxt_q[e] == (... == block(T) + 1) once the scan has passed e in T's block (always by
  // the block's last clock, where blk_cur_q takes it; NUM_CH < 2^LB). A head write sets both
  // from the new tick against block(T+1) and block(T+1) + 1 (blk_c_q, blk_n_q: registered from
  // tick_i + 2, as tick_i counts by one). The simulation check above compares blk_cur_q of
  // every valid head with its close tick in every clock.
  logic [HBW-1:0] blk_c_q, blk_n_q, hbw_t2;
  logic [LB-1:0]  blk_pos;
  logic           blk_end, blk_wc, blk_wn, blk_sn;
  assign hbw_t2  = HBW'((tick_i[HCW-1:0] + HCW'(2)) >> LB);
  assign blk_pos = tick_i[LB-1:0];
  assign blk_end = (blk_pos == '1);
  assign blk_wc  = (hd_close_wd[HCW-1:LB] == blk_c_q);
  assign blk_wn  = (hd_close_wd[HCW-1:LB] == blk_n_q);
  assign blk_sn  = (hd_hi_m[blk_pos] == blk_n_q);
  always_ff @(posedge clk_i) begin
    blk_c_q <= hbw_t2;
    blk_n_q <= hbw_t2 + HBW'(1);
    for (int e = 0; e < NUM_CH; e++) begin
      if (rst_i) begin
        blk_cur_q[e] <= 1'b0;
        blk_nxt_q[e] <= 1'b0;
      end else if (ps_live && hdw_q[e]) begin
        blk_cur_q[e] <= blk_wc;
        blk_nxt_q[e] <= blk_wn;
      end else begin
        if (blk_end)                blk_cur_q[e] <= blk_nxt_q[e];
        if (blk_pos == LB'(e))      blk_nxt_q[e] <= blk_sn;
      end
    end
  end

  // ---- outputs
  assign trig_valid_o   = trig_valid_q;
  assign trig_el_o      = trig_el_q;
  assign trig_delay_o   = trig_delay_q;
  assign trig_burst_o   = trig_burst_q;
  assign pulse_o        = pulse_q;
  assign pulse_vs_o     = pulse_vs_q;
  assign pulse_tx_o     = pulse_tx_q;
  assign pulse_seq_o    = pulse_seq_q;
  assign pulse_t0_o     = pulse_t0_q;
  assign pulse_init_o   = pulse_init_q;
  assign evt_valid_o    = evt_valid_q;
  assign evt_data_o     = evt_data_q;
  assign running_o      = started_q;
  assign cfg_error_o    = cfg_err_q;
  assign cfg_error_vs_o = cfg_err_vs_q;
  assign overrun_o      = ovr_q;

  // fields of the shared record views that a given state does not need
  logic unused_ok;
  assign unused_ok = ^{grx.trk, grx.tof, grx.v, grx.miss, grx.init, grx.vel, irx.trk, irx.vel, irx.tof, irx.v, hw.ws, hw.we,
                       hw.t0, hrx.tof[23:1], hrx.seq, hrx.v, hrx.miss, cw.ws, cw.t0, irx.miss, irx.init,
                       o_mul[26:0], ld_use, cfg_blk_addr, ld_tx, ld_order,
                       ld_reinit, ld_tv, ld_tn, ld_rmax, ld_phase, ld_burst};
endmodule
