// ms_tx_phaser: per-element phasing delay and burst generator of the transmit ring
// (docs/sonar_core.md). One ms_tx_channel per element; the elements share only a
// free-running tick counter, against which each stores the tick of its pending trigger.
//
// Timing contract (ticks of clk_i; "at tick T" = loaded at the edge that ends cycle T, so
// visible from cycle T+1; checked tick-exactly in tests/rtl/test_ms_tx_phaser.py):
//   - fire_i high in cycle t0: every element i with mask_i[i] set is triggered at tick
//     t0 + delay_i[i] (delay 0 = t0 itself; up to 2^DELAY_W - 1). drive_o[i] is first high
//     in cycle t0 + delay_i[i] + 1. Elements not in mask_i are not affected by the fire.
//   - A trigger drives burst_cycles_i periods of 2 * half_period_i ticks, high first, 50 %
//     duty, then drive_o[i] stays low. half_period_i = 0 behaves as 1; burst_cycles_i = 0
//     drives nothing (and ends a burst still running at the trigger tick).
//   - burst_cycles_i[i] (per element: fires of different sensors may share a tick) and
//     half_period_i are latched per element at fire_i: a CSR change after
//     the fire changes neither pending triggers nor running bursts.
//   - drive_o is a flop output per element: zero jitter, elements of one group (and of
//     different groups) start exactly on their computed ticks.
//   - Collision: a fire that hits an element whose previous trigger is still pending (due at
//     a tick >= t0) replaces that trigger (the old one never happens); collision_o is high
//     for one clock, in cycle t0 + 1, per fire with at least one such element.
//   - A fire hitting an element whose burst is running is no collision: the burst runs on
//     until the new trigger tick and restarts there (first half high, full length).
//   - busy_o[i]: element i has a pending trigger or a running burst (registered state).
module ms_tx_phaser #(
  parameter int NUM_CH  = 24,  // ms_layout_pkg::NUM_CH, passed by the top (Icarus 11 cannot parse the package)
  parameter int DELAY_W = 16,
  parameter int HALF_W  = 16,
  parameter int CYC_W   = 8
) (
  input  logic                           clk_i,
  input  logic                           rst_i,
  input  logic                           fire_i,          // strobe in the issue tick t0
  input  logic [NUM_CH-1:0]              mask_i,          // elements triggered by this fire
  input  logic [NUM_CH-1:0][DELAY_W-1:0] delay_i,         // element i triggers at t0 + delay_i[i]
  input  logic [NUM_CH-1:0][CYC_W-1:0]   burst_cycles_i,  // periods per burst, per element (sensor field)
  input  logic [HALF_W-1:0]              half_period_i,   // BURST.half_period, 600 = 40 kHz
  output logic [NUM_CH-1:0]              drive_o,         // registered transducer drives
  output logic [NUM_CH-1:0]              busy_o,          // pending trigger or running burst
  output logic                           collision_o      // one-clock strobe, cycle t0 + 1
);
  logic [NUM_CH-1:0]  override;
  logic               collision_q;
  logic [DELAY_W-1:0] now_q, now_nx_q;  // tick counter and its value in the next cycle

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      now_q    <= '0;
      now_nx_q <= DELAY_W'(1);
    end else begin
      now_q    <= now_nx_q;
      now_nx_q <= now_nx_q + DELAY_W'(1);
    end
  end

  for (genvar i = 0; i < NUM_CH; i++) begin : g_ch
    ms_tx_channel #(
      .DELAY_W(DELAY_W),
      .HALF_W (HALF_W),
      .CYC_W  (CYC_W)
    ) u_ch (
      .clk_i         (clk_i),
      .rst_i         (rst_i),
      .now_i         (now_q),
      .now_nx_i      (now_nx_q),
      .fire_i        (fire_i & mask_i[i]),
      .delay_i       (delay_i[i]),
      .burst_cycles_i(burst_cycles_i[i]),
      .half_period_i (half_period_i),
      .drive_o       (drive_o[i]),
      .busy_o        (busy_o[i]),
      .override_o    (override[i])
    );
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      collision_q <= 1'b0;
    end else begin
      collision_q <= |override;
    end
  end

  assign collision_o = collision_q;
endmodule
