// ms_ulx3s: Multisonar on the Radiona ULX3S (Lattice ECP5 LFE5U, CABGA381).
//
// Pins (constraints/ulx3s_lfe5u25.lpf): 25 MHz oscillator -> EHXPLLL -> 48 MHz system clock;
// FIRE1 button = reset (synchronised, also held while the PLL is not locked); 8 LEDs show
// ms_system's led_o; element i drives ms_drive[i] and listens on ms_echo[i], one GP/GN pair of
// the J1/J2 headers per element. USB on US2 (direct FPGA USB): ms_system_usb's device core reads
// and drives the bidirectional single-ended D+/D- (usb_fpga_bd_dp/dn) through ECP5 TRELLIS_IO
// primitives (the slang frontend treats a 1'bz assignment as X, so no inferred tristates) and
// switches the 1.5 kOhm D+ pull-up with usb_fpga_pu_dp; the D- pull switch and the
// differential receiver pair (usb_fpga_dp/dn) are unused inputs.
// SoC RAM: 60 KiB (RAM_WORDS 15360, four banks of block RAM, 30 DP16KD; ms_ram_sp_bytes) for
// the firmware linked by the top Makefile; INIT_FILE.0 .. .3 hold the banks' images.
module ms_ulx3s #(
  parameter int    NUM_CH    = 24,
  parameter int    RAM_WORDS = 15360,
  parameter string INIT_FILE = "",
  // scheduler size: the full 8 sensors / 16 slots on the 45F and 85F; make synth passes
  // 4 / 8 for the 25F (mk/synth.mk, docs/synthesis.md), which CAPS then reports
  parameter int    NUM_VS    = 8,
  parameter int    WSLOTS    = 16
) (
  input  logic              clk_25mhz,
  input  logic              btn_fire1,    // reset, active high
  output logic [7:0]        led,
  output logic [NUM_CH-1:0] ms_drive,     // transducer burst drive (GP pins)
  input  logic [NUM_CH-1:0] ms_echo,      // comparator outputs (GN pins), asynchronous
  // US2 (direct FPGA USB)
  input  logic              usb_fpga_dp,
  input  logic              usb_fpga_dn,
  inout  wire               usb_fpga_bd_dp,
  inout  wire               usb_fpga_bd_dn,
  output logic              usb_fpga_pu_dp,
  input  logic              usb_fpga_pu_dn
);
  logic clk, locked, rst;

  ms_pll_ecp5 u_pll (.clk25_i (clk_25mhz), .clk48_o (clk), .locked_o (locked));
  ms_reset_sync u_rst (.clk_i (clk), .arst_i (btn_fire1 | ~locked), .rst_o (rst));

  // ---- USB pads: TRELLIS_IO bidirectional buffers (T high: tristate)
  logic dp_in, dn_in, dp_out, dn_out, usb_oe, usb_pu_en;
  TRELLIS_IO #(.DIR ("BIDIR")) u_io_dp (.I (dp_out), .T (~usb_oe), .O (dp_in), .B (usb_fpga_bd_dp));
  TRELLIS_IO #(.DIR ("BIDIR")) u_io_dn (.I (dn_out), .T (~usb_oe), .O (dn_in), .B (usb_fpga_bd_dn));
  assign usb_fpga_pu_dp = usb_pu_en;

  logic        unused_usb, unused_strobe, unused_trap, unused_bus_err, unused_evt, unused_cfg;
  logic        unused_tl_valid, unused_tl_end;
  logic [7:0]  unused_tl_byte;
  logic [31:0] unused_sim_out;
  assign unused_usb = ^{usb_fpga_dp, usb_fpga_dn, usb_fpga_pu_dn};

  ms_system_usb #(.NUM_CH(NUM_CH), .RAM_WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE), .NUM_VS(NUM_VS),
                  .WSLOTS(WSLOTS)) u_system (
    .clk_i (clk), .rst_i (rst),
    .echo_i (ms_echo), .drive_o (ms_drive),
    .usb_dp_i (dp_in), .usb_dn_i (dn_in), .usb_dp_o (dp_out), .usb_dn_o (dn_out), .usb_oe_o (usb_oe),
    .usb_pullup_o (usb_pu_en), .usb_configured_o (unused_cfg),
    .tl_en_i (1'b0), .tl_bus_reset_i (1'b0), .tl_rx_start_i (1'b0), .tl_rx_valid_i (1'b0),
    .tl_rx_byte_i (8'd0), .tl_rx_end_i (1'b0), .tl_tx_valid_o (unused_tl_valid), .tl_tx_byte_o (unused_tl_byte),
    .tl_tx_end_o (unused_tl_end),
    .sim_out_strobe_o (unused_strobe), .sim_out_o (unused_sim_out), .trap_o (unused_trap),
    .bus_err_o (unused_bus_err), .evt_available_o (unused_evt), .led_o (led)
  );
endmodule
