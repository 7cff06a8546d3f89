// ms_sched_cfg: the scheduler's configuration check and load (docs/sonar_core.md).
//
// A check reads the CSR's virtual-sensor table one entry at a time (its nine words, then the
// phasing delay of every element) and reports the first refusal, in the order of
// multisonar.simdevice.decode_vs_table: codes of docs/protocol.md section 5
// (multisonar.protocol.CfgError), the lowest refused entry first, EMPTY_TABLE when no entry
// is enabled. A load writes, per entry, the scheduler's per-sensor record (ld_*), whether it
// shares an element with each lower entry (share_*) and each element's blank interval
// (blk_*: offsets from t0 [a, b), a tx element: its delay, delay + T_dead; a crosstalk
// neighbour: its first and last neighbouring tx delays (within nb), the last + T_xtalk; any
// other element: 0, 0). One register set serves every entry; every step is one table word,
// one delay or one sensor pair per clock.
//
// Timing contract (clocks of clk_i):
//   - check_i / load_i: one-clock strobes while busy_o is low; busy_o is high from the next
//     clock until done_o. abort_i returns to idle in the next clock, without done_o.
//   - vs_rdata_i / delay_rdata_i carry the word addressed in the clock before.
//   - check: per entry 10 clocks (its words), then, for an enabled entry, NUM_CH + 2 (delays)
//     and 4 (the checks); done_o one clock after the last entry, err_o / err_vs_o (0 / 0:
//     accepted) valid from done_o until the next check_i.
//   - load: per entry 10 + NUM_CH + 2 clocks (words, each with word_we_o, and delays), 4
//     (record: ld_we_o one clock, ld_* valid with it), entry + 1 (share_we_o for the pairs
//     (entry, 0..entry)), 7 NUM_CH (blank intervals) and 4 (drain; blk_we_o one clock per
//     element, the last one three clocks before the drain ends); done_o one clock after the
//     last entry.
//   - The table must not change between a check and the load that follows it.
module ms_sched_cfg #(
  parameter int NUM_CH    = 24,   // elements (<= 31)
  parameter int NUM_VS    = 8,    // table entries (2..8)
  parameter int DELAY_W   = 16,
  parameter int LEAD      = 4096, // decision lead P, ticks (ms_scheduler's LEAD)
  parameter int MAX_ORDER = 8,
  parameter int DW        = 19,   // T_dead / T_xtalk width
  parameter int BW        = 20,   // blank end offset width
  parameter int OW        = 4     // order width
) (
  input  logic                  clk_i,
  input  logic                  rst_i,
  input  logic                  check_i,
  input  logic                  load_i,
  input  logic                  abort_i,
  output logic                  busy_o,
  output logic                  done_o,
  output logic [3:0]            err_o,
  output logic [3:0]            err_vs_o,
  // the CSR's table (word entry * 9 + register) and delay RAM ({entry, element})
  output logic                  vs_ren_o,    // vs_raddr_o is read in this clock
  output logic [6:0]            vs_raddr_o,
  input  logic [31:0]           vs_rdata_i,
  output logic [7:0]            delay_raddr_o,
  input  logic [DELAY_W-1:0]    delay_rdata_i,
  input  logic [15:0]           burst_half_period_i,
  // per-sensor record of entry ld_vs_o
  output logic                  ld_we_o,
  output logic [2:0]            ld_vs_o,
  output logic [NUM_CH-1:0]     ld_tx_o,
  output logic [NUM_CH-1:0]     ld_rx_o,
  output logic [NUM_CH-1:0]     ld_xt_o,     // crosstalk neighbours: within nb of tx, not tx
  output logic [NUM_CH-1:0]     ld_use_o,    // tx | rx | crosstalk
  output logic                  ld_act_o,    // mode != off
  output logic                  ld_track_o,  // mode == track
  output logic [OW-1:0]         ld_order_o,
  output logic [3:0]            ld_k_o,
  output logic [7:0]            ld_reinit_o,
  output logic [15:0]           ld_tv_o,
  output logic [15:0]           ld_tn_o,
  output logic [15:0]           ld_vmax_o,
  output logic [23:0]           ld_rmax_o,
  output logic [23:0]           ld_phase_o,
  output logic [23:0]           ld_dbl_o,    // blanking: max(T_dead, T_xtalk) + largest tx delay
  output logic [23:0]           ld_lo_o,     // dbl + T_V
  output logic [23:0]           ld_hi_o,     // max ToF - T_N
  output logic [7:0]            ld_burst_o,
  // during a load, table word word_o of entry ld_vs_o is on vs_rdata_i (word_we_o)
  output logic                  word_we_o,
  output logic [3:0]            word_o,
  // blank interval of element blk_addr_o[4:0] of entry blk_addr_o[7:5]
  output logic                  blk_we_o,
  output logic [7:0]            blk_addr_o,
  output logic [DELAY_W-1:0]    blk_a_o,
  output logic [BW-1:0]         blk_b_o,
  // entries share_a_o and share_b_o use a common element (share_o); the relation is symmetric
  output logic                  share_we_o,
  output logic [2:0]            share_a_o,
  output logic [2:0]            share_b_o,
  output logic                  share_o
);
  localparam int RW = 5;
  localparam int VW = 3;
  localparam int SW = $clog2(NUM_VS);
  localparam logic [3:0] E_EMPTY_TABLE = 4'd1;
  localparam logic [3:0] E_BAD_MODE    = 4'd2;
  localparam logic [3:0] E_TX_MASK     = 4'd3;
  localparam logic [3:0] E_RX_MASK     = 4'd4;
  localparam logic [3:0] E_ORDER       = 4'd5;
  localparam logic [3:0] E_WINDOW      = 4'd6;
  localparam logic [3:0] E_MISS_LIMIT  = 4'd7;
  localparam logic [3:0] E_MAX_TOF     = 4'd9;
  localparam logic [3:0] E_BURST       = 4'd10;
  localparam logic [3:0] E_LEAD        = 4'd11;  // blanking D <= decision lead
  localparam logic [3:0] E_WIN_SHORT   = 4'd12;  // T_V + T_N <= decision lead
  if (NUM_VS < 2 || NUM_VS > 8) begin : g_bad_num_vs
    $error("ms_sched_cfg: NUM_VS = %0d, supported 2..8", NUM_VS);
  end

  function automatic logic [NUM_CH-1:0] rotl(input logic [NUM_CH-1:0] v, input int k);
    rotl = (v << k) | (v >> (NUM_CH - k));
  endfunction
  function automatic logic [NUM_CH-1:0] rotr(input logic [NUM_CH-1:0] v, input int k);
    rotr = (v >> k) | (v << (NUM_CH - k));
  endfunction
  function automatic logic [NUM_CH-1:0] xt_of(input logic [NUM_CH-1:0] tx, input logic [1:0] nb);
    logic [NUM_CH-1:0] m;
    m = '0;
    for (int k = 1; k <= 3; k++) if (k <= int'(nb)) m = m | rotl(tx, k) | rotr(tx, k);
    xt_of = m & ~tx;
  endfunction

  // ------------------------------------------------------------------ control
  typedef enum logic [2:0] {
    C_IDLE, C_GATHER, C_SCAN, C_CHECK, C_RECORD, C_SHARE, C_BLANK, C_DONE
  } cfg_state_t;
  cfg_state_t        st_q, st_d;
  logic              load_q, load_d;    // the operation is a load (else a check)
  logic [VW-1:0]     e_q, e_d;          // table entry
  logic [RW-1:0]     cnt_q, cnt_d;      // word, element, pair or clock within the step
  logic [2:0]        k_q, k_d;          // C_BLANK: neighbour offset k - 3
  logic              drain_q, drain_d;  // C_BLANK: the last element's reads are on their way
  logic [3:0]        err_q, err_d, errvs_q, errvs_d, v_err;
  logic              any_q;             // an entry so far is enabled

  // the fields of entry e_q (C_GATHER), its delay scan (C_SCAN), then three registered steps
  logic [1:0]         mode_q;
  logic [NUM_CH-1:0]  tx_q, rx_q;
  logic [OW-1:0]      order_q;
  logic [3:0]         k_f_q;
  logic [7:0]         reinit_q, burst_q;
  logic [15:0]        tv_q, tn_q, vmax_q;
  logic [DW-1:0]      dead_q, xtk_q;
  logic [23:0]        tmax_q, phase_q;
  logic [1:0]         nb_q;
  logic [DELAY_W-1:0] dmax_q;
  logic [RW-1:0]      runs_q;

  always_comb begin
    st_d    = st_q;
    load_d  = load_q;
    e_d     = e_q;
    cnt_d   = cnt_q;
    k_d     = k_q;
    drain_d = drain_q;
    err_d   = err_q;
    errvs_d = errvs_q;
    unique case (st_q)
      C_IDLE: begin
        if (check_i || load_i) begin
          load_d = load_i;
          e_d    = '0;
          cnt_d  = '0;
          st_d   = C_GATHER;
          if (!load_i) begin
            err_d   = '0;
            errvs_d = '0;
          end
        end
      end
      C_GATHER: begin  // words 0..8 of entry e_q, the last registered in the clock cnt == 9
        cnt_d = cnt_q + 1'b1;
        if (cnt_q == RW'(9)) begin
          cnt_d = '0;
          st_d  = C_SCAN;
          if (!load_q && mode_q == 2'd0) begin  // a disabled entry is not checked
            if (e_q == VW'(NUM_VS - 1)) begin
              st_d = C_DONE;
              if (!any_q) err_d = E_EMPTY_TABLE;
            end else begin
              e_d  = e_q + 1'b1;
              st_d = C_GATHER;
            end
          end
        end
      end
      C_SCAN: begin  // delays of elements 0..NUM_CH-1; the largest tx delay two clocks later
        cnt_d = cnt_q + 1'b1;
        if (cnt_q == RW'(NUM_CH + 1)) begin
          cnt_d = '0;
          st_d  = load_q ? C_RECORD : C_CHECK;
        end
      end
      C_CHECK: begin  // the registered steps p1..p3, then the first refusal
        cnt_d = cnt_q + 1'b1;
        if (cnt_q == RW'(3)) begin
          cnt_d = '0;
          if (v_err != 4'd0) begin
            err_d   = v_err;
            errvs_d = 4'(e_q);
            st_d    = C_DONE;
          end else if (e_q == VW'(NUM_VS - 1)) begin
            st_d = C_DONE;
          end else begin
            e_d  = e_q + 1'b1;
            st_d = C_GATHER;
          end
        end
      end
      C_RECORD: begin  // p1..p3, then the record (ld_we_o)
        cnt_d = cnt_q + 1'b1;
        if (cnt_q == RW'(3)) begin
          cnt_d = '0;
          st_d  = C_SHARE;
        end
      end
      C_SHARE: begin  // pairs (e_q, cnt_q), cnt_q = 0..e_q
        cnt_d = cnt_q + 1'b1;
        if (cnt_q == RW'(e_q)) begin
          cnt_d   = '0;
          k_d     = '0;
          drain_d = 1'b0;
          st_d    = C_BLANK;
        end
      end
      C_BLANK: begin  // element cnt_q, offset k_q - 3; then four clocks for the last writes
        if (drain_q) begin
          k_d = k_q + 1'b1;
          if (k_q == 3'd3) begin
            cnt_d = '0;
            if (e_q == VW'(NUM_VS - 1)) begin
              st_d = C_DONE;
            end else begin
              e_d  = e_q + 1'b1;
              st_d = C_GATHER;
            end
          end
        end else if (k_q == 3'd6) begin
          k_d   = '0;
          cnt_d = cnt_q + 1'b1;
          if (cnt_q == RW'(NUM_CH - 1)) drain_d = 1'b1;
        end else begin
          k_d = k_q + 1'b1;
        end
      end
      C_DONE: st_d = C_IDLE;
      default: st_d = C_IDLE;
    endcase
    if (abort_i) st_d = C_IDLE;
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      st_q    <= C_IDLE;
      load_q  <= 1'b0;
      e_q     <= '0;
      cnt_q   <= '0;
      k_q     <= '0;
      drain_q <= 1'b0;
      err_q   <= '0;
      errvs_q <= '0;
    end else begin
      st_q    <= st_d;
      load_q  <= load_d;
      e_q     <= e_d;
      cnt_q   <= cnt_d;
      k_q     <= k_d;
      drain_q <= drain_d;
      err_q   <= err_d;
      errvs_q <= errvs_d;
    end
  end
  assign busy_o   = st_q != C_IDLE;
  assign done_o   = st_q == C_DONE;
  assign err_o    = err_q;
  assign err_vs_o = errvs_q;

  // ------------------------------------------------------------------ table words
  logic       gv_q;  // word gw_q of entry e_q is on vs_rdata_i
  logic [3:0] gw_q;
  assign vs_raddr_o = {1'b0, e_q, 3'b0} + 7'(e_q) + 7'(cnt_q[3:0]);
  assign vs_ren_o   = st_q == C_GATHER && cnt_q < RW'(9);
  always_ff @(posedge clk_i) begin
    gv_q <= !rst_i && st_q == C_GATHER && cnt_q < RW'(9);
    gw_q <= cnt_q[3:0];
    if (st_q == C_IDLE) any_q <= 1'b0;
    if (gv_q) begin
      unique case (gw_q)
        4'd0: tx_q <= vs_rdata_i[NUM_CH-1:0];
        4'd1: rx_q <= vs_rdata_i[NUM_CH-1:0];
        4'd2: begin
          mode_q   <= vs_rdata_i[1:0];
          order_q  <= vs_rdata_i[7:4];
          k_f_q    <= vs_rdata_i[11:8];
          reinit_q <= vs_rdata_i[19:12];
          any_q    <= any_q || vs_rdata_i[1:0] != 2'd0;
        end
        4'd3: {tn_q, tv_q} <= vs_rdata_i;
        4'd4: dead_q <= vs_rdata_i[DW-1:0];
        4'd5: tmax_q <= vs_rdata_i[23:0];
        4'd6: begin
          nb_q  <= vs_rdata_i[21:20];
          xtk_q <= vs_rdata_i[DW-1:0];
        end
        4'd7: {burst_q, vmax_q} <= vs_rdata_i[23:0];
        default: phase_q <= vs_rdata_i[23:0];
      endcase
    end
  end

  // ------------------------------------------------------------------ delay scan
  // One delay per clock; the tx bit of the element read comes from a rotating copy of the tx
  // mask (rot_q[0]: element cnt_q, rot_q[NUM_CH-1]: the one before), which also counts the
  // mask's runs (an element in tx whose predecessor is not).
  logic [NUM_CH-1:0]  rot_q;
  logic               sv1_q, sv2_q;
  logic [DELAY_W-1:0] sd_q;
  always_ff @(posedge clk_i) begin
    if (st_q == C_GATHER) begin
      rot_q  <= tx_q;
      runs_q <= '0;
      dmax_q <= '0;
    end else if (st_q == C_SCAN) begin
      rot_q <= rotr(rot_q, 1);
      if (cnt_q < RW'(NUM_CH) && rot_q[0] && !rot_q[NUM_CH-1]) runs_q <= runs_q + 1'b1;
    end
    sv1_q <= st_q == C_SCAN && cnt_q < RW'(NUM_CH) && rot_q[0];
    sv2_q <= sv1_q;
    sd_q  <= delay_rdata_i;
    if (st_q != C_GATHER && sv2_q && sd_q > dmax_q) dmax_q <= sd_q;
  end

  // ------------------------------------------------------------------ checks and derived fields
  // Three registered steps from the entry's fields (stable from C_CHECK / C_RECORD's first
  // clock on), so no clock carries more than one carry chain.
  logic [25:0]       p1_burst_ticks;
  logic [DW-1:0]     p1_dx;
  logic [16:0]       p1_tvn;
  logic              p1_txbad, p1_rx0, p1_order, p1_k0, p1_b0, p1_w0;
  logic [NUM_CH-1:0] p1_xt;
  logic [23:0]       p1_hi;
  logic [23:0]       p2_dbl;
  logic              p2_dshort, p2_wshort;
  logic [NUM_CH-1:0] p2_use;
  logic              p3_tof, p3_lead;
  logic [23:0]       p3_lo;
  always_ff @(posedge clk_i) begin
    p1_burst_ticks <= 26'(burst_q) * 26'({burst_half_period_i, 1'b0});
    p1_dx          <= (dead_q > xtk_q) ? dead_q : xtk_q;
    p1_tvn         <= 17'(tv_q) + 17'(tn_q);
    p1_txbad       <= tx_q == '0 || (tx_q != '1 && runs_q != RW'(1));
    p1_rx0         <= rx_q == '0;
    p1_order       <= order_q > OW'(MAX_ORDER);
    p1_k0          <= k_f_q == 4'd0;
    p1_b0          <= burst_q == 8'd0;
    p1_w0          <= tv_q == '0 || tn_q == '0 || xtk_q == '0;
    p1_xt          <= xt_of(tx_q, nb_q);
    p1_hi          <= tmax_q - 24'(tn_q);
    p2_dbl         <= 24'(p1_dx) + 24'(dmax_q);
    p2_dshort      <= 26'(dead_q) < p1_burst_ticks;
    p2_wshort      <= p1_tvn <= 17'(LEAD / 2);
    p2_use         <= tx_q | rx_q | p1_xt;
    p3_tof         <= 26'(tmax_q) < 26'(p2_dbl) + 26'(p1_tvn);
    p3_lead        <= p2_dbl <= 24'(LEAD);
    p3_lo          <= p2_dbl + 24'(tv_q);
  end
  always_comb begin
    v_err = 4'd0;
    if (mode_q == 2'd3)            v_err = E_BAD_MODE;
    else if (p1_txbad)             v_err = E_TX_MASK;
    else if (p1_rx0)               v_err = E_RX_MASK;
    else if (p1_order)             v_err = E_ORDER;
    else if (p1_k0)                v_err = E_MISS_LIMIT;
    else if (p1_b0)                v_err = E_BURST;
    else if (p1_w0 || p2_dshort)   v_err = E_WINDOW;
    else if (p3_tof)               v_err = E_MAX_TOF;
    else if (p3_lead)              v_err = E_LEAD;
    else if (p2_wshort)            v_err = E_WIN_SHORT;
  end

  // ------------------------------------------------------------------ record
  assign ld_we_o     = st_q == C_RECORD && cnt_q == RW'(3);
  assign ld_vs_o     = e_q;
  assign ld_tx_o     = tx_q;
  assign ld_rx_o     = rx_q;
  assign ld_xt_o     = p1_xt;
  assign ld_use_o    = p2_use;
  assign ld_act_o    = mode_q != 2'd0;
  assign ld_track_o  = mode_q == 2'd1;
  assign ld_order_o  = order_q;
  assign ld_k_o      = k_f_q;
  assign ld_reinit_o = reinit_q;
  assign ld_tv_o     = tv_q;
  assign ld_tn_o     = tn_q;
  assign ld_vmax_o   = vmax_q;
  assign ld_rmax_o   = tmax_q;
  assign ld_phase_o  = phase_q;
  assign ld_dbl_o    = p2_dbl;
  assign ld_lo_o     = p3_lo;
  assign ld_hi_o     = p1_hi;
  assign ld_burst_o  = burst_q;
  assign word_we_o   = gv_q && load_q;
  assign word_o      = gw_q;

  // ------------------------------------------------------------------ shared elements
  // every loaded entry's element set, read back for the pairs (e_q, 0..e_q)
  logic [NUM_CH-1:0] use_m [NUM_VS];
  logic              sh_we_q, sh_q;
  logic [VW-1:0]     sh_b_q;
  always_ff @(posedge clk_i) begin
    if (ld_we_o) use_m[SW'(e_q)] <= p2_use;
    sh_we_q <= !rst_i && st_q == C_SHARE;
    sh_b_q  <= cnt_q[VW-1:0];
    sh_q    <= |(p2_use & use_m[SW'(cnt_q)]);
  end
  assign share_we_o = sh_we_q;
  assign share_a_o  = e_q;
  assign share_b_o  = sh_b_q;
  assign share_o    = sh_q;

  // ------------------------------------------------------------------ blank intervals
  // Element cnt_q reads the delays of elements cnt_q - 3 .. cnt_q + 3 (k_q 0..6). Rotating
  // copies hold the tx bits around it (wnd_q[k]: element cnt_q + k - 3) and its crosstalk bit
  // (xr_q[0]). Stage 1: the step's flags with the address; stage 2: the delay; stage 3: first
  // and last delay of the element; stage 4: the element's interval (blk_*).
  logic [NUM_CH-1:0] wnd_q, xr_q;
  logic signed [6:0] bj_raw;
  logic [RW-1:0]     bj;
  logic [2:0]        bdist;
  logic              buse;
  assign bj_raw = $signed({2'b0, cnt_q}) + $signed({4'b0, k_q}) - 7'sd3;
  assign bj     = (bj_raw < 0) ? RW'(bj_raw + 7'(NUM_CH))
                : (bj_raw >= 7'(NUM_CH)) ? RW'(bj_raw - 7'(NUM_CH)) : RW'(bj_raw);
  assign bdist  = (k_q >= 3'd3) ? k_q - 3'd3 : 3'd3 - k_q;
  assign buse   = wnd_q[RW'(k_q)] && ((k_q == 3'd3) || (xr_q[0] && bdist <= {1'b0, nb_q}));
  assign delay_raddr_o = {e_q, (st_q == C_BLANK) ? bj : cnt_q};

  logic               b1_v_q, b1_use_q, b1_last_q, b1_tx_q;
  logic [RW-1:0]      b1_e_q;
  logic               b2_v_q, b2_use_q, b2_last_q, b2_tx_q;
  logic [RW-1:0]      b2_e_q;
  logic [DELAY_W-1:0] b2_d_q, first_q, last_q;
  logic               bany_q, w3_q, w3_any_q, w3_tx_q;
  logic [RW-1:0]      w3_e_q;
  logic               blk_we_q;
  logic [7:0]         blk_addr_q;
  logic [DELAY_W-1:0] blk_a_q;
  logic [BW-1:0]      blk_b_q;
  always_ff @(posedge clk_i) begin
    if (st_q == C_SHARE) begin
      wnd_q <= rotl(tx_q, 3);
      xr_q  <= p1_xt;
    end else if (st_q == C_BLANK && !drain_q && k_q == 3'd6) begin
      wnd_q <= rotr(wnd_q, 1);
      xr_q  <= rotr(xr_q, 1);
    end
    // stage 1
    b1_v_q    <= !rst_i && st_q == C_BLANK && !drain_q;
    b1_use_q  <= buse;
    b1_last_q <= k_q == 3'd6;
    b1_tx_q   <= wnd_q[3];
    b1_e_q    <= cnt_q;
    // stage 2
    b2_v_q    <= !rst_i && b1_v_q;
    b2_use_q  <= b1_use_q;
    b2_last_q <= b1_last_q;
    b2_tx_q   <= b1_tx_q;
    b2_e_q    <= b1_e_q;
    b2_d_q    <= delay_rdata_i;
    // stage 3
    if (st_q == C_SHARE) bany_q <= 1'b0;
    if (b2_v_q) begin
      if (b2_use_q) begin
        if (!bany_q || b2_d_q < first_q) first_q <= b2_d_q;
        if (!bany_q || b2_d_q > last_q)  last_q  <= b2_d_q;
      end
      bany_q <= !b2_last_q && (bany_q || b2_use_q);
    end
    w3_q     <= !rst_i && b2_v_q && b2_last_q;
    w3_any_q <= bany_q || b2_use_q;
    w3_tx_q  <= b2_tx_q;
    w3_e_q   <= b2_e_q;
    // stage 4
    blk_we_q   <= !rst_i && w3_q;
    blk_addr_q <= {e_q, w3_e_q};
    blk_a_q    <= w3_any_q ? first_q : '0;
    blk_b_q    <= !w3_any_q ? '0
                : w3_tx_q ? BW'(first_q) + BW'(dead_q) : BW'(last_q) + BW'(xtk_q);
  end
  assign blk_we_o   = blk_we_q;
  assign blk_addr_o = blk_addr_q;
  assign blk_a_o    = blk_a_q;
  assign blk_b_o    = blk_b_q;
endmodule
