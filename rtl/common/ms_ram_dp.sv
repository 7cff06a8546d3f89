// ms_ram_dp: block RAM with one read/write port (A) and one read-only port (B).
//
// Timing contract: both ports are synchronous. Port A writes wdata_a_i at addr_a_i on a
// clock edge where we_a_i is high; rdata_a_o / rdata_b_o show the word at the address
// presented on the previous edge (one clock of read latency, read-before-write on port A).
// B_WRITE_FIRST = 1: a port B read of the word port A writes at the same edge returns the
// new data. With both read ports in use, that lets Yosys map the memory to one ECP5 DP16KD
// (a read-first port B made it keep a copy per read port, two DP16KD); the bypass costs a
// comparator and a multiplexer.
// Written in the plain style Yosys maps to ECP5 DP16KD.
module ms_ram_dp #(
  parameter int WIDTH         = 32,
  parameter int DEPTH         = 256,
  parameter int AW            = $clog2(DEPTH),
  parameter bit B_WRITE_FIRST = 1'b0
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
    if (B_WRITE_FIRST && we_a_i && addr_a_i == addr_b_i) rdata_b_o <= wdata_a_i;
    else                                                  rdata_b_o <= mem_q[addr_b_i];
  end
endmodule
