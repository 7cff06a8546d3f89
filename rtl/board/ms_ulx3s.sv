// ms_ulx3s: Multisonar on the Radiona ULX3S (Lattice ECP5 LFE5U, CABGA381).
//
// Pins (constraints/ulx3s_lfe5u25.lpf): 25 MHz oscillator -> EHXPLLL -> 48 MHz system clock;
// FIRE1 button = reset (synchronised, also held while the PLL is not locked); 8 LEDs show
// ms_system's led_o; element i drives ms_drive[i] and listens on ms_echo[i], one GP/GN pair of
// the J1/J2 headers per element. The US2 USB port (D+/D- and the D+ pull-up switch) is
// declared and held detached: every USB pin is an input for now, i.e. never driven (the pull
// switches float, the board's 15 kOhm pull-downs win, a host sees no device). Issue #6 turns
// them into inout pins driven by the USB device core, placed between ms_system's host FIFO
// (host_*) and these pins, with the ECP5 I/O primitive (BB / TRELLIS_IO) for the tristate
// (the slang frontend treats a 1'bz assignment as X, so no inferred tristates). Until then
// nothing reads the host FIFO: the firmware sees it fill (HOST_STATUS), later words are dropped
// and counted.
module ms_ulx3s #(
  parameter int    NUM_CH    = 24,
  parameter int    RAM_WORDS = 16384,
  parameter string INIT_FILE = ""
) (
  input  logic              clk_25mhz,
  input  logic              btn_fire1,    // reset, active high
  output logic [7:0]        led,
  output logic [NUM_CH-1:0] ms_drive,     // transducer burst drive (GP pins)
  input  logic [NUM_CH-1:0] ms_echo,      // comparator outputs (GN pins), asynchronous
  // US2 (direct FPGA USB, issue #6): differential receiver, single-ended D+/D-, pull-ups
  input  logic              usb_fpga_dp,
  input  logic              usb_fpga_dn,
  input  logic              usb_fpga_bd_dp,
  input  logic              usb_fpga_bd_dn,
  input  logic              usb_fpga_pu_dp,
  input  logic              usb_fpga_pu_dn
);
  logic clk, locked, rst;

  ms_pll_ecp5 u_pll (.clk25_i (clk_25mhz), .clk48_o (clk), .locked_o (locked));
  ms_reset_sync u_rst (.clk_i (clk), .arst_i (btn_fire1 | ~locked), .rst_o (rst));

  // ---- USB: detached until issue #6 (host_rd stays low; see the header)
  logic        host_rvalid;
  logic [32:0] host_rdata;
  logic        unused_usb;
  assign unused_usb = ^{usb_fpga_dp, usb_fpga_dn, usb_fpga_bd_dp, usb_fpga_bd_dn, usb_fpga_pu_dp,
                        usb_fpga_pu_dn, host_rvalid, host_rdata};

  logic        unused_strobe, unused_trap, unused_bus_err, unused_evt;
  logic [31:0] unused_sim_out;

  ms_system #(.NUM_CH(NUM_CH), .RAM_WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE)) u_system (
    .clk_i (clk), .rst_i (rst),
    .echo_i (ms_echo), .drive_o (ms_drive),
    .host_rd_i (1'b0), .host_rvalid_o (host_rvalid), .host_rdata_o (host_rdata),
    .sim_out_strobe_o (unused_strobe), .sim_out_o (unused_sim_out), .trap_o (unused_trap),
    .bus_err_o (unused_bus_err), .evt_available_o (unused_evt), .led_o (led)
  );
endmodule
