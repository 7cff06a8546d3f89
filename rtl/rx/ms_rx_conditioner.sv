// ms_rx_conditioner: front end of one receive channel. Synchronises the asynchronous
// comparator output, rejects glitches and marks the rising edge of each accepted pulse.
//
// Timing contract (ticks of clk_i, checked against a Python model in
// tests/rtl/test_ms_rx_conditioner.py):
//   - echo_i is sampled on every rising clock edge; sample n is the value at edge n.
//   - Two flops synchronise it: sample n reaches the filter at edge n+2 (sync_q).
//   - The filtered level follows sync_q only after sync_q has differed from it for
//     max(glitch_min_i, 1) consecutive clocks; shorter pulses and gaps are ignored.
//   - rise_o is high for exactly one clock when the filtered level goes high: for a pulse
//     first sampled high at edge n, rise_o is high after edge n + 1 + max(glitch_min_i, 1).
//     Consumers subtract 1 + max(glitch_min_i, 1) from their timestamp to recover n.
//   - A pulse is accepted if and only if it spans at least max(glitch_min_i, 1) samples.
//   - glitch_min_i is the value in the last clock before sync_q departed from the level (in
//     reset, or while they agree): a change takes effect from the next pulse or gap.
module ms_rx_conditioner #(
  parameter int CNT_W = 8
) (
  input  logic             clk_i,
  input  logic             rst_i,
  input  logic             echo_i,        // asynchronous comparator output
  input  logic [CNT_W-1:0] glitch_min_i,  // shortest accepted pulse/gap, clocks (0 behaves as 1)
  output logic             level_o,       // filtered comparator level
  output logic             rise_o         // one-clock strobe: filtered level went high
);
  logic             meta_q, sync_q;
  logic             level_q, rise_q;
  logic [CNT_W-1:0] run_q;  // consecutive clocks sync_q has differed from level_q, minus one
  // max(glitch_min_i, 1) - 1 as of the last clock the level was settled: a change takes effect
  // for the next pulse, never half-way through one. run_q counts up by one from 0, so the
  // first clock with run_q + 1 >= max(g, 1) is the one with run_q == max(g, 1) - 1: an
  // equality test (LUTs) instead of a magnitude compare (a second carry chain per channel,
  // which nextpnr also pads with feed-in / feed-out cells). The subtraction depends on
  // glitch_min_i only, so after flattening the 24 conditioners share one.
  logic [CNT_W-1:0] gm1_q;

  always_ff @(posedge clk_i) begin
    if (rst_i || sync_q == level_q) gm1_q <= glitch_min_i - CNT_W'(glitch_min_i != '0);
    if (rst_i) begin
      meta_q  <= 1'b0;
      sync_q  <= 1'b0;
      level_q <= 1'b0;
      rise_q  <= 1'b0;
      run_q   <= '0;
    end else begin
      meta_q <= echo_i;
      sync_q <= meta_q;
      rise_q <= 1'b0;
      if (sync_q == level_q) begin
        run_q <= '0;
      end else if (run_q == gm1_q) begin
        level_q <= sync_q;
        rise_q  <= sync_q;
        run_q   <= '0;
      end else begin
        run_q <= run_q + CNT_W'(1);
      end
    end
  end

  assign level_o = level_q;
  assign rise_o  = rise_q;
endmodule
