// ms_sonar_core: the complete sonar core — registers, 24 receive channels, the fast-firing
// scheduler, the phased transmitters and the event FIFO — behind one register bus.
//
// Timing contract: one clock (48 MHz). tick counts clocks since reset (TICK_START lets tests
// start it just below the 32-bit wrap). Element i triggers at tick t when drive_o[i] is first
// high in clock t+1; an echo first sampled high at tick n gets timestamp n (docs/sonar_core.md).
// Events reach the FIFO in the golden model's order (docs/fast_firing.md); the host or the
// soft-core reads them through EVT_LO / EVT_HI. EVENTS counts events produced, OVERFLOWS the
// ones dropped because the FIFO was full (the next stored one carries ms_event_pkg::OVF_BIT, 44).
module ms_sonar_core #(
  parameter int          NUM_CH     = 24,
  parameter int unsigned TICK_START = 0,
  parameter int          LEAD       = 32768, // scheduler decision lead (docs/fast_firing.md 3.1)
  parameter int          EVT_DEPTH_W = 9,   // event FIFO depth 2^EVT_DEPTH_W words (block RAM)
  // scheduler size (reported in CAPS): virtual sensors run and window slots per element; the
  // scheduler's program is built for 8 and 16 (sched_program.layout), other values do not elaborate
  parameter int          NUM_VS      = 8,
  parameter int          WSLOTS      = 16
) (
  input  logic              clk_i,
  input  logic              rst_i,
  // register bus (PeakRDL passthrough)
  input  logic              bus_req_i,
  input  logic              bus_req_is_wr_i,
  input  logic [10:0]       bus_addr_i,
  input  logic [31:0]       bus_wr_data_i,
  input  logic [31:0]       bus_wr_biten_i,
  output logic              bus_req_stall_wr_o,
  output logic              bus_req_stall_rd_o,
  output logic              bus_rd_ack_o,
  output logic              bus_rd_err_o,
  output logic [31:0]       bus_rd_data_o,
  output logic              bus_wr_ack_o,
  output logic              bus_wr_err_o,
  // transducers
  input  logic [NUM_CH-1:0] echo_i,   // comparator outputs, asynchronous
  output logic [NUM_CH-1:0] drive_o,  // burst drive, registered
  output logic              evt_available_o  // an event waits in the FIFO (interrupt)
);
  localparam int DELAY_W = 16;

  logic [31:0] tick_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) tick_q <= 32'(TICK_START);
    else       tick_q <= tick_q + 32'd1;
  end

  // ---- registers
  logic                          enable, hold, start, unused_clear_counters;
  logic [15:0]                   burst_half_period;
  logic [7:0]                    unused_burst_cycles, glitch_min;
  logic                          ld_we;
  logic [11:0]                   ld_addr;
  logic [31:0]                   ld_data;
  logic                          fifo_rvalid, fifo_pop, fifo_overflow;
  logic [63:0]                   fifo_rdata;
  logic [11:0]                   fifo_level;
  logic                          running, overrun, pulse, tx_collision;
  logic                          evt_valid;
  logic [63:0]                   evt_data;

  ms_csr #(.NUM_CH(NUM_CH), .DELAY_W(DELAY_W), .NUM_VS(NUM_VS), .WSLOTS(WSLOTS),
           .EVT_DEPTH_W(EVT_DEPTH_W)) u_csr (
    .clk_i, .rst_i,
    .bus_req_i, .bus_req_is_wr_i, .bus_addr_i, .bus_wr_data_i, .bus_wr_biten_i,
    .bus_req_stall_wr_o, .bus_req_stall_rd_o, .bus_rd_ack_o, .bus_rd_err_o, .bus_rd_data_o,
    .bus_wr_ack_o, .bus_wr_err_o,
    .enable_o (enable), .hold_o (hold), .start_o (start),
    .clear_counters_o (unused_clear_counters),
    .burst_half_period_o (burst_half_period), .burst_cycles_o (unused_burst_cycles),
    .glitch_min_o (glitch_min), .ld_we_o (ld_we), .ld_addr_o (ld_addr), .ld_data_o (ld_data),
    .evt_rvalid_i (fifo_rvalid), .evt_rdata_i (fifo_rdata), .evt_pop_o (fifo_pop),
    .running_i (running), .sched_overrun_i (overrun), .tx_collision_i (tx_collision),
    .fifo_level_i (fifo_level),
    .event_i (evt_valid), .overflow_i (fifo_overflow), .pulse_i (pulse)
  );

  // ---- receive channels
  logic [NUM_CH-1:0] rise;
  logic [NUM_CH-1:0] unused_level;
`ifdef MS_TWIN_RX_GATE
  // Simulation only (the full-system twin, sim/twin; mk/twin.mk defines it): the conditioners are
  // clocked by a variable the harness drives, held while every one has settled on its input and
  // neither an input nor twin_rx_key changes, so their state would not change (docs/twin.md).
  // Never defined for synthesis, lint or the RTL tests.
  logic       twin_rx_clk;
  logic [8:0] twin_rx_key;
  assign twin_rx_key = {rst_i, glitch_min};
`endif
  for (genvar c = 0; c < NUM_CH; c++) begin : g_rx
    ms_rx_conditioner u_rx (
`ifdef MS_TWIN_RX_GATE
      .clk_i (twin_rx_clk),
`else
      .clk_i,
`endif
      .rst_i, .echo_i (echo_i[c]), .glitch_min_i (glitch_min),
      .level_o (unused_level[c]), .rise_o (rise[c])
    );
  end

  // ---- scheduler
  logic                      trig_valid, pulse_init;
  logic [4:0]                trig_el;
  logic [DELAY_W:0]          trig_delay;
  logic [7:0]                trig_burst, pulse_seq;
  logic [2:0]                pulse_vs;
  logic [NUM_CH-1:0]         unused_pulse_tx;  // for testbenches (through the hierarchy)
  logic [31:0]               pulse_t0;

  ms_sched_uc #(.NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .DELAY_W(DELAY_W), .LEAD(LEAD), .WSLOTS(WSLOTS)) u_sched (
    .clk_i, .rst_i, .tick_i (tick_q), .enable_i (enable),
    // the firmware's check and load (CTRL.hold, LOAD_ADDR / LOAD_DATA, CTRL.start)
    .hold_i (hold), .ld_we_i (ld_we), .ld_addr_i (ld_addr), .ld_data_i (ld_data), .start_i (start),
    .glitch_min_i (glitch_min), .rise_i (rise),
    .trig_valid_o (trig_valid), .trig_el_o (trig_el), .trig_delay_o (trig_delay),
    .trig_burst_o (trig_burst),
    .pulse_o (pulse), .pulse_vs_o (pulse_vs), .pulse_tx_o (unused_pulse_tx), .pulse_seq_o (pulse_seq), .pulse_t0_o (pulse_t0),
    .pulse_init_o (pulse_init),
    .evt_valid_o (evt_valid), .evt_data_o (evt_data),
    .running_o (running), .overrun_o (overrun)
  );

  // ---- transmitters: the scheduler arms one element per clock (one-hot fire, its delay
  // counted from this cycle), so pulses of several sensors may be pending at once
  logic [NUM_CH-1:0]              fire_mask;
  logic [NUM_CH-1:0][DELAY_W:0]   fire_delay;
  logic [NUM_CH-1:0][7:0]         fire_burst;
  always_comb begin
    for (int c = 0; c < NUM_CH; c++) begin
      fire_mask[c]  = trig_valid && (trig_el == 5'(c));
      fire_delay[c] = trig_delay;
      fire_burst[c] = trig_burst;
    end
  end
  logic [NUM_CH-1:0] unused_busy;
  logic              unused_pulse;
  assign unused_pulse = ^{pulse_vs, pulse_seq, pulse_t0, pulse_init};
  ms_tx_phaser #(.NUM_CH(NUM_CH), .DELAY_W(DELAY_W + 1)) u_tx (
    .clk_i, .rst_i, .fire_i (trig_valid), .mask_i (fire_mask), .delay_i (fire_delay),
    .burst_cycles_i (fire_burst), .half_period_i (burst_half_period),
    .drive_o, .busy_o (unused_busy), .collision_o (tx_collision)
  );

  // ---- events
  ms_event_fifo #(
    .WIDTH(64), .DEPTH_W(EVT_DEPTH_W), .OVF_BIT(ms_event_pkg::OVF_BIT), .LEVEL_W(12)
  ) u_fifo (
    .clk_i, .rst_i, .wr_i (evt_valid), .wdata_i (evt_data), .rd_i (fifo_pop),
    .rvalid_o (fifo_rvalid), .rdata_o (fifo_rdata), .overflow_o (fifo_overflow), .level_o (fifo_level)
  );
  assign evt_available_o = fifo_rvalid;
endmodule
