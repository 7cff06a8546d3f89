// ms_reset_sync: reset for the system clock domain from an asynchronous source.
//
// Timing contract: rst_o rises asynchronously as soon as arst_i is high (button pressed or
// PLL not locked) and falls synchronously STAGES clocks after arst_i has fallen, so every
// flop of the design leaves reset in the same clock.
module ms_reset_sync #(
  parameter int STAGES = 3
) (
  input  logic clk_i,
  input  logic arst_i,
  output logic rst_o
);
  logic [STAGES-1:0] sync_q;
  always_ff @(posedge clk_i or posedge arst_i) begin
    if (arst_i) sync_q <= '1;
    else        sync_q <= {sync_q[STAGES-2:0], 1'b0};
  end
  assign rst_o = sync_q[STAGES-1];
endmodule
