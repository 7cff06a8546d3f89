// ms_sonar_core_tb: ms_sonar_core with its clock made here (tests/rtl/tb_ms_sonar_core.py).
// A build with Verilator --timing (tests/rtl/cocotb_run.py OWN_CLOCK_TOPS): cocotb's GPI clock
// costs a VPI call per edge. The ports are the core's, clk_i aside; the core is u_core. The
// bench writes its inputs at falling edges (the bus master) or a quarter clock into a cycle
// (the echo driver), never at a rising edge.
module ms_sonar_core_tb #(
  parameter int          CLK_HALF_PS = 10417,  // tests/rtl/tbutil.py CLK_PERIOD_PS / 2
  parameter int          NUM_CH      = 24,
  parameter int unsigned TICK_START  = 0,
  parameter int          LEAD        = 32768,
  parameter int          EVT_DEPTH_W = 9,
  parameter int          NUM_VS      = 8,
  parameter int          WSLOTS      = 16
) (
  input  logic              rst_i,
  input  logic              bus_req_i,
  input  logic              bus_req_is_wr_i,
  input  logic [10:0]       bus_addr_i,
  input  logic [31:0]       bus_wr_data_i,
  input  logic [31:0]       bus_wr_biten_i,
  output logic              bus_req_stall_wr_o,
  output logic              bus_req_stall_rd_o,
  output logic              bus_rd_ack_o,
  output logic              bus_rd_err_o,
  output logic [31:0]       bus_rd_data_o,
  output logic              bus_wr_ack_o,
  output logic              bus_wr_err_o,
  input  logic [NUM_CH-1:0] echo_i,
  output logic [NUM_CH-1:0] drive_o,
  output logic              evt_available_o
);
  logic clk_i = 1'b0;
  always #(CLK_HALF_PS * 1ps) clk_i = ~clk_i;

  ms_sonar_core #(
    .NUM_CH(NUM_CH), .TICK_START(TICK_START), .LEAD(LEAD), .EVT_DEPTH_W(EVT_DEPTH_W),
    .NUM_VS(NUM_VS), .WSLOTS(WSLOTS)
  ) u_core (
    .clk_i, .rst_i, .bus_req_i, .bus_req_is_wr_i, .bus_addr_i, .bus_wr_data_i, .bus_wr_biten_i,
    .bus_req_stall_wr_o, .bus_req_stall_rd_o, .bus_rd_ack_o, .bus_rd_err_o, .bus_rd_data_o,
    .bus_wr_ack_o, .bus_wr_err_o, .echo_i, .drive_o, .evt_available_o
  );
endmodule
