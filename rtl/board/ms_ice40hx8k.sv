// ms_ice40hx8k: Multisonar on a Lattice iCE40-HX8K (ct256) board, e.g. the iCE40-HX8K
// breakout board: 12 MHz oscillator on J3 -> SB_PLL40 -> 48 MHz, 8 LEDs, transducer lines
// and the USB pins on the headers (constraints/ice40_hx8k_ct256.pcf).
//
// Reduced for the iCE40 (see docs/synthesis.md): NUM_CH transducer channels (default 8, not
// 24) and RAM_WORDS = 1024 (4 KiB of SoC RAM, firmware linked for it by mk/synth.mk); the
// sonar register map still reports CAPS.num_ch = 24. USB (issue #6): D+/D- and the D+
// pull-up switch are declared as inputs, i.e. never driven (detached), until the USB device
// core lands and drives them through SB_IO (no inferred tristates with the slang frontend).
module ms_ice40hx8k #(
  parameter int    NUM_CH    = 8,
  parameter int    RAM_WORDS = 1024,
  parameter string INIT_FILE = ""
) (
  input  logic              clk_12mhz,
  input  logic              btn_rst_n,   // reset, active low (header pin with pull-up)
  output logic [7:0]        led,
  output logic [NUM_CH-1:0] ms_drive,
  input  logic [NUM_CH-1:0] ms_echo,
  input  logic              usb_dp,
  input  logic              usb_dn,
  input  logic              usb_pu       // will drive the 1.5 kOhm D+ pull-up when attached
);
  logic clk, locked, rst;

  ms_pll_ice40 u_pll (.clk12_i (clk_12mhz), .clk48_o (clk), .locked_o (locked));
  ms_reset_sync u_rst (.clk_i (clk), .arst_i (~btn_rst_n | ~locked), .rst_o (rst));

  logic        host_rvalid;
  logic [32:0] host_rdata;
  logic        unused_usb;
  assign unused_usb = ^{usb_dp, usb_dn, usb_pu, host_rvalid, host_rdata};

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
