// Testbench top for the SoC: ms_soc with the sonar core's register block (ms_csr) on its
// sonar port, so firmware reads the real generated registers. No commands (cmd_* tied off);
// host_* is the link's bulk IN byte stream (tests/rtl/link_reader.py); wake_evt_i stands for
// the sonar core's "an event waits" (it ends a WAIT read).
module ms_soc_tb #(
  parameter int    CLK_HALF_PS = 10417,  // tests/rtl/tbutil.py CLK_PERIOD_PS / 2
  parameter string INIT_FILE = "",
  parameter string CPU       = "picorv32"
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
  // the clock is made here (Verilator --timing, tests/rtl/cocotb_run.py OWN_CLOCK_TOPS): no VPI
  // call per edge; the bench writes its inputs at falling edges
  logic clk_i = 1'b0;
  always #(CLK_HALF_PS * 1ps) clk_i = ~clk_i;

  /* verilator lint_off PINCONNECTEMPTY */
  logic        req, req_is_wr, stall_wr, stall_rd, rd_ack, rd_err, wr_ack, wr_err;
  logic [10:0] addr;
  logic [31:0] wr_data, wr_biten, rd_data;

  ms_soc #(.INIT_FILE(INIT_FILE), .CPU(CPU)) u_soc (
    .clk_i, .rst_i,
    .sonar_req_o (req), .sonar_req_is_wr_o (req_is_wr), .sonar_addr_o (addr),
    .sonar_wr_data_o (wr_data), .sonar_wr_biten_o (wr_biten),
    .sonar_req_stall_wr_i (stall_wr), .sonar_req_stall_rd_i (stall_rd),
    .sonar_rd_ack_i (rd_ack), .sonar_rd_err_i (rd_err), .sonar_rd_data_i (rd_data),
    .sonar_wr_ack_i (wr_ack), .sonar_wr_err_i (wr_err), .wake_evt_i,
    .cmd_valid_i (1'b0), .cmd_data_i (8'd0), .cmd_end_i (1'b0), .cmd_zlp_i (1'b0), .cmd_ready_o (),
    .host_rd_i, .host_rvalid_o, .host_rdata_o, .host_flush_o,
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o
  );

  ms_csr u_csr (
    .clk_i, .rst_i,
    .bus_req_i (req), .bus_req_is_wr_i (req_is_wr), .bus_addr_i (addr),
    .bus_wr_data_i (wr_data), .bus_wr_biten_i (wr_biten),
    .bus_req_stall_wr_o (stall_wr), .bus_req_stall_rd_o (stall_rd),
    .bus_rd_ack_o (rd_ack), .bus_rd_err_o (rd_err), .bus_rd_data_o (rd_data),
    .bus_wr_ack_o (wr_ack), .bus_wr_err_o (wr_err),
    .enable_o (), .hold_o (), .start_o (), .clear_counters_o (), .burst_half_period_o (),
    .burst_cycles_o (), .glitch_min_o (), .ld_we_o (), .ld_addr_o (), .ld_data_o (),
    .evt_rvalid_i (1'b0), .evt_rdata_i (64'd0), .evt_pop_o (),
    .running_i (1'b0), .sched_overrun_i (1'b0), .tx_collision_i (1'b0), .fifo_level_i (12'd0),
    .event_i (1'b0), .overflow_i (1'b0), .pulse_i (1'b0)
  );
  /* verilator lint_on PINCONNECTEMPTY */
endmodule
