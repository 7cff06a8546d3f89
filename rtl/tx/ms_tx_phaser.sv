// ms_tx_phaser: per-element phasing delay and burst generator of the transmit ring
// (docs/sonar_core.md). One ms_tx_channel per element; the elements share a free-running
// tick counter, against which each stores the tick of its pending trigger, and a phase
// counter modulo the half period, against which each times the halves of its burst.
//
// Timing contract (ticks of clk_i; "at tick T" = loaded at the edge that ends cycle T, so
// visible from cycle T+1; checked tick-exactly in tests/rtl/test_ms_tx_phaser.py):
//   - fire_i high in cycle t0: every element i with mask_i[i] set is triggered at tick
//     t0 + delay_i[i] (delay 0 = t0 itself; up to 2^DELAY_W - 1). drive_o[i] is first high
//     in cycle t0 + delay_i[i] + 1. Elements not in mask_i are not affected by the fire.
//   - A trigger drives burst_cycles_i periods of 2 * half_period_i ticks, high first, 50 %
//     duty, then drive_o[i] stays low. half_period_i = 0 behaves as 1; burst_cycles_i = 0
//     drives nothing (and ends a burst still running at the trigger tick).
//   - burst_cycles_i[i] (per element: fires of different sensors may share a tick) is
//     latched per element at fire_i: a change after the fire changes neither pending
//     triggers nor running bursts.
//   - half_period_i (one for all elements: the transducers' frequency, BURST.half_period) is
//     sampled in every clock in which no element is busy, the clock of a fire included; a
//     busy stretch (from such a fire until every element is idle again) uses the value of
//     its first clock, and a change during it waits until all elements are idle. So every
//     burst of a stretch has the same H, and the elements share one phase counter.
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
  // Half periods: phase_q counts 0 .. H-1 round (H = max(half_period, 1), hm1_q = H - 1)
  // while an element is busy, phase_nx_q is its value in the next cycle. One edge after its
  // trigger an element stores the phase of that cycle and ends a half in every cycle whose
  // next phase comes round to it, i.e. H, 2H, ... clocks after the trigger (in the cycle after
  // the trigger from h1_q: H = 1). While all are idle hm1_q follows half_period_i and the
  // count restarts from 0 in the next cycle, so a burst triggered in an idle cycle (a fire
  // with delay 0) counts with the H of its own cycle.
  logic [HALF_W-1:0]  phase_q, phase_nx_q, hm1_q, hm1_in;
  logic               h1_q;
  logic [NUM_CH-1:0]  busy;
  logic               idle;
  assign hm1_in = half_period_i - HALF_W'(half_period_i != '0);
  assign idle   = (busy == '0);

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      now_q    <= '0;
      now_nx_q <= DELAY_W'(1);
    end else begin
      now_q    <= now_nx_q;
      now_nx_q <= now_nx_q + DELAY_W'(1);
    end
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      hm1_q      <= '0;
      h1_q       <= 1'b1;
      phase_q    <= '0;
      phase_nx_q <= '0;
    end else if (idle) begin
      hm1_q      <= hm1_in;
      h1_q       <= (hm1_in == '0);
      phase_q    <= '0;
      phase_nx_q <= HALF_W'(hm1_in != '0);
    end else begin
      phase_q    <= phase_nx_q;
      phase_nx_q <= (phase_nx_q == hm1_q) ? '0 : phase_nx_q + HALF_W'(1);
    end
  end

`ifdef MS_TWIN_TX_GATE
  // Simulation only (the full-system twin, sim/twin; mk/twin.mk defines it): each element is
  // clocked by a variable the harness drives, held while the element is idle and no fire or
  // reset reaches it (twin_wake), so its state would not change (docs/twin.md). Never defined
  // for synthesis, lint or the RTL tests.
  logic [NUM_CH-1:0] twin_wake;
  assign twin_wake = {NUM_CH{rst_i}} | (fire_i ? mask_i : '0);
`endif

  for (genvar i = 0; i < NUM_CH; i++) begin : g_ch
`ifdef MS_TWIN_TX_GATE
    logic twin_ch_clk;
`endif
    ms_tx_channel #(
      .DELAY_W(DELAY_W),
      .HALF_W (HALF_W),
      .CYC_W  (CYC_W)
    ) u_ch (
`ifdef MS_TWIN_TX_GATE
      .clk_i         (twin_ch_clk),
`else
      .clk_i         (clk_i),
`endif
      .rst_i         (rst_i),
      .now_i         (now_q),
      .now_nx_i      (now_nx_q),
      .phase_i       (phase_q),
      .phase_nx_i    (phase_nx_q),
      .h1_i          (h1_q),
      .fire_i        (fire_i & mask_i[i]),
      .delay_i       (delay_i[i]),
      .burst_cycles_i(burst_cycles_i[i]),
      .drive_o       (drive_o[i]),
      .busy_o        (busy[i]),
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
  assign busy_o      = busy;
endmodule
