// Testbench top: ms_soc_tb with CPU = "vexriscv" (tests/rtl/test_ms_soc.py). A top of its
// own gives the VexRiscv build its own Verilator folder (build/sim/ms_soc_vex_tb-verilator),
// so running both CPUs never rebuilds either.
module ms_soc_vex_tb #(
  parameter string INIT_FILE = ""
) (
  input  logic        rst_i,
  input  logic        wake_evt_i,
  input  logic        host_rd_i,
  output logic        host_rvalid_o,
  output logic [7:0]  host_rdata_o,
  output logic        host_flush_o,
  output logic        sim_out_strobe_o,
  output logic [31:0] sim_out_o,
  output logic        trap_o,
  output logic        bus_err_o
);
  logic clk_i;  // ms_soc_tb's own clock, for the bench
  assign clk_i = u_tb.clk_i;

  ms_soc_tb #(.INIT_FILE(INIT_FILE), .CPU("vexriscv")) u_tb (
    .rst_i, .wake_evt_i, .host_rd_i, .host_rvalid_o, .host_rdata_o, .host_flush_o,
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o
  );
endmodule
