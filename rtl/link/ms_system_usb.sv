// ms_system_usb: the whole Multisonar device — ms_system (soft-core SoC with the host link,
// sonar core) joined to the USB 2.0 full-speed device core (ms_usb_device): bulk OUT 0x01
// feeds the link's command buffer, the link's packets go to bulk IN 0x81, one transfer each
// (docs/protocol.md, docs/usb_core.md). The board tops (rtl/board/) instantiate this.
//
// Timing contract: one clock, clk_i = 48 MHz (the USB core samples the 12 Mbit/s bus at 4x),
// synchronous active-high rst_i. usb_dp_i / usb_dn_i are asynchronous; usb_dp_o / usb_dn_o are
// driven onto the pads while usb_oe_o is high; usb_pullup_o switches the 1.5 kOhm D+ pull-up.
// tl_*: the USB core's transaction-level port for simulation (docs/usb_core.md); tie tl_en_i,
// tl_bus_reset_i and tl_rx_* to 0 on a board. Other ports as ms_system.
module ms_system_usb #(
  parameter int    NUM_CH    = 24,
  parameter int    RAM_WORDS = 16384,
  parameter string INIT_FILE = "",
  parameter int    STRETCH_W = 22,
  parameter string CPU       = "vexriscv",
  parameter int    FAST_MUL  = 1,
  parameter int    SERIAL    = 'h00000001, // USB serial number (8 hex digits)
  parameter int    NUM_VS    = 8,      // scheduler size (ms_sonar_core)
  parameter int    WSLOTS    = 16
) (
  input  logic              clk_i,
  input  logic              rst_i,
  input  logic [NUM_CH-1:0] echo_i,
  output logic [NUM_CH-1:0] drive_o,
  // USB pins
  input  logic              usb_dp_i,
  input  logic              usb_dn_i,
  output logic              usb_dp_o,
  output logic              usb_dn_o,
  output logic              usb_oe_o,
  output logic              usb_pullup_o,
  output logic              usb_configured_o,
  // USB transaction-level port (simulation)
  input  logic              tl_en_i,
  input  logic              tl_bus_reset_i,
  input  logic              tl_rx_start_i,
  input  logic              tl_rx_valid_i,
  input  logic [7:0]        tl_rx_byte_i,
  input  logic              tl_rx_end_i,
  output logic              tl_tx_valid_o,
  output logic [7:0]        tl_tx_byte_o,
  output logic              tl_tx_end_o,
  // observation
  output logic              sim_out_strobe_o,
  output logic [31:0]       sim_out_o,
  output logic              trap_o,
  output logic              bus_err_o,
  output logic              evt_available_o,
  output logic [7:0]        led_o
);
  logic       out_valid, out_end, out_zlp, out_ready, in_valid, in_ready, in_flush;
  logic       unused_bus_reset, unused_last;
  logic [7:0] out_data, in_data;
  logic       rst_sys, rst_usb;

  ms_reset_copy u_rst_sys (.clk_i, .rst_i, .rst_o (rst_sys));
  ms_reset_copy u_rst_usb (.clk_i, .rst_i, .rst_o (rst_usb));

  ms_system #(.NUM_CH(NUM_CH), .RAM_WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE), .STRETCH_W(STRETCH_W),
              .CPU(CPU), .FAST_MUL(FAST_MUL), .NUM_VS(NUM_VS), .WSLOTS(WSLOTS)) u_sys (
    .clk_i, .rst_i (rst_sys), .echo_i, .drive_o,
    .cmd_valid_i (out_valid), .cmd_data_i (out_data), .cmd_end_i (out_end), .cmd_zlp_i (out_zlp),
    .cmd_ready_o (out_ready),
    .host_rd_i (in_ready), .host_rvalid_o (in_valid), .host_rdata_o (in_data), .host_flush_o (in_flush),
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o, .evt_available_o, .led_o
  );

`ifdef MS_TWIN_USB_GATE
  // Simulation only (the full-system twin, sim/twin; mk/twin.mk defines it): the device is clocked
  // by a variable the harness drives, held while no packet is in flight, no byte moves between it
  // and the host link and its inputs from the system (twin_usb_in) do not change: its state then
  // changes only in two counters the harness advances (docs/twin.md). Never defined for
  // synthesis, lint or the RTL tests.
  logic        twin_usb_clk;
  logic [11:0] twin_usb_in;
  logic        twin_usb_moves;
  assign twin_usb_in    = {rst_usb, out_ready, in_valid, in_flush, in_data};
  assign twin_usb_moves = (out_valid & out_ready) | (in_valid & in_ready) | in_flush;
`endif
  ms_usb_device #(.SERIAL(SERIAL)) u_usb (
`ifdef MS_TWIN_USB_GATE
    .clk_i (twin_usb_clk),
`else
    .clk_i,
`endif
    .rst_i (rst_usb),
    .usb_dp_i, .usb_dn_i, .usb_dp_o, .usb_dn_o, .usb_oe_o, .usb_pullup_o,
    .configured_o (usb_configured_o), .bus_reset_o (unused_bus_reset),
    .out_data_o (out_data), .out_valid_o (out_valid), .out_last_o (unused_last), .out_end_o (out_end),
    .out_zlp_o (out_zlp), .out_ready_i (out_ready),
    .in_data_i (in_data), .in_valid_i (in_valid), .in_ready_o (in_ready), .in_flush_i (in_flush),
    .tl_en_i, .tl_bus_reset_i, .tl_rx_start_i, .tl_rx_valid_i, .tl_rx_byte_i, .tl_rx_end_i,
    .tl_tx_valid_o, .tl_tx_byte_o, .tl_tx_end_o
  );
endmodule
