// ms_tx_channel: delay counter and burst generator of one transmit element (one instance
// per element inside ms_tx_phaser, which states the contract for the whole array).
//
// Timing contract (ticks of clk_i; "at tick T" = loaded at the edge that ends cycle T):
//   - fire_i high in cycle t0 (already masked for this element) triggers the element at
//     tick t = t0 + delay_i. delay_i = 0 triggers in t0 itself (no extra latency).
//   - A trigger at tick t with latched cycles B sets drive_o high from cycle t+1: B periods
//     of 2*H ticks, high first (H high, H low), then low, where H is the phaser's half
//     period (ms_tx_phaser: sampled while no element is busy, so constant during a burst).
//     B = 0 drives nothing and ends a running burst at t.
//   - burst_cycles_i is latched with fire_i; later changes of the input affect neither the
//     pending trigger nor the running burst.
//   - A fire while a trigger is pending (its tick >= t0, i.e. including a trigger due in
//     t0 itself) replaces it: override_o is high in cycle t0 (combinational, from
//     fire_i), the old trigger never happens.
//   - A fire while a burst runs lets the burst run on until the new trigger tick, where
//     the new burst starts from its beginning (a high half then lasts the rest of the old
//     high half plus H). The delay counter and the burst generator are independent.
//   - busy_o: a trigger is pending or a burst is running (registered state only).
//
// Implementation (sized for area: equality compares and constant loads instead of load
// muxes and subtractors):
//   - The delay is not counted per element. The phaser's free-running tick counter (now_i,
//     and now_nx_i = now_i + 1 one register ahead) is shared; a fire stores the trigger tick
//     tgt_q = now_i + delay_i (mod 2^DELAY_W, reached exactly once since delay_i < 2^DELAY_W).
//     The scheduler arms one element per clock with one delay bus, so after flattening Yosys
//     merges the 24 adders (and the delay_i == 0 / == 1 tests) into one. due_q says "the
//     pending trigger is due in the next cycle", registered from tgt_q == now_nx_i: the
//     trigger comes from a flop, not from a compare against a counter across the chip.
//   - The half periods are not counted per element either. The phaser's phase counter
//     phase_i runs modulo H (H ticks per lap) while any element is busy, phase_nx_i is its
//     next value. One edge after the trigger (trig_q) the element stores the phase of that
//     cycle (phi_q); a later cycle whose next phase equals phi_q ends a half (H, 2H, ... ticks
//     after the trigger). In the cycle after the trigger itself the half ends iff H = 1
//     (h1_i). No per-element counter, no copy of H.
//   - cyc_q counts the periods left including the current one: running = cyc_q != 0. It is
//     loaded from p_cyc_q one edge after the trigger (trig_q), so no mux on the fire inputs;
//     in that cycle the run test comes from p_cyc_q instead.
module ms_tx_channel #(
  parameter int DELAY_W = 16,
  parameter int HALF_W  = 16,
  parameter int CYC_W   = 8
) (
  input  logic               clk_i,
  input  logic               rst_i,
  input  logic [DELAY_W-1:0] now_i,           // shared free-running tick counter
  input  logic [DELAY_W-1:0] now_nx_i,        // now_i + 1, registered
  input  logic [HALF_W-1:0]  phase_i,         // shared phase, counts modulo the half period
  input  logic [HALF_W-1:0]  phase_nx_i,      // phase_i of the next cycle
  input  logic               h1_i,            // the half period is 1
  input  logic               fire_i,          // fire strobe for this element (fire & mask)
  input  logic [DELAY_W-1:0] delay_i,         // ticks from fire to trigger
  input  logic [CYC_W-1:0]   burst_cycles_i,  // periods per burst, 0 = no drive
  output logic               drive_o,         // registered transducer drive
  output logic               busy_o,          // pending trigger or running burst
  output logic               override_o       // this fire replaced a pending trigger
);
  // pending trigger (from fire to trigger tick) and the burst length of the last fire
  logic [DELAY_W-1:0] tgt_q;      // tick of the pending trigger (mod 2^DELAY_W)
  logic               pend_q;     // a trigger is pending (due in this cycle or later)
  logic               due_q;      // the pending trigger is due in this cycle
  logic [CYC_W-1:0]   p_cyc_q;
  // running burst; trig_q: trigger at the last edge, load cyc_q now
  logic               drive_q, trig_q;
  logic [HALF_W-1:0]  phi_q;      // phase_i in the cycle after the trigger: a half ends when it comes round
  logic [CYC_W-1:0]   cyc_q;      // periods left including the current one

  // trig: trigger at this edge; trig_on: it starts a burst (cycles != 0); half_end: the
  // current half ends at this edge; run: a burst is running
  logic              trig, trig_on, half_end, run;

  assign trig     = fire_i ? (delay_i == '0) : due_q;
  assign trig_on  = fire_i ? (burst_cycles_i != '0) : (p_cyc_q != '0);
  // cyc_q is stale in the cycle after a trigger: p_cyc_q still holds that burst's count
  assign run      = trig_q ? (p_cyc_q != '0) : (cyc_q != '0);
  assign half_end = trig_q ? h1_i : (phase_nx_i == phi_q);

  // trigger tick and the latched burst length. A fire replaces a pending trigger, also one
  // due in its own cycle (trig then comes from the fire: due_q is ignored).
  always_ff @(posedge clk_i) begin
    if (fire_i) begin
      tgt_q <= now_i + delay_i;
    end
    if (trig_q) begin
      phi_q <= phase_i;
    end
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      pend_q  <= 1'b0;
      due_q   <= 1'b0;
      p_cyc_q <= '0;
    end else if (fire_i) begin
      pend_q  <= (delay_i != '0);
      due_q   <= (delay_i == DELAY_W'(1));
      p_cyc_q <= burst_cycles_i;
    end else begin
      pend_q <= pend_q & ~due_q;
      due_q  <= pend_q & ~due_q & (tgt_q == now_nx_i);
    end
  end

  // drive: set by a trigger, toggled at the end of each half while periods remain
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      drive_q <= 1'b0;
    end else if (trig) begin
      drive_q <= trig_on;
    end else if (half_end) begin
      if (drive_q) begin
        drive_q <= 1'b0;
      end else if (run) begin
        drive_q <= (cyc_q[CYC_W-1:1] != '0);
      end
    end
  end

  // burst length, loaded one edge after the trigger; a period ends with its low half
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      trig_q <= 1'b0;
      cyc_q  <= '0;
    end else begin
      trig_q <= trig;
      if (trig_q) begin
        cyc_q <= p_cyc_q;
      end else if (half_end && !drive_q && run) begin
        cyc_q <= cyc_q - CYC_W'(1);
      end
    end
  end

  assign drive_o    = drive_q;
  assign busy_o     = pend_q | run;
  assign override_o = fire_i & pend_q;
endmodule
