// ms_scheduler_tb: cocotb wrapper of ms_scheduler (tests/rtl/tb_ms_scheduler.py).
//
// Holds what the testbench would otherwise have to drive per clock: a free-running tick
// counter loaded with tick_start_i during reset (wrap tests), the real ms_rx_conditioner per channel, the
// phasing-delay RAM (ms_ram_dp; the testbench loads it through port A before enable) and an
// event log the testbench reads at the end through evt_raddr_i / evt_rdata_o. Only table
// entry 0 of the VS table is driven (stage 1 of the scheduler uses only that entry).
module ms_scheduler_tb #(
  parameter int          NUM_CH    = 24,
  parameter int unsigned LEAD      = 1024,
  parameter int          EVT_DEPTH = 4096
) (
  input  logic                    clk_i,
  input  logic                    rst_i,
  input  logic                    enable_i,
  input  logic [31:0]             tick_start_i,  // tick counter value during reset (wrap tests)
  input  logic [7:0]              glitch_min_i,
  input  logic [NUM_CH-1:0]       echo_i,
  input  logic [NUM_CH-1:0]       tx_mask_i,
  input  logic [NUM_CH-1:0]       rx_mask_i,
  input  logic [1:0]              mode_i,
  input  logic [2:0]              order_i,
  input  logic [3:0]              miss_limit_i,
  input  logic [15:0]             t_v_i,
  input  logic [15:0]             t_n_i,
  input  logic [19:0]             t_dead_i,
  input  logic [23:0]             max_tof_i,
  input  logic [19:0]             t_xtalk_i,
  input  logic [15:0]             vmax_i,
  input  logic [7:0]              burst_cycles_i,
  input  logic [23:0]             phase_i,
  input  logic                    dly_we_i,
  input  logic [7:0]              dly_addr_i,
  input  logic [15:0]             dly_wdata_i,
  output logic [31:0]             tick_o,
  output logic                    fire_o,
  output logic [NUM_CH-1:0]       fire_mask_o,
  output logic [NUM_CH*16-1:0]    fire_delay_o,
  output logic [7:0]              fire_burst_cycles_o,
  output logic [15:0]             evt_count_o,
  input  logic [15:0]             evt_raddr_i,
  output logic [63:0]             evt_rdata_o,
  output logic                    running_o,
  output logic                    overrun_o
);
  localparam int NUM_VS = 8;

  logic [31:0] tick_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) tick_q <= tick_start_i;
    else       tick_q <= tick_q + 32'd1;
  end
  assign tick_o = tick_q;

  logic [NUM_CH-1:0] rise, level;
  for (genvar i = 0; i < NUM_CH; i++) begin : g_rx
    ms_rx_conditioner u_rx (
      .clk_i       (clk_i),
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
    .clk_i    (clk_i),
    .we_a_i   (dly_we_i),
    .addr_a_i (dly_addr_i),
    .wdata_a_i(dly_wdata_i),
    .rdata_a_o(dly_rdata_a),
    .addr_b_i (dly_raddr),
    .rdata_b_o(dly_rdata)
  );

  logic [NUM_VS-1:0][NUM_CH-1:0] vs_tx, vs_rx;
  logic [NUM_VS-1:0][1:0]        vs_mode, vs_nb;
  logic [NUM_VS-1:0][2:0]        vs_order;
  logic [NUM_VS-1:0][3:0]        vs_k;
  logic [NUM_VS-1:0][15:0]       vs_tv, vs_tn, vs_vmax;
  logic [NUM_VS-1:0][19:0]       vs_dead, vs_xt;
  logic [NUM_VS-1:0][23:0]       vs_rmax, vs_phase;
  logic [NUM_VS-1:0][7:0]        vs_burst;
  always_comb begin
    vs_tx = '0; vs_rx = '0; vs_mode = '0; vs_nb = '0; vs_order = '0; vs_k = '0;
    vs_tv = '0; vs_tn = '0; vs_vmax = '0; vs_dead = '0; vs_xt = '0; vs_rmax = '0;
    vs_phase = '0; vs_burst = '0;
    vs_tx[0] = tx_mask_i;   vs_rx[0] = rx_mask_i;     vs_mode[0] = mode_i;
    vs_order[0] = order_i;  vs_k[0] = miss_limit_i;   vs_tv[0] = t_v_i;
    vs_tn[0] = t_n_i;       vs_vmax[0] = vmax_i;      vs_dead[0] = t_dead_i;
    vs_xt[0] = t_xtalk_i;   vs_rmax[0] = max_tof_i;   vs_phase[0] = phase_i;
    vs_burst[0] = burst_cycles_i;
  end

  logic [NUM_CH-1:0][15:0] fire_delay;
  logic                    evt_valid;
  logic [63:0]             evt_data;
  logic [2:0]              fire_vs;
  logic                    pulse;
  logic [3:0]              cfg_error, cfg_error_vs;

  ms_scheduler #(.NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .LEAD(LEAD)) u_sched (
    .clk_i              (clk_i),
    .rst_i              (rst_i),
    .tick_i             (tick_q),
    .enable_i           (enable_i),
    .apply_i            (1'b0),
    .vs_tx_mask_i       (vs_tx),
    .vs_rx_mask_i       (vs_rx),
    .vs_mode_i          (vs_mode),
    .vs_order_i         (vs_order),
    .vs_miss_limit_i    (vs_k),
    .vs_t_v_i           (vs_tv),
    .vs_t_n_i           (vs_tn),
    .vs_t_dead_i        (vs_dead),
    .vs_max_tof_i       (vs_rmax),
    .vs_t_xtalk_i       (vs_xt),
    .vs_xtalk_nb_i      (vs_nb),
    .vs_vmax_i          (vs_vmax),
    .vs_burst_cycles_i  (vs_burst),
    .vs_phase_i         (vs_phase),
    .glitch_min_i       (glitch_min_i),
    .delay_raddr_o      (dly_raddr),
    .delay_rdata_i      (dly_rdata),
    .rise_i             (rise),
    .fire_o             (fire_o),
    .fire_vs_o          (fire_vs),
    .fire_mask_o        (fire_mask_o),
    .fire_delay_o       (fire_delay),
    .fire_burst_cycles_o(fire_burst_cycles_o),
    .evt_valid_o        (evt_valid),
    .evt_data_o         (evt_data),
    .pulse_o            (pulse),
    .running_o          (running_o),
    .cfg_error_o        (cfg_error),
    .cfg_error_vs_o     (cfg_error_vs),
    .overrun_o          (overrun_o)
  );
  assign fire_delay_o = fire_delay;

  logic [63:0] evt_mem [EVT_DEPTH];
  logic [15:0] evt_cnt_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      evt_cnt_q <= '0;
    end else if (evt_valid) begin
      if (evt_cnt_q < 16'(EVT_DEPTH)) evt_mem[evt_cnt_q[$clog2(EVT_DEPTH)-1:0]] <= evt_data;
      evt_cnt_q <= evt_cnt_q + 16'd1;
    end
  end
  assign evt_count_o = evt_cnt_q;
  assign evt_rdata_o = evt_mem[evt_raddr_i[$clog2(EVT_DEPTH)-1:0]];

  logic unused_ok;
  assign unused_ok = ^{level, dly_rdata_a, fire_vs, pulse, cfg_error, cfg_error_vs};
endmodule
