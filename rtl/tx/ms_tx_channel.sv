// ms_tx_channel: delay counter and burst generator of one transmit element (one instance
// per element inside ms_tx_phaser, which states the contract for the whole array).
//
// Timing contract (ticks of clk_i; "at tick T" = loaded at the edge that ends cycle T):
//   - fire_i high in cycle t0 (already masked for this element) triggers the element at
//     tick t = t0 + delay_i. delay_i = 0 triggers in t0 itself (no extra latency).
//   - A trigger at tick t with latched (cycles B, half period H) sets drive_o high from
//     cycle t+1: B periods of 2*H ticks, high first (H high, H low), then low. H = 0 is
//     taken as 1. B = 0 drives nothing and ends a running burst at t.
//   - burst_cycles_i and half_period_i are latched with fire_i; later changes of the
//     inputs affect neither the pending trigger nor the running burst.
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
//   - The burst parameters of the pending trigger (p_*_q) stay untouched until the next
//     fire, whose earliest write is the edge ending t+1. So the trigger edge t only sets
//     drive_q and clears the half counter; the running burst's copies (a_half_q, cyc_q)
//     are loaded from p_*_q one edge later (trig_q), without a mux on the fire inputs.
//     In cycle t+1 the end-of-half test and run come from p_half_q / p_cyc_q instead.
//   - The fire inputs go straight into flops (no logic before the latch, apart from the
//     shared adder): the phaser's channels sit by their pins, across the chip from the
//     register block, so any gate on half_period_i would be shared by all channels (Yosys
//     merges it) and add a second chip-long net to the path. H = 0 -> 1 is applied to the
//     latched copy.
//   - The half counter counts up from 1 and is cleared (flop sync reset) at the end of each
//     half, found by comparing with a_half_q; one edge after a trigger it is loaded with 2.
//   - cyc_q counts the periods left including the current one: running = cyc_q != 0.
module ms_tx_channel #(
  parameter int DELAY_W = 16,
  parameter int HALF_W  = 16,
  parameter int CYC_W   = 8
) (
  input  logic               clk_i,
  input  logic               rst_i,
  input  logic [DELAY_W-1:0] now_i,           // shared free-running tick counter
  input  logic [DELAY_W-1:0] now_nx_i,        // now_i + 1, registered
  input  logic               fire_i,          // fire strobe for this element (fire & mask)
  input  logic [DELAY_W-1:0] delay_i,         // ticks from fire to trigger
  input  logic [CYC_W-1:0]   burst_cycles_i,  // periods per burst, 0 = no drive
  input  logic [HALF_W-1:0]  half_period_i,   // ticks per half period, 0 behaves as 1
  output logic               drive_o,         // registered transducer drive
  output logic               busy_o,          // pending trigger or running burst
  output logic               override_o       // this fire replaced a pending trigger
);
  // pending trigger (from fire to trigger tick) and the burst parameters of the last fire
  logic [DELAY_W-1:0] tgt_q;      // tick of the pending trigger (mod 2^DELAY_W)
  logic               pend_q;     // a trigger is pending (due in this cycle or later)
  logic               due_q;      // the pending trigger is due in this cycle
  logic [HALF_W-1:0]  p_half_q;   // half period as given (0 behaves as 1)
  logic [CYC_W-1:0]   p_cyc_q;
  logic               p_h1;       // p_half_q is 0 or 1: the first half ends after one tick
  logic [HALF_W-1:0]  p_half;     // p_half_q with 0 taken as 1
  // running burst; trig_q: trigger at the last edge, load a_half_q and cyc_q now
  logic               drive_q, trig_q;
  logic [HALF_W-1:0]  hcnt_q;     // tick within the current half, 1..H
  logic [HALF_W-1:0]  a_half_q;   // half period of the running burst
  logic [CYC_W-1:0]   cyc_q;      // periods left including the current one

  // trig: trigger at this edge; trig_on: it starts a burst (cycles != 0); half_end: the
  // current half ends at this edge; run: a burst is running
  logic              trig, trig_on, half_end, run;

  assign p_h1     = (p_half_q[HALF_W-1:1] == '0);
  assign p_half   = {p_half_q[HALF_W-1:1], p_half_q[0] | p_h1};
  assign trig     = fire_i ? (delay_i == '0) : due_q;
  assign trig_on  = fire_i ? (burst_cycles_i != '0) : (p_cyc_q != '0);
  // cyc_q is stale in the cycle after a trigger: p_cyc_q still holds that burst's count
  assign run      = trig_q ? (p_cyc_q != '0) : (cyc_q != '0);
  assign half_end = trig_q ? p_h1 : (hcnt_q == a_half_q);

  // trigger tick and the latched parameters. A fire replaces a pending trigger, also one
  // due in its own cycle (trig then comes from the fire: due_q is ignored).
  always_ff @(posedge clk_i) begin
    if (fire_i) begin
      tgt_q <= now_i + delay_i;
    end
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      pend_q   <= 1'b0;
      due_q    <= 1'b0;
      p_half_q <= '0;
      p_cyc_q  <= '0;
    end else if (fire_i) begin
      pend_q   <= (delay_i != '0);
      due_q    <= (delay_i == DELAY_W'(1));
      p_half_q <= half_period_i;
      p_cyc_q  <= burst_cycles_i;
    end else begin
      pend_q <= pend_q & ~due_q;
      due_q  <= pend_q & ~due_q & (tgt_q == now_nx_i);
    end
  end

  // half counter: runs freely when idle (its half_end pulses then change nothing). It restarts
  // one edge after a trigger, not at it: in the cycle after a trigger half_end comes from
  // p_h1, not from hcnt_q, so the edge ending that cycle loads what the count would be by
  // then (2, or 1 when the first half ends there). trig stays out of the 16 sync resets: it
  // comes from the scheduler's delay across the chip (the phaser's slowest path at 62.4 MHz).
  always_ff @(posedge clk_i) begin
    if (rst_i || half_end) begin
      hcnt_q <= HALF_W'(1);
    end else if (trig_q) begin
      hcnt_q <= HALF_W'(2);
    end else begin
      hcnt_q <= hcnt_q + HALF_W'(1);
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

  // burst copies, loaded one edge after the trigger; a period ends with its low half
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      trig_q   <= 1'b0;
      a_half_q <= '0;
      cyc_q    <= '0;
    end else begin
      trig_q <= trig;
      if (trig_q) begin
        a_half_q <= p_half;
        cyc_q    <= p_cyc_q;
      end else if (half_end && !drive_q && run) begin
        cyc_q <= cyc_q - CYC_W'(1);
      end
    end
  end

  assign drive_o    = drive_q;
  assign busy_o     = pend_q | run;
  assign override_o = fire_i & pend_q;
endmodule
