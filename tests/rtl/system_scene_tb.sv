// Testbench top for the whole-system scene test (tests/rtl/test_system_scene.py): ms_system
// running the sonar firmware (firmware/app/sonar). A thin wrapper only so that this test
// has its own Verilator build (build/sim/system_scene_tb-verilator) and never rebuilds the
// smoke test's ms_system (the firmware image is a build-time parameter). Short LED stretch.
// The clock clk_i is made here (Verilator --timing, tests/rtl/cocotb_run.py OWN_CLOCK_TOPS): no
// VPI call per edge. The bench writes its inputs at falling edges or a quarter clock into a cycle.
module system_scene_tb #(
  parameter int    CLK_HALF_PS = 10417,  // tests/rtl/tbutil.py CLK_PERIOD_PS / 2
  parameter string INIT_FILE = ""
) (
  input  logic        rst_i,
  input  logic [23:0] echo_i,
  output logic [23:0] drive_o,
  input  logic        cmd_valid_i,
  input  logic [7:0]  cmd_data_i,
  input  logic        cmd_end_i,
  input  logic        cmd_zlp_i,
  output logic        cmd_ready_o,
  input  logic        host_rd_i,
  output logic        host_rvalid_o,
  output logic [7:0]  host_rdata_o,
  output logic        host_flush_o,
  output logic        sim_out_strobe_o,
  output logic [31:0] sim_out_o,
  output logic        trap_o,
  output logic        bus_err_o,
  output logic        evt_available_o
);
  logic clk_i = 1'b0;
  always #(CLK_HALF_PS * 1ps) clk_i = ~clk_i;

  logic [7:0] led;
  ms_system #(.NUM_CH(24), .INIT_FILE(INIT_FILE), .STRETCH_W(4)) u_sys (
    .clk_i, .rst_i, .echo_i, .drive_o, .cmd_valid_i, .cmd_data_i, .cmd_end_i, .cmd_zlp_i, .cmd_ready_o,
    .host_rd_i, .host_rvalid_o, .host_rdata_o, .host_flush_o,
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o, .evt_available_o, .led_o (led)
  );
endmodule
