// ms_scheduler_tb: cocotb wrapper of the fast-firing scheduler, ms_sched_uc (the scheduler on
// the microcoded engine; tests/rtl/tb_ms_scheduler.py).
//
// Holds what the testbench would otherwise have to drive or sample per clock: a free-running
// tick counter loaded with tick_start_i during reset (wrap tests), the real ms_rx_conditioner
// per channel, the CSR phasing-delay RAM (ms_ram_dp; loaded through port A), and logs the
// testbench reads at the end: every event word, and every trigger as {element, tick it fires}
// (the tick of the arming cycle plus trig_delay_o, i.e. when ms_tx_phaser would trigger it).
// The whole virtual-sensor table is driven as flat vectors (sensor s at bits [s*W +: W]).
// The clock `clk` is made here (a build with Verilator --timing; tests/rtl/cocotb_run.py
// OWN_CLOCK_TOPS), not driven through the simulator interface: cocotb's GPI clock costs a VPI
// callback per edge, which held the scoreboards to 130-500 k cycles/s. The testbench writes
// its inputs at falling edges, where no write races a rising edge.
module ms_scheduler_tb #(
  parameter int CLK_HALF_PS = 10417,   // tests/rtl/tbutil.py CLK_PERIOD_PS / 2
  parameter int NUM_CH    = 24,
  parameter int LEAD      = 4096,
  parameter int EVT_DEPTH = 8192,
  parameter int TRG_DEPTH = 4096,
  parameter string UCODE_FILE = ""  // the engine's program image (empty: the gen step's)
) (
  input  logic                 rst_i,
  input  logic                 enable_i,
  input  logic                 apply_i,
  input  logic                 hold_i,        // the load port (ms_sched_uc)
  input  logic                 ld_we_i,
  input  logic [11:0]          ld_addr_i,
  input  logic [31:0]          ld_data_i,
  input  logic                 start_i,
  input  logic [31:0]          tick_start_i,  // tick counter value during reset (wrap tests)
  input  logic [7:0]           glitch_min_i,
  input  logic [15:0]          miss_gate_i,
  input  logic [15:0]          burst_half_period_i,
  input  logic [NUM_CH-1:0]    echo_i,
  input  logic [8*NUM_CH-1:0]  tx_mask_i,
  input  logic [8*NUM_CH-1:0]  rx_mask_i,
  input  logic [8*2-1:0]       mode_i,
  input  logic [8*4-1:0]       order_i,
  input  logic [8*4-1:0]       miss_limit_i,
  input  logic [8*8-1:0]       reinit_every_i,
  input  logic [8*16-1:0]      t_v_i,
  input  logic [8*16-1:0]      t_n_i,
  input  logic [8*20-1:0]      t_dead_i,
  input  logic [8*24-1:0]      max_tof_i,
  input  logic [8*20-1:0]      t_xtalk_i,
  input  logic [8*2-1:0]       xtalk_nb_i,
  input  logic [8*16-1:0]      vmax_i,
  input  logic [8*8-1:0]       burst_cycles_i,
  input  logic [8*24-1:0]      phase_i,
  input  logic                 dly_we_i,
  input  logic [7:0]           dly_addr_i,
  input  logic [15:0]          dly_wdata_i,
  output logic [31:0]          tick_o,
  output logic                 pulse_o,
  output logic [2:0]           pulse_vs_o,
  output logic [7:0]           pulse_seq_o,
  output logic [31:0]          pulse_t0_o,
  output logic                 pulse_init_o,
  output logic [15:0]          evt_count_o,
  input  logic [15:0]          evt_raddr_i,
  output logic [63:0]          evt_rdata_o,
  output logic [15:0]          trg_count_o,
  input  logic [15:0]          trg_raddr_i,
  output logic [39:0]          trg_rdata_o,   // {element[7:0], tick[31:0]}
  output logic                 running_o,
  output logic [3:0]           cfg_error_o,
  output logic [3:0]           cfg_error_vs_o,
  output logic                 overrun_o
);
  localparam int NUM_VS = 8;

  logic clk = 1'b0;
  always #(CLK_HALF_PS * 1ps) clk = ~clk;

  logic [31:0] tick_q;
  always_ff @(posedge clk) begin
    if (rst_i) tick_q <= tick_start_i;
    else       tick_q <= tick_q + 32'd1;
  end
  assign tick_o = tick_q;

  logic [NUM_CH-1:0] rise, level;
  for (genvar i = 0; i < NUM_CH; i++) begin : g_rx
    ms_rx_conditioner u_rx (
      .clk_i       (clk),
      .rst_i       (rst_i),
      .echo_i      (echo_i[i]),
      .glitch_min_i(glitch_min_i),
      .level_o     (level[i]),
      .rise_o      (rise[i])
    );
  end

  logic [7:0]  dly_raddr;
  logic [15:0] dly_rdata, dly_rdata_a;
  ms_ram_dp #(.WIDTH(16), .DEPTH(256)) u_dly (
    .clk_i    (clk),
    .we_a_i   (dly_we_i),
    .addr_a_i (dly_addr_i),
    .wdata_a_i(dly_wdata_i),
    .rdata_a_o(dly_rdata_a),
    .addr_b_i (dly_raddr),
    .rdata_b_o(dly_rdata)
  );

  logic [NUM_VS-1:0][NUM_CH-1:0] vs_tx, vs_rx;
  logic [NUM_VS-1:0][1:0]        vs_mode, vs_nb;
  logic [NUM_VS-1:0][3:0]        vs_order;
  logic [NUM_VS-1:0][3:0]        vs_k;
  logic [NUM_VS-1:0][15:0]       vs_tv, vs_tn, vs_vmax;
  logic [NUM_VS-1:0][19:0]       vs_dead, vs_xt;
  logic [NUM_VS-1:0][23:0]       vs_rmax, vs_phase;
  logic [NUM_VS-1:0][7:0]        vs_burst, vs_reinit;
  assign vs_tx = tx_mask_i;   assign vs_rx = rx_mask_i;      assign vs_mode = mode_i;
  assign vs_nb = xtalk_nb_i;  assign vs_order = order_i;     assign vs_k = miss_limit_i;
  assign vs_reinit = reinit_every_i;
  assign vs_tv = t_v_i;       assign vs_tn = t_n_i;          assign vs_vmax = vmax_i;
  assign vs_dead = t_dead_i;  assign vs_xt = t_xtalk_i;      assign vs_rmax = max_tof_i;
  assign vs_phase = phase_i;  assign vs_burst = burst_cycles_i;

  // The CSR's VS table read port (ms_csr): word entry * 9 + register, the register map's field
  // positions, data one clock after the address.
  logic [6:0]  vs_raddr;
  logic [31:0] vs_rdata;
  function automatic logic [31:0] vs_word(input int a);
    int e, r;
    e = a / 9;
    r = a % 9;
    vs_word = '0;
    if (e < NUM_VS)
      unique case (r)
        0:       vs_word = 32'(vs_tx[e]);
        1:       vs_word = 32'(vs_rx[e]);
        2:       vs_word = {12'd0, vs_reinit[e], vs_k[e], vs_order[e], 2'b0, vs_mode[e]};
        3:       vs_word = {vs_tn[e], vs_tv[e]};
        4:       vs_word = 32'(vs_dead[e]);
        5:       vs_word = 32'(vs_rmax[e]);
        6:       vs_word = {10'd0, vs_nb[e], vs_xt[e]};
        7:       vs_word = {8'd0, vs_burst[e], vs_vmax[e]};
        default: vs_word = 32'(vs_phase[e]);
      endcase
  endfunction
  always_ff @(posedge clk) vs_rdata <= vs_word(int'(vs_raddr));

  logic             trig_valid;
  logic [4:0]       trig_el;
  logic [16:0]      trig_delay;
  logic [7:0]       trig_burst;
  logic             evt_valid;
  logic [63:0]      evt_data;

  ms_sched_uc #(.NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .LEAD(LEAD), .UCODE_FILE(UCODE_FILE)) u_sched (
    .clk_i              (clk),
    .rst_i              (rst_i),
    .tick_i             (tick_q),
    .enable_i           (enable_i),
    .apply_i            (apply_i),
    .hold_i             (hold_i),
    .ld_we_i            (ld_we_i),
    .ld_addr_i          (ld_addr_i),
    .ld_data_i          (ld_data_i),
    .start_i            (start_i),
    .vs_ren_o           (),
    .vs_raddr_o         (vs_raddr),
    .vs_rdata_i         (vs_rdata),
    .burst_half_period_i(burst_half_period_i),
    .glitch_min_i       (glitch_min_i),
    .miss_gate_i        (miss_gate_i),
    .delay_raddr_o      (dly_raddr),
    .delay_rdata_i      (dly_rdata),
    .rise_i             (rise),
    .trig_valid_o       (trig_valid),
    .trig_el_o          (trig_el),
    .trig_delay_o       (trig_delay),
    .trig_burst_o       (trig_burst),
    .pulse_o            (pulse_o),
    .pulse_vs_o         (pulse_vs_o),
    .pulse_tx_o         (),
    .pulse_seq_o        (pulse_seq_o),
    .pulse_t0_o         (pulse_t0_o),
    .pulse_init_o       (pulse_init_o),
    .evt_valid_o        (evt_valid),
    .evt_data_o         (evt_data),
    .running_o          (running_o),
    .cfg_error_o        (cfg_error_o),
    .cfg_error_vs_o     (cfg_error_vs_o),
    .overrun_o          (overrun_o)
  );

  logic [63:0] evt_mem [EVT_DEPTH];
  logic [15:0] evt_cnt_q;
  logic [39:0] trg_mem [TRG_DEPTH];
  logic [15:0] trg_cnt_q;
  always_ff @(posedge clk) begin
    if (rst_i) begin
      evt_cnt_q <= '0;
      trg_cnt_q <= '0;
    end else begin
      if (evt_valid) begin
        if (evt_cnt_q < 16'(EVT_DEPTH)) evt_mem[evt_cnt_q[$clog2(EVT_DEPTH)-1:0]] <= evt_data;
        evt_cnt_q <= evt_cnt_q + 16'd1;
      end
      if (trig_valid) begin  // fire seen by the phaser in this cycle: triggers at tick_q + delay
        if (trg_cnt_q < 16'(TRG_DEPTH))
          trg_mem[trg_cnt_q[$clog2(TRG_DEPTH)-1:0]] <= {3'd0, trig_el, tick_q + 32'(trig_delay)};
        trg_cnt_q <= trg_cnt_q + 16'd1;
      end
    end
  end
  assign evt_count_o = evt_cnt_q;
  assign evt_rdata_o = evt_mem[evt_raddr_i[$clog2(EVT_DEPTH)-1:0]];
  assign trg_count_o = trg_cnt_q;
  assign trg_rdata_o = trg_mem[trg_raddr_i[$clog2(TRG_DEPTH)-1:0]];

  logic unused_ok;
  assign unused_ok = ^{level, dly_rdata_a, trig_burst, evt_raddr_i[15:$clog2(EVT_DEPTH)],
                       trg_raddr_i[15:$clog2(TRG_DEPTH)]};
endmodule
