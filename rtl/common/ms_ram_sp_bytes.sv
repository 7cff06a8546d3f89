// ms_ram_sp_bytes: single-port 32-bit RAM with byte write enables, optionally preloaded.
//
// Timing contract: synchronous; rdata_o shows the word at addr_i of the previous clock
// (read-before-write). INIT_FILE (hex words for $readmemh, one per line) preloads it: the
// firmware image in simulation and in the FPGA bitstream.
module ms_ram_sp_bytes #(
  parameter int    WORDS     = 8192,
  parameter int    AW        = $clog2(WORDS),
  parameter string INIT_FILE = ""
) (
  input  logic          clk_i,
  input  logic [AW-1:0] addr_i,
  input  logic [3:0]    we_i,
  input  logic [31:0]   wdata_i,
  output logic [31:0]   rdata_o
);
  logic [31:0] mem_q [WORDS];

  initial begin
    if (INIT_FILE != "") $readmemh(INIT_FILE, mem_q);
  end

  always_ff @(posedge clk_i) begin
    for (int b = 0; b < 4; b++) begin
      if (we_i[b]) mem_q[addr_i][8*b +: 8] <= wdata_i[8*b +: 8];
    end
    rdata_o <= mem_q[addr_i];
  end
endmodule
