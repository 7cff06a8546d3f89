// ms_scheduler_tb: cocotb wrapper of the fast-firing scheduler, ms_sched_uc (the scheduler on
// the microcoded engine; tests/rtl/tb_ms_scheduler.py).
//
// Holds what the testbench would otherwise have to drive or sample per clock: a free-running
// tick counter loaded with tick_start_i during reset (wrap tests), the real ms_rx_conditioner
// per channel, and logs the testbench reads at the end: every event word, and every trigger as
// {element, tick it fires} (the tick of the arming cycle plus trig_delay_o, i.e. when
// ms_tx_phaser would trigger it). Tables come through the load port, as the firmware writes them.
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
  input  logic                 hold_i,        // the load port (ms_sched_uc)
  input  logic                 ld_we_i,
  input  logic [11:0]          ld_addr_i,
  input  logic [31:0]          ld_data_i,
  input  logic                 start_i,
  input  logic [31:0]          tick_start_i,  // tick counter value during reset (wrap tests)
  input  logic [7:0]           glitch_min_i,
  input  logic [NUM_CH-1:0]    echo_i,
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
    .hold_i             (hold_i),
    .ld_we_i            (ld_we_i),
    .ld_addr_i          (ld_addr_i),
    .ld_data_i          (ld_data_i),
    .start_i            (start_i),
    .glitch_min_i       (glitch_min_i),
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
  assign unused_ok = ^{level, trig_burst, evt_raddr_i[15:$clog2(EVT_DEPTH)],
                       trg_raddr_i[15:$clog2(TRG_DEPTH)]};
endmodule
