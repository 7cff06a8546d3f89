// Testbench top for the geometry firmware on the SoC (tests/rtl/test_ms_soc_geometry.py,
// scripts/bench_fw_cycles.py): ms_soc with default parameters (RAM_WORDS) and no sonar core
// (that firmware never touches it: a sonar access is acknowledged at once with an error, which
// raises bus_err_o and fails the test). Its own top name gives it its own Verilator build
// (build/sim/ms_soc_geometry_tb-verilator), so it never evicts the self-test's build.
// INIT_FILE is one fixed path in that build folder; the runner copies the image for each run
// there, so switching between the f64 / f32 / q images needs no rebuild.
module ms_soc_geometry_tb #(
  parameter int    CLK_HALF_PS = 10417,  // tests/rtl/tbutil.py CLK_PERIOD_PS / 2
  parameter string INIT_FILE = "",
  parameter string CPU       = "picorv32"
) (
  input  logic        rst_i,
  input  logic        host_rd_i,
  output logic        host_rvalid_o,
  output logic [7:0]  host_rdata_o,
  output logic        host_flush_o,
  output logic        sim_out_strobe_o,
  output logic [31:0] sim_out_o,
  output logic        trap_o,
  output logic        bus_err_o
);
  // the clock is made here (Verilator --timing, tests/rtl/cocotb_run.py OWN_CLOCK_TOPS): no VPI
  // call per edge; the bench writes its inputs at falling edges
  logic clk_i = 1'b0;
  always #(CLK_HALF_PS * 1ps) clk_i = ~clk_i;

  logic        req, req_is_wr;
  logic [10:0] addr;
  logic [31:0] wr_data, wr_biten;

  ms_soc #(.INIT_FILE(INIT_FILE), .CPU(CPU)) u_soc (
    .clk_i, .rst_i,
    .sonar_req_o (req), .sonar_req_is_wr_o (req_is_wr), .sonar_addr_o (addr),
    .sonar_wr_data_o (wr_data), .sonar_wr_biten_o (wr_biten),
    .sonar_req_stall_wr_i (1'b0), .sonar_req_stall_rd_i (1'b0),
    .sonar_rd_ack_i (req & ~req_is_wr), .sonar_rd_err_i (1'b1), .sonar_rd_data_i (32'd0),
    .sonar_wr_ack_i (req & req_is_wr), .sonar_wr_err_i (1'b1), .wake_evt_i (1'b0),
    .cmd_valid_i (1'b0), .cmd_data_i (8'd0), .cmd_end_i (1'b0), .cmd_zlp_i (1'b0), .cmd_ready_o (),
    .host_rd_i, .host_rvalid_o, .host_rdata_o, .host_flush_o,
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o
  );
endmodule
