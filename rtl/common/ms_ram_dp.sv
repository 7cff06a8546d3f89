// ms_ram_dp: block RAM with one read/write port (A) and one read-only port (B).
//
// Timing contract: both ports are synchronous. Port A writes wdata_a_i at addr_a_i on a
// clock edge where we_a_i is high; rdata_a_o / rdata_b_o show the word at the address
// presented on the previous edge (one clock of read latency, read-before-write on port A).
// Written in the plain style Yosys maps to ECP5 DP16KD / iCE40 SB_RAM40_4K.
module ms_ram_dp #(
  parameter int WIDTH = 32,
  parameter int DEPTH = 256,
  parameter int AW    = $clog2(DEPTH)
) (
  input  logic             clk_i,
  input  logic             we_a_i,
  input  logic [AW-1:0]    addr_a_i,
  input  logic [WIDTH-1:0] wdata_a_i,
  output logic [WIDTH-1:0] rdata_a_o,
  input  logic [AW-1:0]    addr_b_i,
  output logic [WIDTH-1:0] rdata_b_o
);
  logic [WIDTH-1:0] mem_q [DEPTH];

  always_ff @(posedge clk_i) begin
    if (we_a_i) mem_q[addr_a_i] <= wdata_a_i;
    rdata_a_o <= mem_q[addr_a_i];
  end

  always_ff @(posedge clk_i) begin
    rdata_b_o <= mem_q[addr_b_i];
  end
endmodule
