// ms_sched_uc: the fast-firing scheduler on the microcoded engine (docs/sched_engine.md):
// ms_scheduler's ports and contract, with its run-time work done by the main program of
// multisonar.tools.sched_program (ROM image and I/O map from the make gen step) on
// ms_sched_engine, and fixed units around it: the slot unit (ms_sched_slot), the divider
// (ms_sched_div), the work queue (ms_sched_workq), the close detector, the window slots (WIN)
// and the output strobes. The configuration check and load is ms_sched_cfg's; a loader turns
// its records into the program's data-memory words. The program's golden model, with this
// hardware modelled around it, is sched_program.system.EngineSystem.
//
// Timing contract (ticks of clk_i; tick_i counts by one every clock; ms_scheduler's, with these
// differences):
//   - The engine's lateness: a logical tick's work is done some clocks after the tick; a
//     dispatch P / 2 or more late, a trigger or a head written at or after its tick, or a full
//     work queue raise overrun_o (sticky). LEAD must give the program its clocks (32768 for the
//     product's loads; scripts/bench_sched_mainloop.py).
//   - Start: the engine leaves reset in the clock after the start tick S (running_o rises
//     there) and its INIT reads S from the data memory.
//   - Apply while running: the program finishes every logical tick before the apply's tick
//     (STOP_AT), halts; the load follows and the schedule starts afresh.
//   - The load port, the firmware's check and load (sched_program.system.load_image): hold_i
//     while running stops as an apply does (running_o falls once the program halted), without a
//     load. While running_o is low and no apply is pending or under way, ld_we_i writes one
//     word per clock: the data memory (< 1024), a blank offset (BLK + 64 s + e: a, held;
//     BLK + 64 s + 32 + e: b, written with the a before it) or the LD_* tables. start_i (enable_i
//     high) starts the loaded table: its tick is the start tick S, running_o rises a clock later.
// Storage, all block RAM with a registered read (six DP16KD): the microcode ROM (UCODE_WORDS
// x 36, two), the data memory (1024 x 32, two) and WINB (two): the window slots {t0, we, seq,
// epoch, init, sensor} (no start: a window is [t0 + we - len, t0 + we), len from the table of
// the sensors' window lengths) and, in its spare rows, the blank offsets of every (sensor,
// element), read on the bus at BLK.
module ms_sched_uc
  import ms_sched_io_pkg::*;
#(
  parameter int    NUM_CH     = 24,
  parameter int    NUM_VS     = 8,
  parameter int    DELAY_W    = 16,
  parameter int    LEAD       = 32768,
  parameter int    WSLOTS     = 16,
  parameter int    QDEPTH     = 32,
  parameter string UCODE_FILE = ""          // empty: the gen step's image (UCODE_HEX)
) (
  input  logic                  clk_i,
  input  logic                  rst_i,
  input  logic [31:0]           tick_i,
  input  logic                  enable_i,
  input  logic                  apply_i,
  // the load port (the firmware's load, firmware/app/sonar/sched_table.c): hold_i stops the
  // engine as an apply does, without a load; ld_we_i writes ld_data_i at ld_addr_i (the engine's
  // data memory, the blank offsets, the LD_* tables) while running_o and the hardware's own
  // check and load are idle; start_i then starts the loaded table at the next clock's tick
  input  logic                  hold_i,
  input  logic                  ld_we_i,
  input  logic [11:0]           ld_addr_i,
  input  logic [31:0]           ld_data_i,
  input  logic                  start_i,
  output logic                  vs_ren_o,
  output logic [6:0]            vs_raddr_o,
  input  logic [31:0]           vs_rdata_i,
  input  logic [15:0]           burst_half_period_i,
  input  logic [7:0]            glitch_min_i,
  input  logic [15:0]           miss_gate_i,
  output logic [7:0]            delay_raddr_o,
  input  logic [DELAY_W-1:0]    delay_rdata_i,
  input  logic [NUM_CH-1:0]     rise_i,
  output logic                  trig_valid_o,
  output logic [4:0]            trig_el_o,
  output logic [DELAY_W:0]      trig_delay_o,
  output logic [7:0]            trig_burst_o,
  output logic                  pulse_o,
  output logic [2:0]            pulse_vs_o,
  output logic [NUM_CH-1:0]     pulse_tx_o,
  output logic [7:0]            pulse_seq_o,
  output logic [31:0]           pulse_t0_o,
  output logic                  pulse_init_o,
  output logic                  evt_valid_o,
  output logic [63:0]           evt_data_o,
  output logic                  running_o,
  output logic [3:0]            cfg_error_o,
  output logic [3:0]            cfg_error_vs_o,
  output logic                  overrun_o
);
  localparam int AW  = 12;                         // the engine's bus
  localparam int EW  = $clog2(NUM_CH);
  localparam int WAW = $clog2(NUM_CH * WSLOTS);
  localparam int QW  = 32 + 2 * NUM_CH;
  localparam int BW  = 20;
  localparam int OW  = 4;
  if (NUM_CH != PROG_NUM_RX || WSLOTS != PROG_WSLOTS || NUM_VS != PROG_NUM_VS) begin : g_bad_shape
    $error("ms_sched_uc: the program is built for %0d elements, %0d slots, %0d sensors",
           PROG_NUM_RX, PROG_WSLOTS, PROG_NUM_VS);
  end

  // ------------------------------------------------------------------ control
  typedef enum logic [2:0] {C_OFF, C_CHECK, C_STOPPING, C_LOAD, C_FINISH, C_RUN} ctl_e;
  ctl_e        ctl_q, ctl_d;
  logic        started_q, started_d, en_q, en_prev_q, apply_pend_q, apply_pend_d;
  logic        cfg_chk, cfg_ld, cfg_ld_q, cfg_busy, cfg_done, stop_req_q, stop_req_d, eng_run_q,
               eng_run_d;
  logic [3:0]  cfg_err, cfg_err_vs, cfg_err_q, cfg_err_d, cfg_err_vs_q, cfg_err_vs_d;
  logic [31:0] stop_at_q, stop_at_d;
  logic        halted;      // the program wrote HALT (every tick before stop_at_q done)
  logic        fin_done;    // the loader's final words are written
  logic        start_now;   // C_FINISH -> C_RUN: the start tick is tick_i
  logic        hold_q, hold_d;  // C_STOPPING for hold_i: no load follows
  logic        port_open;   // the load port writes: C_OFF (no apply pending: the caller's part)
  always_comb begin
    ctl_d        = ctl_q;
    started_d    = started_q;
    apply_pend_d = apply_pend_q || apply_i || (en_q && !en_prev_q);
    stop_req_d   = stop_req_q;
    stop_at_d    = stop_at_q;
    hold_d       = hold_q;
    eng_run_d    = eng_run_q;
    cfg_err_d    = cfg_err_q;
    cfg_err_vs_d = cfg_err_vs_q;
    cfg_chk      = 1'b0;
    cfg_ld       = 1'b0;
    start_now    = 1'b0;
    if (!en_q && started_q) begin          // stop: windows dropped, armed triggers still fire
      ctl_d      = C_OFF;
      started_d  = 1'b0;
      eng_run_d  = 1'b0;
      stop_req_d = 1'b0;
      hold_d     = 1'b0;
    end else begin
      unique case (ctl_q)
        C_OFF, C_RUN: if (ctl_q == C_OFF && start_i && en_q) begin
          start_now    = 1'b1;          // a table loaded through the port
          apply_pend_d = 1'b0;
          started_d    = 1'b1;
          eng_run_d    = 1'b1;
          ctl_d        = C_RUN;
        end else if (ctl_q == C_RUN && hold_i) begin
          stop_req_d = 1'b1;
          stop_at_d  = tick_i;
          hold_d     = 1'b1;
          ctl_d      = C_STOPPING;
        end else if (apply_pend_q && !cfg_busy) begin
          apply_pend_d = 1'b0;
          cfg_chk      = 1'b1;
          ctl_d        = C_CHECK;
        end
        C_CHECK: if (cfg_done) begin       // a refused table changes nothing
          cfg_err_d    = cfg_err;
          cfg_err_vs_d = cfg_err_vs;
          if (cfg_err != 4'd0) begin
            ctl_d = started_q ? C_RUN : C_OFF;
          end else if (started_q) begin
            stop_req_d = 1'b1;
            stop_at_d  = tick_i;
            ctl_d      = C_STOPPING;
          end else begin
            cfg_ld = 1'b1;
            ctl_d  = C_LOAD;
          end
        end
        C_STOPPING: if (halted) begin     // every logical tick before stop_at is done
          stop_req_d = 1'b0;
          eng_run_d  = 1'b0;
          started_d  = 1'b0;
          hold_d     = 1'b0;
          cfg_ld     = !hold_q;
          ctl_d      = hold_q ? C_OFF : C_LOAD;
        end
        C_LOAD: if (cfg_done) ctl_d = en_q ? C_FINISH : C_OFF;
        C_FINISH: if (fin_done) begin     // the start tick S = tick_i (model start_tick)
          start_now = 1'b1;
          started_d = 1'b1;
          eng_run_d = 1'b1;
          ctl_d     = C_RUN;
        end
        default: ctl_d = C_OFF;
      endcase
    end
  end
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      ctl_q        <= C_OFF;
      started_q    <= 1'b0;
      en_q         <= 1'b0;
      en_prev_q    <= 1'b0;
      apply_pend_q <= 1'b0;
      stop_req_q   <= 1'b0;
      hold_q       <= 1'b0;
      eng_run_q    <= 1'b0;
      cfg_err_q    <= '0;
      cfg_err_vs_q <= '0;
    end else begin
      ctl_q        <= ctl_d;
      started_q    <= started_d;
      en_q         <= enable_i;
      en_prev_q    <= en_q;
      apply_pend_q <= apply_pend_d;
      stop_req_q   <= stop_req_d;
      hold_q       <= hold_d;
      eng_run_q    <= eng_run_d;
      cfg_err_q    <= cfg_err_d;
      cfg_err_vs_q <= cfg_err_vs_d;
    end
    stop_at_q <= stop_at_d;
    cfg_ld_q  <= !rst_i && cfg_ld;   // after the check's done clock (ms_sched_cfg still busy there)
  end
  assign running_o      = started_q;
  assign port_open      = ctl_q == C_OFF;
  assign cfg_error_o    = cfg_err_q;
  assign cfg_error_vs_o = cfg_err_vs_q;

  // edge latency L = 1 + max(glitch_min, 1): an edge's timestamp is its detection tick - L; a
  // window closes L - 1 ticks after its end
  logic [7:0] latm1;
  assign latm1 = glitch_min_i > 8'd1 ? glitch_min_i : 8'd1;

  // ------------------------------------------------------------------ configuration check, load
  logic              ld_we, ld_act, ld_track, word_we, blk_we, share_we, share;
  logic [2:0]        ld_vs, share_a, share_b;
  logic [NUM_CH-1:0] ld_tx, ld_rx, ld_xt, ld_use;
  logic [OW-1:0]     ld_order;
  logic [3:0]        ld_k, word;
  logic [7:0]        ld_reinit, ld_burst, blk_addr;
  logic [15:0]       ld_tv, ld_tn, ld_vmax;
  logic [23:0]       ld_rmax, ld_phase, ld_dbl, ld_lo, ld_hi;
  logic [DELAY_W-1:0] blk_a;
  logic [BW-1:0]     blk_b;
  ms_sched_cfg #(
    .NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .DELAY_W(DELAY_W), .LEAD(LEAD), .MAX_ORDER(8), .DW(19),
    .BW(BW), .OW(OW)
  ) u_cfg (
    .clk_i, .rst_i, .check_i(cfg_chk), .load_i(cfg_ld_q), .abort_i(!en_q && started_q),
    .busy_o(cfg_busy), .done_o(cfg_done), .err_o(cfg_err), .err_vs_o(cfg_err_vs), .vs_ren_o,
    .vs_raddr_o, .vs_rdata_i, .delay_raddr_o, .delay_rdata_i, .burst_half_period_i,
    .ld_we_o(ld_we), .ld_vs_o(ld_vs), .ld_tx_o(ld_tx), .ld_rx_o(ld_rx), .ld_xt_o(ld_xt),
    .ld_use_o(ld_use), .ld_act_o(ld_act), .ld_track_o(ld_track), .ld_order_o(ld_order),
    .ld_k_o(ld_k), .ld_reinit_o(ld_reinit), .ld_tv_o(ld_tv), .ld_tn_o(ld_tn),
    .ld_vmax_o(ld_vmax), .ld_rmax_o(ld_rmax), .ld_phase_o(ld_phase), .ld_dbl_o(ld_dbl),
    .ld_lo_o(ld_lo), .ld_hi_o(ld_hi), .ld_burst_o(ld_burst), .word_we_o(word_we),
    .word_o(word), .blk_we_o(blk_we), .blk_addr_o(blk_addr), .blk_a_o(blk_a), .blk_b_o(blk_b),
    .share_we_o(share_we), .share_a_o(share_a), .share_b_o(share_b), .share_o(share)
  );

  // The loader: a record (ld_we) is latched and its words go to the data memory one per clock
  // (the load's next record comes NUM_CH + 2 clocks later at the earliest); the shares
  // collect in flops; C_FINISH writes each sensor's share word and the program's constants.
  typedef struct packed {
    logic [2:0]        vs;
    logic [NUM_CH-1:0] tx, rx, blk;
    logic              track;
    logic [OW-1:0]     order;
    logic [3:0]        k;
    logic [7:0]        reinit;
    logic [15:0]       tv, tn, vmax;
    logic [23:0]       rmax, phase, dbl, lo, hi;
    logic [5:0]        nrx;
  } rec_t;
  rec_t              rec_q;
  logic [23:0]       wlen_q [2 * NUM_VS];   // window length of {sensor, init}: T_V + T_N, R - D
  logic [23:0]       rec_qoff;              // R - D: an init ping's window length (S_QOFF)
  assign rec_qoff = rec_q.rmax - rec_q.dbl;
  logic [4:0]        rec_i_q;        // the record's next word (0 .. 16), 31: none
  logic [3:0]        fin_i_q;        // C_FINISH: the next final word (0 .. 11)
  logic [NUM_VS-1:0][NUM_VS-1:0] share_q;
  logic [NUM_VS-1:0] act_q;
  logic [NUM_VS-1:0][7:0]        burst_q;
  logic [NUM_VS-1:0][NUM_CH-1:0] txm_q;
  logic [NUM_CH-1:0] rx_any_q;
  logic [15:0]       gate_q;
  function automatic logic [5:0] popcount(input logic [NUM_CH-1:0] m);
    popcount = '0;
    for (int i = 0; i < NUM_CH; i++) popcount = popcount + 6'(m[i]);
  endfunction
  // the load port's writes (port_open: C_OFF; the firmware writes nothing else meanwhile)
  logic port_we, port_dm, port_blk_a, port_blk_b;
  logic [DELAY_W-1:0] port_a_q;     // a blank offset a, committed with its b
  assign port_we    = port_open && ld_we_i;
  assign port_dm    = port_we && ld_addr_i < 12'd1024;
  assign port_blk_a = port_we && ld_addr_i >= 12'(BLK) && !ld_addr_i[5];
  assign port_blk_b = port_we && ld_addr_i >= 12'(BLK) && ld_addr_i[5];
  always_ff @(posedge clk_i) if (port_blk_a) port_a_q <= ld_data_i[DELAY_W-1:0];
  // the per-sensor tables' one write each, from the loader or the port (one write port keeps
  // wlen_q in LUT-RAM and the others' entries free of per-entry multiplexers)
  logic              wl_we, bu_we, tm_we;
  logic [3:0]        wl_a;
  logic [23:0]       wl_d;
  logic [2:0]        tab_a;
  logic [7:0]        bu_d;
  logic [NUM_CH-1:0] tm_d;
  always_comb begin
    wl_we = rec_i_q == 5'd0 || rec_i_q == 5'd1;   // while the record's first two words go out
    wl_a  = {rec_q.vs, rec_i_q[0]};
    wl_d  = rec_i_q[0] ? rec_qoff : 24'(rec_q.tv) + 24'(rec_q.tn);
    bu_we = ld_we;
    tm_we = ld_we;
    tab_a = ld_vs;
    bu_d  = ld_burst;
    tm_d  = ld_tx;
    if (port_we && ld_addr_i[11:4] == 8'(LD_WLEN >> 4)) begin
      wl_we = 1'b1;
      wl_a  = ld_addr_i[3:0];
      wl_d  = ld_data_i[23:0];
    end
    if (port_we && ld_addr_i[11:3] == 9'(LD_BURST >> 3)) begin
      bu_we = 1'b1;
      tab_a = ld_addr_i[2:0];
      bu_d  = ld_data_i[7:0];
    end
    if (port_we && ld_addr_i[11:3] == 9'(LD_TXM >> 3)) begin
      tm_we = 1'b1;
      tab_a = ld_addr_i[2:0];
      tm_d  = ld_data_i[NUM_CH-1:0];
    end
  end
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      rec_i_q <= '1;
    end else if (ld_we) begin
      rec_i_q <= '0;
    end else if (rec_i_q != '1) begin
      rec_i_q <= rec_i_q == 5'd16 ? '1 : rec_i_q + 5'd1;
    end
    if (ld_we) begin
      rec_q <= '{vs: ld_vs, tx: ld_tx, rx: ld_rx, blk: ld_tx | ld_xt, track: ld_track,
                 order: ld_order, k: ld_k, reinit: ld_reinit, tv: ld_tv, tn: ld_tn,
                 vmax: ld_vmax, rmax: ld_rmax, phase: ld_phase, dbl: ld_dbl, lo: ld_lo,
                 hi: ld_hi, nrx: popcount(ld_rx)};
      act_q[ld_vs]   <= ld_act;
      rx_any_q       <= (ld_vs == '0 ? '0 : rx_any_q) | (ld_act ? ld_rx : '0);
    end
    if (wl_we) wlen_q[wl_a] <= wl_d;
    if (bu_we) burst_q[tab_a] <= bu_d;
    if (tm_we) txm_q[tab_a] <= tm_d;
    if (port_we && ld_addr_i == 12'(LD_RXANY)) rx_any_q <= ld_data_i[NUM_CH-1:0];
    if (share_we) begin
      share_q[share_a][share_b] <= share && share_a != share_b;
      share_q[share_b][share_a] <= share && share_a != share_b;
    end
    if (cfg_ld_q) gate_q <= miss_gate_i;
    fin_i_q <= (ctl_q == C_FINISH) ? fin_i_q + 4'(!fin_done) : '0;
  end
  assign fin_done = fin_i_q == 4'd12;

  // the loader's data-memory write (the engine is in reset while it writes)
  logic        ld_dm_we;
  logic [9:0]  ld_dm_a;
  logic [31:0] ld_dm_d;
  always_comb begin
    ld_dm_we = 1'b0;
    ld_dm_a  = '0;
    ld_dm_d  = '0;
    if (rec_i_q != '1) begin
      ld_dm_we = 1'b1;
      ld_dm_a  = 10'(SENS + SENS_STRIDE * int'(rec_q.vs));
      unique case (rec_i_q)
        5'd0:  begin ld_dm_a += 10'(S_TX);     ld_dm_d = 32'(rec_q.tx);     end
        5'd1:  begin ld_dm_a += 10'(S_RX);     ld_dm_d = 32'(rec_q.rx);     end
        5'd2:  begin ld_dm_a += 10'(S_BLK);    ld_dm_d = 32'(rec_q.blk);    end
        5'd3:  begin ld_dm_a += 10'(S_ORDER);  ld_dm_d = 32'(rec_q.order);  end
        5'd4:  begin ld_dm_a += 10'(S_TV);     ld_dm_d = 32'(rec_q.tv);     end
        5'd5:  begin ld_dm_a += 10'(S_TN);     ld_dm_d = 32'(rec_q.tn);     end
        5'd6:  begin ld_dm_a += 10'(S_D);      ld_dm_d = 32'(rec_q.dbl);    end
        5'd7:  begin ld_dm_a += 10'(S_RMAX);   ld_dm_d = 32'(rec_q.rmax);   end
        5'd8:  begin ld_dm_a += 10'(S_LO);     ld_dm_d = 32'(rec_q.lo);     end
        5'd9:  begin ld_dm_a += 10'(S_HI);     ld_dm_d = 32'(rec_q.hi);     end
        5'd10: begin ld_dm_a += 10'(S_VMAX);   ld_dm_d = 32'(rec_q.vmax);   end
        5'd11: begin ld_dm_a += 10'(S_QOFF);   ld_dm_d = 32'(rec_qoff);    end
        5'd12: begin ld_dm_a += 10'(S_PHASE);  ld_dm_d = 32'(rec_q.phase);  end
        5'd13: begin ld_dm_a += 10'(S_NRX);    ld_dm_d = 32'(rec_q.nrx);    end
        5'd14: begin ld_dm_a += 10'(S_K);      ld_dm_d = 32'(rec_q.k);      end
        5'd15: begin ld_dm_a += 10'(S_MODE);   ld_dm_d = rec_q.track ? 32'd1 : 32'd2; end
        default: begin ld_dm_a += 10'(S_REINIT); ld_dm_d = 32'(rec_q.reinit); end
      endcase
    end else if (ctl_q == C_FINISH && !fin_done) begin
      ld_dm_we = 1'b1;
      if (fin_i_q < 4'(NUM_VS)) begin
        ld_dm_a = 10'(SENS + SENS_STRIDE * int'(fin_i_q) + S_SHARE);
        ld_dm_d = 32'(share_q[fin_i_q[2:0]]);
      end else begin
        unique case (fin_i_q)
          4'd8:    begin ld_dm_a = 10'(MAIN + M_P);    ld_dm_d = 32'(LEAD); end
          4'd9:    begin ld_dm_a = 10'(MAIN + M_L);    ld_dm_d = 32'(latm1) + 32'd1; end
          4'd10:   begin ld_dm_a = 10'(MAIN + M_GATE); ld_dm_d = 32'(gate_q); end
          default: begin ld_dm_a = 10'(MAIN + M_ACT);  ld_dm_d = 32'(act_q); end
        endcase
      end
    end else if (start_now) begin
      ld_dm_we = 1'b1;
      ld_dm_a  = 10'(MAIN + M_START);
      ld_dm_d  = tick_i;
    end else if (port_dm) begin
      ld_dm_we = 1'b1;
      ld_dm_a  = ld_addr_i[9:0];
      ld_dm_d  = ld_data_i;
    end
  end

  // ------------------------------------------------------------------ engine and bus
  logic          eng_rst, bus_re, bus_we;
  logic [AW-1:0] bus_a;
  logic [31:0]   bus_wd, bus_rd;
  logic [$clog2(UCODE_WORDS)-1:0] eng_pc;
  assign eng_rst = rst_i || !eng_run_q;
  localparam string UCODE_IMAGE = UCODE_FILE == "" ? UCODE_HEX : UCODE_FILE;
  ms_sched_engine #(.UCODE_WORDS(UCODE_WORDS), .UCODE_FILE(UCODE_IMAGE), .AW(AW)) u_eng (
    .clk_i, .rst_i(eng_rst), .bus_re_o(bus_re), .bus_we_o(bus_we), .bus_addr_o(bus_a),
    .bus_wdata_o(bus_wd), .bus_rdata_i(bus_rd), .pc_o(eng_pc)
  );
  logic io_we;
  assign io_we = bus_we && !eng_rst;
  function automatic logic io(input logic [AW-1:0] a, input int reg_addr);
    io = int'(a) == reg_addr;
  endfunction

  // data memory: the engine's port, or the loader's while the engine is in reset
  logic [31:0] dm_q [1024];
  logic [31:0] dm_rd_q;
  always_ff @(posedge clk_i) begin
    if (eng_rst ? ld_dm_we : (bus_we && bus_a < AW'(1024)))
      dm_q[eng_rst ? ld_dm_a : bus_a[9:0]] <= eng_rst ? ld_dm_d : bus_wd;
    dm_rd_q <= dm_q[bus_a[9:0]];
  end

  // ---- I/O registers the program writes
  logic [31:0]       su_ta_q, su_tb_q, su_twa_q, su_twb_q, w_t0_q, trig_t_q, hd_t_q, evt_lo_q;
  logic [23:0]       w_we_q, div_x_q;
  logic [18:0]       w_meta_q;      // seq [7:0], init 8, epoch 9, sensor [18:16]
  logic [WSLOTS-1:0] su_valid_q;
  logic [WAW-1:0]    win_ra_q;
  always_ff @(posedge clk_i) begin
    if (io_we) begin
      if (io(bus_a, SU_TA))    su_ta_q    <= bus_wd;
      if (io(bus_a, SU_TB))    su_tb_q    <= bus_wd;
      if (io(bus_a, SU_TWA))   su_twa_q   <= bus_wd;
      if (io(bus_a, SU_TWB))   su_twb_q   <= bus_wd;
      if (io(bus_a, SU_VALID)) su_valid_q <= bus_wd[WSLOTS-1:0];
      if (io(bus_a, W_T0))     w_t0_q     <= bus_wd;
      if (io(bus_a, W_WE))     w_we_q     <= bus_wd[23:0];
      if (io(bus_a, W_META))   w_meta_q   <= bus_wd[18:0];
      if (io(bus_a, TRIG_T))   trig_t_q   <= bus_wd;
      if (io(bus_a, HD_T))     hd_t_q     <= bus_wd;
      if (io(bus_a, EVT_LO))   evt_lo_q   <= bus_wd;
      if (io(bus_a, DIV_X))    div_x_q    <= bus_wd[23:0];
      if (io(bus_a, WIN_RA))   win_ra_q   <= WAW'(bus_wd);
    end
  end
  assign halted = io_we && io(bus_a, HALT);

  // ---- slot unit, divider
  logic              su_busy, su_re;
  logic [WAW-1:0]    su_ra;
  logic [31:0]       su_x, su_minc;
  logic [7:0]        su_flags;
  logic              div_busy;
  logic [23:0]       div_q;
  typedef struct packed {
    logic [31:0] t0;
    logic [23:0] we;
    logic [7:0]  seq;
    logic        epoch, init;
    logic [2:0]  sensor;
  } win_t;
  win_t           win_rd_q;
  ms_sched_slot #(.NUM_CH(NUM_CH), .WSLOTS(WSLOTS)) u_slot (
    .clk_i, .rst_i(eng_rst), .go_i(io_we && io(bus_a, SU_GO)), .mode_i(bus_wd[11:10]),
    .el_i(EW'(bus_wd[7:0])), .bon_i(bus_wd[8]), .won_i(bus_wd[9]), .valid_i(su_valid_q),
    .ta_i(su_ta_q), .tb_i(su_tb_q), .twa_i(su_twa_q), .twb_i(su_twb_q),
    .latm1_i(latm1), .win_ra_o(su_ra), .win_re_o(su_re), .win_t0_i(win_rd_q.t0),
    .win_len_i(wlen_q[{win_rd_q.sensor, win_rd_q.init}]), .win_we_i(win_rd_q.we),
    .win_sensor_i(win_rd_q.sensor),
    .busy_o(su_busy), .x_o(su_x), .flags_o(su_flags), .minc_o(su_minc)
  );
  ms_sched_div u_div (
    .clk_i, .rst_i(eng_rst), .start_i(io_we && io(bus_a, DIV_N)), .x_i(div_x_q),
    .n_i(bus_wd[3:0]), .busy_o(div_busy), .q_o(div_q)
  );

  // ---- WINB (512 x 72: one write and one read port, two DP16KD of 512 x 36). Rows below
  // BLK_ROW are WIN, the window slots the program writes (W_ADDR commits W_*), read by the
  // slot unit's scan or at the program's WIN_RA; the rows above hold the blank offsets {a, b}
  // of every (sensor s, element e), two per row (row BLK_ROW + {s, e / 2}, half e % 2),
  // written by the loader while the engine is in reset, read on the bus (a at BLK + 64 s + e,
  // b at BLK + 64 s + 32 + e). The read port serves the scan first, then a bus read of BLK,
  // then WIN_RA: the program reads BLK only while the slot unit is idle, and a WIN_* read in
  // the clock after a BLK read sees the blank row (EngineSystem models both).
  localparam int XW      = DELAY_W + BW;               // a blank interval {a, b}: half a row
  localparam int BLK_ROW = 2 ** WAW - NUM_VS * 16;
  if ($bits(win_t) > 2 * XW || NUM_CH * WSLOTS > BLK_ROW) begin : g_bad_winb
    $error("ms_sched_uc: WINB holds %0d-bit slots and %0d slots below the blank rows",
           2 * XW, BLK_ROW);
  end
  logic [2*XW-1:0] winb_q [2 ** WAW];
  logic [2*XW-1:0] winb_rd_q, winb_wd;
  logic [WAW-1:0]  winb_wa, winb_ra;
  logic [1:0]      winb_we;                            // per half row
  logic            blk_re, blk_odd_q;
  win_t            win_wd;
  function automatic logic [WAW-1:0] blk_row(input logic [2:0] s, input logic [3:0] e_half);
    blk_row = WAW'(BLK_ROW) + WAW'({s, e_half});              // element e: e_half = e / 2
  endfunction
  assign win_wd = '{t0: w_t0_q, we: w_we_q, seq: w_meta_q[7:0], init: w_meta_q[8],
                    epoch: w_meta_q[9], sensor: w_meta_q[18:16]};
  assign blk_re = bus_re && !eng_rst && bus_a >= AW'(BLK);
  always_comb begin
    winb_we = '0;
    winb_wa = WAW'(bus_wd);
    winb_wd = (2 * XW)'(win_wd);
    if (eng_rst && port_blk_b) begin       // BLK + 64 s + 32 + e: {a, b} of (s, e)
      winb_wa = blk_row(ld_addr_i[8:6], ld_addr_i[4:1]);
      winb_wd = {2{port_a_q, ld_data_i[BW-1:0]}};
      winb_we = {ld_addr_i[0], !ld_addr_i[0]};
    end else if (eng_rst) begin
      winb_wa = blk_row(blk_addr[7:5], blk_addr[4:1]);
      winb_wd = {2{blk_a, blk_b}};
      winb_we = {blk_we && blk_addr[0], blk_we && !blk_addr[0]};
    end else if (io_we && io(bus_a, W_ADDR)) begin
      winb_we = 2'b11;
    end
    winb_ra = su_re ? su_ra : blk_re ? blk_row(bus_a[8:6], bus_a[4:1]) : win_ra_q;
  end
  always_ff @(posedge clk_i) begin
    if (winb_we[0]) winb_q[winb_wa][XW-1:0]    <= winb_wd[XW-1:0];
    if (winb_we[1]) winb_q[winb_wa][2*XW-1:XW] <= winb_wd[2*XW-1:XW];
    winb_rd_q <= winb_q[winb_ra];
    blk_odd_q <= bus_a[0];
  end
  assign win_rd_q = win_t'(winb_rd_q[$bits(win_t)-1:0]);
  logic [XW-1:0] blk_rd;
  assign blk_rd = blk_odd_q ? winb_rd_q[2*XW-1:XW] : winb_rd_q[XW-1:0];

  // ---- the work queue: {tick, edges, closes} per tick with work, visible two ticks later
  logic [NUM_CH-1:0]  closes, edges;
  logic [31:0]        tick_prev_q;
  logic               q_empty, q_ovf, q_pop;
  logic [QW-1:0]      q_head;
  always_ff @(posedge clk_i) tick_prev_q <= tick_i;   // rise_i / closes of this clock: tick_i - 1
  assign edges = rise_i & rx_any_q;
  // the heads the program sets (HD_T, then HD_EL commits: element, bit 16 no head)
  ms_sched_closes #(.NUM_CH(NUM_CH)) u_closes (
    .clk_i, .rst_i(eng_rst), .tick_i, .we_i(io_we && io(bus_a, HD_EL)), .el_i(EW'(bus_wd[7:0])),
    .vld_i(!bus_wd[16]), .close_i(hd_t_q), .closes_o(closes)
  );
  assign q_pop = io_we && io(bus_a, Q_POP);
  ms_sched_workq #(.WIDTH(QW), .DEPTH(QDEPTH)) u_workq (
    .clk_i, .rst_i(eng_rst), .push_i(!eng_rst && (|edges || |closes)),
    .data_i({tick_prev_q, edges, closes}), .pop_i(q_pop), .head_o(q_head), .empty_o(q_empty),
    .overflow_o(q_ovf)
  );
  logic late_head_q, late_trig_q, late_disp_q;
  always_ff @(posedge clk_i)
    late_head_q <= io_we && io(bus_a, HD_EL) && !bus_wd[16] && $signed(hd_t_q - tick_i) <= 0;

  // ---- reads: every source answers one clock after the address, as the block RAMs do. The
  // I/O space (0x400 .. 0x43F) is decoded on its low six bits; ONEHOT (32 aligned words of the
  // data memory's range) reads 1 << k from a decoder.
  logic [31:0] io_rd_q;
  logic [1:0]  rsel_q;      // 0 data memory, 1 blank offsets a, 2 b, 3 I/O or ONEHOT
  logic        onehot;
  assign onehot = bus_a[AW-1:5] == 7'(ONEHOT >> 5);
  always_ff @(posedge clk_i) begin
    rsel_q <= bus_a >= AW'(BLK) ? (bus_a[5] ? 2'd2 : 2'd1)
            : (bus_a < AW'(1024) && !onehot) ? 2'd0 : 2'd3;
    if (onehot) begin
      io_rd_q <= 32'd1 << bus_a[4:0];
    end else begin
      unique case (6'(int'(bus_a) - 'h400))
        6'(SU_X - 'h400):     io_rd_q <= su_x;
        6'(SU_FLAGS - 'h400): io_rd_q <= 32'(su_flags);
        6'(SU_MINC - 'h400):  io_rd_q <= su_minc;
        6'(DIV_Q - 'h400):    io_rd_q <= 32'(div_q);
        6'(DIV_STAT - 'h400): io_rd_q <= div_busy ? 32'h80 : 32'h0;
        6'(TICK - 'h400):     io_rd_q <= tick_i;
        6'(Q_STAT - 'h400):   io_rd_q <= 32'(!q_empty);
        6'(Q_T - 'h400):      io_rd_q <= q_head[QW-1 -: 32];
        6'(Q_E - 'h400):      io_rd_q <= 32'(q_head[2*NUM_CH-1:NUM_CH]);
        6'(Q_C - 'h400):      io_rd_q <= 32'(q_head[NUM_CH-1:0]);
        6'(WIN_T0 - 'h400):   io_rd_q <= win_rd_q.t0;
        6'(WIN_WE - 'h400):   io_rd_q <= 32'(win_rd_q.we);
        6'(WIN_META - 'h400): io_rd_q <= {13'd0, win_rd_q.sensor, 6'd0, win_rd_q.epoch,
                                          win_rd_q.init, win_rd_q.seq};
        6'(STOP_REQ - 'h400): io_rd_q <= 32'(stop_req_q);
        6'(STOP_AT - 'h400):  io_rd_q <= stop_at_q;
        default:              io_rd_q <= '0;
      endcase
    end
  end
  always_comb begin
    unique case (rsel_q)
      2'd0:    bus_rd = dm_rd_q;
      2'd1:    bus_rd = 32'(blk_rd[XW-1:BW]);
      2'd2:    bus_rd = 32'(blk_rd[BW-1:0]);
      default: bus_rd = io_rd_q;
    endcase
  end

  // ------------------------------------------------------------------ outputs
  logic [2:0] pulse_vs_q;   // the sensor of the last pulse record (its triggers follow it)
  logic [31:0] trig_rel;
  assign trig_rel = trig_t_q - tick_i - 32'd1;   // the delay from the next clock's tick
  always_ff @(posedge clk_i) begin
    trig_valid_o <= 1'b0;
    evt_valid_o  <= 1'b0;
    pulse_o      <= 1'b0;
    late_trig_q  <= 1'b0;
    late_disp_q  <= 1'b0;
    if (io_we && io(bus_a, TRIG_EL)) begin
      trig_valid_o <= 1'b1;
      trig_el_o    <= bus_wd[4:0];
      trig_delay_o <= (DELAY_W + 1)'(trig_rel);
      trig_burst_o <= burst_q[pulse_vs_q];
      late_trig_q  <= trig_rel[31:DELAY_W+1] != '0;   // negative or too far: the engine is late
    end
    if (io_we && io(bus_a, EVT_HI)) begin
      evt_valid_o <= 1'b1;
      evt_data_o  <= {bus_wd, evt_lo_q};
      if (bus_wd[30] && !bus_wd[29]) begin          // a pulse record: the pulse goes
        pulse_o      <= 1'b1;
        pulse_vs_o   <= bus_wd[7:5];
        pulse_vs_q   <= bus_wd[7:5];
        pulse_tx_o   <= txm_q[bus_wd[7:5]];
        pulse_seq_o  <= bus_wd[20:13];
        pulse_t0_o   <= evt_lo_q;
        pulse_init_o <= bus_wd[11];
      end
    end
    if (io_we && io(bus_a, LAG_CUR)) late_disp_q <= $signed(tick_i - bus_wd) >= LEAD / 2 + 2;
  end
  // lag_max_q (the benches read it through the hierarchy): the largest tick - logical tick at
  // the end of a logical tick's work since the start
  logic [31:0] lag_max_q;
  logic        ovr_q;
  always_ff @(posedge clk_i) begin
    if (rst_i || start_now) begin
      lag_max_q <= '0;
      ovr_q     <= 1'b0;
    end else begin
      if (io_we && io(bus_a, T_DONE) && tick_i - bus_wd > lag_max_q) lag_max_q <= tick_i - bus_wd;
      if (q_ovf || late_head_q || late_trig_q || late_disp_q) ovr_q <= 1'b1;
    end
  end
  assign overrun_o = ovr_q;

  logic unused_ok;
  assign unused_ok = ^{ld_use, word_we, word, eng_pc, su_busy, w_meta_q[15:10],
                       winb_rd_q[2*XW-1:$bits(win_t)]};
endmodule
