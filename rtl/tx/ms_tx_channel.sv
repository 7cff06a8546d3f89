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
module ms_tx_channel #(
  parameter int DELAY_W = 16,
  parameter int HALF_W  = 16,
  parameter int CYC_W   = 8
) (
  input  logic               clk_i,
  input  logic               rst_i,
  input  logic               fire_i,          // fire strobe for this element (fire & mask)
  input  logic [DELAY_W-1:0] delay_i,         // ticks from fire to trigger
  input  logic [CYC_W-1:0]   burst_cycles_i,  // periods per burst, 0 = no drive
  input  logic [HALF_W-1:0]  half_period_i,   // ticks per half period, 0 behaves as 1
  output logic               drive_o,         // registered transducer drive
  output logic               busy_o,          // pending trigger or running burst
  output logic               override_o       // this fire replaced a pending trigger
);
  localparam int HALVES_W = CYC_W + 1;

  // pending trigger (from fire to trigger tick) and its latched burst parameters
  logic               pend_q;
  logic [DELAY_W-1:0] dcnt_q;     // ticks left until the trigger, minus one
  logic [HALF_W-1:0]  p_hm1_q;    // half period - 1
  logic [CYC_W-1:0]   p_cyc_q;
  // running burst
  logic               run_q, drive_q;
  logic [HALF_W-1:0]  hcnt_q;     // ticks left in the current half, minus one
  logic [HALF_W-1:0]  a_hm1_q;    // half period - 1 of the running burst
  logic [HALVES_W-1:0] halves_q;  // halves still to come after the current one

  logic [HALF_W-1:0]  in_hm1;
  logic               trig;       // trigger at this edge
  logic [HALF_W-1:0]  trig_hm1;
  logic [CYC_W-1:0]   trig_cyc;

  assign in_hm1 = (half_period_i == '0) ? '0 : half_period_i - HALF_W'(1);

  always_comb begin
    if (fire_i) begin
      trig     = (delay_i == '0);
      trig_hm1 = in_hm1;
      trig_cyc = burst_cycles_i;
    end else begin
      trig     = pend_q && (dcnt_q == '0);
      trig_hm1 = p_hm1_q;
      trig_cyc = p_cyc_q;
    end
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      pend_q   <= 1'b0;
      dcnt_q   <= '0;
      p_hm1_q  <= '0;
      p_cyc_q  <= '0;
      run_q    <= 1'b0;
      drive_q  <= 1'b0;
      hcnt_q   <= '0;
      a_hm1_q  <= '0;
      halves_q <= '0;
    end else begin
      // delay counter
      if (fire_i) begin
        pend_q  <= (delay_i != '0);
        dcnt_q  <= delay_i - DELAY_W'(1);
        p_hm1_q <= in_hm1;
        p_cyc_q <= burst_cycles_i;
      end else if (pend_q) begin
        pend_q <= (dcnt_q != '0);
        dcnt_q <= dcnt_q - DELAY_W'(1);
      end
      // burst generator
      if (trig) begin
        run_q    <= (trig_cyc != '0);
        drive_q  <= (trig_cyc != '0);
        hcnt_q   <= trig_hm1;
        a_hm1_q  <= trig_hm1;
        halves_q <= {trig_cyc, 1'b0} - HALVES_W'(1);
      end else if (run_q) begin
        if (hcnt_q != '0) begin
          hcnt_q <= hcnt_q - HALF_W'(1);
        end else if (halves_q == '0) begin
          run_q   <= 1'b0;
          drive_q <= 1'b0;
        end else begin
          hcnt_q   <= a_hm1_q;
          halves_q <= halves_q - HALVES_W'(1);
          drive_q  <= ~drive_q;
        end
      end
    end
  end

  assign drive_o    = drive_q;
  assign busy_o     = pend_q | run_q;
  assign override_o = fire_i & pend_q;
endmodule
