// ms_system: the board-independent Multisonar system — the soft-core SoC (ms_soc) with the
// complete sonar core (ms_sonar_core) on its sonar register port (CPU address 0x1000_0000).
//
// Timing contract: one clock (48 MHz), synchronous active-high reset rst_i (the board top
// synchronises it). echo_i is asynchronous (the receive conditioners synchronise it);
// drive_o is registered in the sonar core. Host link (ms_soc, rtl/link/ms_link.sv): cmd_* are
// the USB bulk OUT endpoint's entries (ms_usb_device out_*: first-word-fall-through, taken on
// a clock with cmd_ready_o), host_* the bulk IN byte stream (host_rdata_o valid while
// host_rvalid_o, taken on a clock with host_rd_i = in_ready; host_flush_o one clock at the end
// of each packet = in_flush).
//
// USB: ms_system_usb (rtl/link/ms_system_usb.sv) wraps this module with the USB device core;
// ms_system itself has no USB logic, so tests can read the link's byte stream directly.
//
// Status for LEDs: every led_o bit is a level or a pulse stretched to at least
// 2^STRETCH_W clocks (2^22 clocks = 87 ms at 48 MHz) so a one-clock event is visible:
//   led_o[0] heartbeat: toggles every 2^(STRETCH_W+2) clocks (the clock and reset are alive)
//   led_o[1] CPU running: no trap (PicoRV32 halts on an illegal instruction or bus fault)
//   led_o[2] trap (level)
//   led_o[3] bus error seen by the CPU (stretched pulse)
//   led_o[4] a transducer drive is active (stretched, any element)
//   led_o[5] an event waits in the sonar event FIFO
//   led_o[6] a byte waits for the bulk IN endpoint (the host has not read it yet)
//   led_o[7] the firmware wrote the SIM_OUT mailbox (stretched pulse)
// The watchdog reset of the CPU and the scheduler's "running" flag are not visible here:
// ms_soc and ms_sonar_core do not export them (see docs/synthesis.md).
module ms_system #(
  parameter int    NUM_CH    = 24,
  parameter int    RAM_WORDS = 16384,  // SoC RAM, 32-bit words (firmware image + data + stack)
  parameter string INIT_FILE = "",     // firmware image, hex words for $readmemh
  parameter int    STRETCH_W = 22,     // LED pulse stretch: 2^STRETCH_W clocks
  parameter string CPU       = "vexriscv",  // soft-core: "vexriscv" or "picorv32" (ms_soc)
  parameter int    FAST_MUL  = 1,      // PicoRV32 only: single-cycle DSP multiplier (ms_soc)
  parameter int    NUM_VS    = 8,      // scheduler: virtual sensors run (ms_sonar_core, CAPS.num_vs)
  parameter int    WSLOTS    = 16      // scheduler: window slots per element (CAPS.win_slots)
) (
  input  logic              clk_i,
  input  logic              rst_i,
  // transducers
  input  logic [NUM_CH-1:0] echo_i,   // comparator outputs, asynchronous
  output logic [NUM_CH-1:0] drive_o,  // burst drive, registered
  // host link (to the USB device core's bulk endpoints)
  input  logic              cmd_valid_i,
  input  logic [7:0]        cmd_data_i,
  input  logic              cmd_end_i,
  input  logic              cmd_zlp_i,
  output logic              cmd_ready_o,
  input  logic              host_rd_i,
  output logic              host_rvalid_o,
  output logic [7:0]        host_rdata_o,
  output logic              host_flush_o,
  // observation: mailbox (simulation and debugging), raw status, LEDs
  output logic              sim_out_strobe_o,
  output logic [31:0]       sim_out_o,
  output logic              trap_o,
  output logic              bus_err_o,
  output logic              evt_available_o,
  output logic [7:0]        led_o
);
  localparam int SONAR_AW = 11;

  logic                req, req_is_wr, stall_wr, stall_rd, rd_ack, rd_err, wr_ack, wr_err;
  logic [SONAR_AW-1:0] addr;
  logic [31:0]         wr_data, wr_biten, rd_data;
  logic                rst_soc, rst_sonar;

  ms_reset_copy u_rst_soc (.clk_i, .rst_i, .rst_o (rst_soc));
  ms_reset_copy u_rst_sonar (.clk_i, .rst_i, .rst_o (rst_sonar));

  ms_soc #(.RAM_WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE), .SONAR_AW(SONAR_AW), .CPU(CPU),
           .FAST_MUL(FAST_MUL)) u_soc (
    .clk_i, .rst_i (rst_soc),
    .sonar_req_o (req), .sonar_req_is_wr_o (req_is_wr), .sonar_addr_o (addr),
    .sonar_wr_data_o (wr_data), .sonar_wr_biten_o (wr_biten),
    .sonar_req_stall_wr_i (stall_wr), .sonar_req_stall_rd_i (stall_rd),
    .sonar_rd_ack_i (rd_ack), .sonar_rd_err_i (rd_err), .sonar_rd_data_i (rd_data),
    .sonar_wr_ack_i (wr_ack), .sonar_wr_err_i (wr_err), .wake_evt_i (evt_available_o),
    .cmd_valid_i, .cmd_data_i, .cmd_end_i, .cmd_zlp_i, .cmd_ready_o,
    .host_rd_i, .host_rvalid_o, .host_rdata_o, .host_flush_o,
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o
  );

`ifdef MS_TWIN_SONAR_GATE
  // Simulation only (the full-system twin, sim/twin; mk/twin.mk defines it): the sonar core is
  // clocked by a variable the harness drives, held while the core is calm (its state then
  // changes only in counters that run with time) and the SoC does not address it; to bring it
  // up to date the harness advances those counters and clocks it alone for the last few held
  // clocks with the SoC's outputs of those clocks (twin_replay, twin_r_*: its register block
  // latches the bus lines in every clock; docs/twin.md). Never defined for synthesis, lint or
  // the RTL tests.
  logic                twin_sonar_clk, twin_replay;
  logic                twin_r_rst, twin_r_req, twin_r_is_wr;
  logic [SONAR_AW-1:0] twin_r_addr;
  logic [31:0]         twin_r_wdata, twin_r_biten;
  logic                s_rst, s_req, s_is_wr;
  logic [SONAR_AW-1:0] s_addr;
  logic [31:0]         s_wdata, s_biten;
  assign s_rst   = twin_replay ? twin_r_rst : rst_sonar;
  assign s_req   = twin_replay ? twin_r_req : req;
  assign s_is_wr = twin_replay ? twin_r_is_wr : req_is_wr;
  assign s_addr  = twin_replay ? twin_r_addr : addr;
  assign s_wdata = twin_replay ? twin_r_wdata : wr_data;
  assign s_biten = twin_replay ? twin_r_biten : wr_biten;
  ms_sonar_core #(.NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .WSLOTS(WSLOTS)) u_sonar (
    .clk_i (twin_sonar_clk), .rst_i (s_rst),
    .bus_req_i (s_req), .bus_req_is_wr_i (s_is_wr), .bus_addr_i (s_addr),
    .bus_wr_data_i (s_wdata), .bus_wr_biten_i (s_biten),
`else
  ms_sonar_core #(.NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .WSLOTS(WSLOTS)) u_sonar (
    .clk_i, .rst_i (rst_sonar),
    .bus_req_i (req), .bus_req_is_wr_i (req_is_wr), .bus_addr_i (addr),
    .bus_wr_data_i (wr_data), .bus_wr_biten_i (wr_biten),
`endif
    .bus_req_stall_wr_o (stall_wr), .bus_req_stall_rd_o (stall_rd),
    .bus_rd_ack_o (rd_ack), .bus_rd_err_o (rd_err), .bus_rd_data_o (rd_data),
    .bus_wr_ack_o (wr_ack), .bus_wr_err_o (wr_err),
    .echo_i, .drive_o, .evt_available_o
  );

  // ---- LEDs: stretch one-clock events so they can be seen
  logic [STRETCH_W+2:0] beat_q;
  logic [STRETCH_W-1:0] bus_err_cnt_q, drive_cnt_q, mbox_cnt_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      beat_q        <= '0;
      bus_err_cnt_q <= '0;
      drive_cnt_q   <= '0;
      mbox_cnt_q    <= '0;
    end else begin
      beat_q <= beat_q + 1'b1;
      if (bus_err_o)                bus_err_cnt_q <= '1;
      else if (bus_err_cnt_q != '0) bus_err_cnt_q <= bus_err_cnt_q - 1'b1;
      if (|drive_o)                 drive_cnt_q <= '1;
      else if (drive_cnt_q != '0)   drive_cnt_q <= drive_cnt_q - 1'b1;
      if (sim_out_strobe_o)         mbox_cnt_q <= '1;
      else if (mbox_cnt_q != '0)    mbox_cnt_q <= mbox_cnt_q - 1'b1;
    end
  end

  assign led_o = {mbox_cnt_q != '0, host_rvalid_o, evt_available_o, drive_cnt_q != '0,
                  bus_err_cnt_q != '0, trap_o, ~trap_o, beat_q[STRETCH_W+2]};
endmodule
