// ms_sched_uc: the fast-firing scheduler on the microcoded engine (docs/sched_engine.md):
// the main program of multisonar.tools.sched_program (ROM image and I/O map from the make gen
// step) on ms_sched_engine, and fixed units around it: the slot unit (ms_sched_slot), the
// divider (ms_sched_div), the work queue (ms_sched_workq), the close detector, the window slots
// (WIN) and the output strobes. The table's check and load are the firmware's
// (firmware/app/sonar/sched_table.c): it writes the program's data-memory words through the
// load port. The program's golden model, with this hardware modelled around it, is
// sched_program.system.EngineSystem.
//
// Timing contract (ticks of clk_i; tick_i counts by one every clock):
//   - The engine's lateness: a logical tick's work is done some clocks after the tick; a
//     dispatch P / 2 or more late, a trigger or a head written at or after its tick, or a full
//     work queue raise overrun_o (sticky). LEAD must give the program its clocks (32768 for the
//     product's loads; scripts/bench_sched_mainloop.py). The checks take their differences
//     modulo 2^26 (a head: a window closes less than 2^24 + LEAD ticks after the tick), 2^20 (a
//     trigger: within 2^19 of the tick unless the dispatch is already that late) and 2^24 (a
//     dispatch's lag).
//   - The load port (sched_program.system.load_image's words): while running_o is low, ld_we_i
//     writes one word per clock: the data memory (< 1024), a blank offset (BLK + 64 s + e: a,
//     held; BLK + 64 s + 32 + e: b, written with the a before it) or the LD_* tables.
//   - Start: start_i with enable_i high; its tick is the start tick S. The engine leaves reset
//     in the next clock (running_o rises there) and its INIT reads S from the data memory.
//   - Hold: hold_i while running makes the program finish every logical tick before hold_i's
//     tick (STOP_AT) and halt; running_o falls in the clock after the halt, the loaded table
//     kept (a start_i runs it afresh).
//   - enable_i low (registered: a clock later) stops at once: windows dropped, armed triggers
//     still fire.
// Storage, block RAM with a registered read (six DP16KD): the microcode ROM (UCODE_BRAM x 36,
// two; its UCODE_WORDS - UCODE_BRAM further words are a table in logic), the data memory (1024
// x 32, two) and WINB (two): the window slots {t0, we, seq, epoch, init, sensor} (no start: a
// window is [t0 + we - len, t0 + we), len from the table of the sensors' window lengths) and,
// in its spare rows, the blank offsets of every (sensor, element), read on the bus at BLK.
module ms_sched_uc
  import ms_sched_io_pkg::*;
#(
  parameter int    NUM_CH     = 24,
  parameter int    NUM_VS     = 8,
  parameter int    DELAY_W    = 16,
  parameter int    LEAD       = 32768,
  parameter int    WSLOTS     = 16,
  parameter int    QDEPTH     = 32,
  parameter string UCODE_FILE = "",         // empty: the gen step's image (UCODE_HEX)
  parameter string UCODE_FILE_HI = ""       // its words from UCODE_BRAM on (empty: UCODE_HEX_HI)
) (
  input  logic                  clk_i,
  input  logic                  rst_i,
  input  logic [31:0]           tick_i,
  input  logic                  enable_i,
  // the load port (the firmware's load, firmware/app/sonar/sched_table.c)
  input  logic                  hold_i,
  input  logic                  ld_we_i,
  input  logic [11:0]           ld_addr_i,
  input  logic [31:0]           ld_data_i,
  input  logic                  start_i,
  input  logic [7:0]            glitch_min_i,
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
  output logic                  overrun_o
);
  localparam int AW  = 12;                         // the engine's bus
  localparam int EW  = $clog2(NUM_CH);
  localparam int WAW = $clog2(NUM_CH * WSLOTS);
  localparam int QW  = 32 + 2 * NUM_CH;
  localparam int BW  = 20;
  if (NUM_CH != PROG_NUM_RX || WSLOTS != PROG_WSLOTS || NUM_VS != PROG_NUM_VS) begin : g_bad_shape
    $error("ms_sched_uc: the program is built for %0d elements, %0d slots, %0d sensors",
           PROG_NUM_RX, PROG_WSLOTS, PROG_NUM_VS);
  end

  // ------------------------------------------------------------------ control
  typedef enum logic [1:0] {C_OFF, C_RUN, C_STOPPING} ctl_e;
  ctl_e        ctl_q, ctl_d;
  logic        en_q;
  logic [31:0] stop_at_q, stop_at_d;
  logic        halted;      // the program wrote HALT (every tick before stop_at_q done)
  logic        start_now;   // C_OFF -> C_RUN: the start tick is tick_i
  always_comb begin
    ctl_d     = ctl_q;
    stop_at_d = stop_at_q;
    start_now = 1'b0;
    if (!en_q && ctl_q != C_OFF) begin     // stop: windows dropped, armed triggers still fire
      ctl_d = C_OFF;
    end else begin
      unique case (ctl_q)
        C_OFF: if (start_i && enable_i) begin
          start_now = 1'b1;
          ctl_d     = C_RUN;
        end
        C_RUN: if (hold_i) begin          // STOP_REQ reads 1 from here
          stop_at_d = tick_i;
          ctl_d     = C_STOPPING;
        end
        C_STOPPING: if (halted) ctl_d = C_OFF;  // every logical tick before stop_at is done
        default: ctl_d = C_OFF;
      endcase
    end
  end
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      ctl_q <= C_OFF;
      en_q  <= 1'b0;
    end else begin
      ctl_q <= ctl_d;
      en_q  <= enable_i;
    end
    stop_at_q <= stop_at_d;
  end
  assign running_o = ctl_q != C_OFF;

  // edge latency L = 1 + max(glitch_min, 1): an edge's timestamp is its detection tick - L; a
  // window closes L - 1 ticks after its end
  logic [7:0] latm1;
  assign latm1 = glitch_min_i > 8'd1 ? glitch_min_i : 8'd1;

  // ------------------------------------------------------------------ the load port
  // Writes while the engine is off (ctl_q == C_OFF: the engine is in reset). The LD_* tables:
  // the window length of each {sensor, init} (slot unit), each sensor's burst cycles and tx
  // elements (output strobes) and the rx elements of all (work queue).
  logic              port_we, port_dm, port_blk_a, port_blk_b;
  logic [DELAY_W-1:0] port_a_q;     // a blank offset a, committed with its b
  logic [23:0]       wlen_q [2 * NUM_VS];   // window length of {sensor, init}: T_V + T_N, R - D
  logic [7:0]        burst_q [NUM_VS];    // memories with one write port: LUT-RAM
  logic [NUM_CH-1:0] txm_q [NUM_VS];
  logic [NUM_CH-1:0] rx_any_q;
  assign port_we    = ctl_q == C_OFF && ld_we_i;
  assign port_dm    = port_we && ld_addr_i < 12'd1024;
  assign port_blk_a = port_we && ld_addr_i >= 12'(BLK) && !ld_addr_i[5];
  assign port_blk_b = port_we && ld_addr_i >= 12'(BLK) && ld_addr_i[5];
  always_ff @(posedge clk_i) begin
    if (port_blk_a) port_a_q <= ld_data_i[DELAY_W-1:0];
    if (port_we && ld_addr_i[11:4] == 8'(LD_WLEN >> 4)) wlen_q[ld_addr_i[3:0]] <= ld_data_i[23:0];
    if (port_we && ld_addr_i[11:3] == 9'(LD_BURST >> 3)) burst_q[ld_addr_i[2:0]] <= ld_data_i[7:0];
    if (port_we && ld_addr_i[11:3] == 9'(LD_TXM >> 3))
      txm_q[ld_addr_i[2:0]] <= ld_data_i[NUM_CH-1:0];
    if (port_we && ld_addr_i == 12'(LD_RXANY)) rx_any_q <= ld_data_i[NUM_CH-1:0];
  end

  // the data memory's write while the engine is in reset: the port, or the start tick
  logic        ld_dm_we;
  logic [9:0]  ld_dm_a;
  logic [31:0] ld_dm_d;
  always_comb begin
    ld_dm_we = port_dm;
    ld_dm_a  = ld_addr_i[9:0];
    ld_dm_d  = ld_data_i;
    if (start_now) begin
      ld_dm_we = 1'b1;
      ld_dm_a  = 10'(MAIN + M_START);
      ld_dm_d  = tick_i;
    end
  end

  // ------------------------------------------------------------------ engine and bus
  logic          eng_rst, bus_re, bus_we, bus_abs;
  logic [AW-1:0] bus_a, bus_ia;
  logic [31:0]   bus_wd, bus_rd;
  logic [$clog2(UCODE_WORDS)-1:0] eng_pc;
  assign eng_rst = rst_i || ctl_q == C_OFF;
  localparam string UCODE_IMAGE = UCODE_FILE == "" ? UCODE_HEX : UCODE_FILE;
  localparam string UCODE_IMAGE_HI = UCODE_FILE_HI == "" ? UCODE_HEX_HI : UCODE_FILE_HI;
  ms_sched_engine #(.UCODE_WORDS(UCODE_WORDS), .UCODE_FILE(UCODE_IMAGE), .UCODE_BRAM(UCODE_BRAM),
                    .UCODE_FILE_HI(UCODE_IMAGE_HI), .AW(AW)) u_eng (
    .clk_i, .rst_i(eng_rst), .bus_re_o(bus_re), .bus_we_o(bus_we), .bus_addr_o(bus_a),
    .bus_abs_o(bus_abs), .bus_imm_o(bus_ia), .bus_wdata_o(bus_wd), .bus_rdata_i(bus_rd),
    .pc_o(eng_pc)
  );
  // the program writes I/O registers only through r0 (sched_program refuses an indexed store
  // there, the model too): their decode starts at the engine's immediate register, not at the
  // address adder; an indexed store writes the data memory
  logic io_we;
  assign io_we = bus_we && bus_abs && !eng_rst;
  function automatic logic io(input logic [AW-1:0] a, input int reg_addr);
    io = int'(a) == reg_addr;
  endfunction

  // data memory: the engine's port, or the load port's while the engine is in reset
  logic [31:0] dm_q [1024];
  logic [31:0] dm_rd_q;
  always_ff @(posedge clk_i) begin
    if (eng_rst ? ld_dm_we : (bus_we && (!bus_abs || bus_ia < AW'(1024))))
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
      if (io(bus_ia, SU_TA))    su_ta_q    <= bus_wd;
      if (io(bus_ia, SU_TB))    su_tb_q    <= bus_wd;
      if (io(bus_ia, SU_TWA))   su_twa_q   <= bus_wd;
      if (io(bus_ia, SU_TWB))   su_twb_q   <= bus_wd;
      if (io(bus_ia, SU_VALID)) su_valid_q <= bus_wd[WSLOTS-1:0];
      if (io(bus_ia, W_T0))     w_t0_q     <= bus_wd;
      if (io(bus_ia, W_WE))     w_we_q     <= bus_wd[23:0];
      if (io(bus_ia, W_META))   w_meta_q   <= bus_wd[18:0];
      if (io(bus_ia, TRIG_T))   trig_t_q   <= bus_wd;
      if (io(bus_ia, HD_T))     hd_t_q     <= bus_wd;
      if (io(bus_ia, EVT_LO))   evt_lo_q   <= bus_wd;
      if (io(bus_ia, DIV_X))    div_x_q    <= bus_wd[23:0];
      if (io(bus_ia, WIN_RA))   win_ra_q   <= WAW'(bus_wd);
    end
  end
  assign halted = io_we && io(bus_ia, HALT);

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
    .clk_i, .rst_i(eng_rst), .go_i(io_we && io(bus_ia, SU_GO)), .mode_i(bus_wd[11:10]),
    .el_i(EW'(bus_wd[7:0])), .bon_i(bus_wd[8]), .won_i(bus_wd[9]), .valid_i(su_valid_q),
    .ta_i(su_ta_q), .tb_i(su_tb_q), .twa_i(su_twa_q), .twb_i(su_twb_q),
    .latm1_i(latm1), .win_ra_o(su_ra), .win_re_o(su_re), .win_t0_i(win_rd_q.t0),
    .win_len_i(wlen_q[{win_rd_q.sensor, win_rd_q.init}]), .win_we_i(win_rd_q.we),
    .win_sensor_i(win_rd_q.sensor),
    .busy_o(su_busy), .x_o(su_x), .flags_o(su_flags), .minc_o(su_minc)
  );
  ms_sched_div u_div (
    .clk_i, .rst_i(eng_rst), .start_i(io_we && io(bus_ia, DIV_N)), .x_i(div_x_q),
    .n_i(bus_wd[3:0]), .busy_o(div_busy), .q_o(div_q)
  );

  // ---- WINB (512 x 72: one write and one read port, two DP16KD of 512 x 36). Rows below
  // BLK_ROW are WIN, the window slots the program writes (W_ADDR commits W_*), read by the
  // slot unit's scan or at the program's WIN_RA; the rows above hold the blank offsets {a, b}
  // of every (sensor s, element e), two per row (row BLK_ROW + {s, e / 2}, half e % 2),
  // written through the load port while the engine is in reset, read on the bus (a at
  // BLK + 64 s + e, b at BLK + 64 s + 32 + e). The read port serves the scan first, then a bus
  // read of BLK, then WIN_RA: the program reads BLK only while the slot unit is idle, and a
  // WIN_* read in the clock after a BLK read sees the blank row (EngineSystem models both).
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
    end else if (io_we && io(bus_ia, W_ADDR)) begin
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
    .clk_i, .rst_i(eng_rst), .tick_i, .we_i(io_we && io(bus_ia, HD_EL)), .el_i(EW'(bus_wd[7:0])),
    .vld_i(!bus_wd[16]), .close_i(hd_t_q), .closes_o(closes)
  );
  assign q_pop = io_we && io(bus_ia, Q_POP);
  ms_sched_workq #(.WIDTH(QW), .DEPTH(QDEPTH)) u_workq (
    .clk_i, .rst_i(eng_rst), .push_i(!eng_rst && (|edges || |closes)),
    .data_i({tick_prev_q, edges, closes}), .pop_i(q_pop), .head_o(q_head), .empty_o(q_empty),
    .overflow_o(q_ovf)
  );
  logic late_head_q, late_trig_q, late_disp_q;
  always_ff @(posedge clk_i)
    late_head_q <= io_we && io(bus_ia, HD_EL) && !bus_wd[16] && $signed(26'(hd_t_q - tick_i)) <= 0;

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
        6'(STOP_REQ - 'h400): io_rd_q <= 32'(ctl_q == C_STOPPING);
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
  logic [19:0] trig_rel;
  assign trig_rel = 20'(trig_t_q - tick_i - 32'd1);   // the delay from the next clock's tick
  always_ff @(posedge clk_i) begin
    trig_valid_o <= 1'b0;
    evt_valid_o  <= 1'b0;
    pulse_o      <= 1'b0;
    late_trig_q  <= 1'b0;
    late_disp_q  <= 1'b0;
    if (io_we && io(bus_ia, TRIG_EL)) begin
      trig_valid_o <= 1'b1;
      trig_el_o    <= bus_wd[4:0];
      trig_delay_o <= (DELAY_W + 1)'(trig_rel);
      trig_burst_o <= burst_q[pulse_vs_q];
      late_trig_q  <= trig_rel[19:DELAY_W+1] != '0;   // negative or too far: the engine is late
    end
    if (io_we && io(bus_ia, EVT_HI)) begin
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
    if (io_we && io(bus_ia, LAG_CUR))
      late_disp_q <= $signed(24'(tick_i - bus_wd)) >= $signed(24'(LEAD / 2 + 2));
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
      if (io_we && io(bus_ia, T_DONE) && tick_i - bus_wd > lag_max_q) lag_max_q <= tick_i - bus_wd;
      if (q_ovf || late_head_q || late_trig_q || late_disp_q) ovr_q <= 1'b1;
    end
  end
  assign overrun_o = ovr_q;

  logic unused_ok;
  assign unused_ok = ^{eng_pc, su_busy, w_meta_q[15:10],
                       winb_rd_q[2*XW-1:$bits(win_t)]};
endmodule
