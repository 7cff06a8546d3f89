// ms_reset_copy: a registered copy of the synchronous reset for one block.
//
// Timing contract: rst_o = rst_i one clock later (the block leaves reset one clock after its
// parent). Why: one reset flop driving every block of the chip is a net the placer cannot put
// near all its loads; on the 45F its route alone took 16.6 ns of a 20.8 ns period into the
// host link's clock enables. Each copy sits near its block. Yosys would merge the copies (the
// same input, the same function): mk/synth.mk marks every rst_copy_q keep.
module ms_reset_copy (
  input  logic clk_i,
  input  logic rst_i,
  output logic rst_o
);
  logic rst_copy_q;
  always_ff @(posedge clk_i) rst_copy_q <= rst_i;
  assign rst_o = rst_copy_q;
endmodule
