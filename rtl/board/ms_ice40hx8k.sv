// ms_ice40hx8k: Multisonar on a Lattice iCE40-HX8K (ct256) board, e.g. the iCE40-HX8K
// breakout board: 12 MHz oscillator on J3 -> SB_PLL40 -> 48 MHz, 8 LEDs, transducer lines
// and the USB pins on the headers (constraints/ice40_hx8k_ct256.pcf).
//
// Reduced for the iCE40 (see docs/synthesis.md): NUM_CH transducer channels (default 8, not
// 24), the scheduler at its smallest (NUM_VS 2 sensors, WSLOTS 2 window slots per element)
// and RAM_WORDS = 1024 (4 KiB of SoC RAM, firmware linked for it by mk/synth.mk); CAPS reports
// them. Even so the design is about twice the HX8K (docs/synthesis.md, "The 25F profile"). USB: ms_system_usb's device core on
// usb_dp / usb_dn through SB_IO tristate pads (no inferred tristates with the slang frontend);
// usb_pu drives the 1.5 kOhm D+ pull-up (high = attached).
module ms_ice40hx8k #(
  parameter int    NUM_CH    = 8,
  parameter int    RAM_WORDS = 1024,
  parameter string INIT_FILE = "",
  parameter int    NUM_VS    = 2,
  parameter int    WSLOTS    = 2
) (
  input  logic              clk_12mhz,
  input  logic              btn_rst_n,   // reset, active low (header pin with pull-up)
  output logic [7:0]        led,
  output logic [NUM_CH-1:0] ms_drive,
  input  logic [NUM_CH-1:0] ms_echo,
  inout  wire               usb_dp,
  inout  wire               usb_dn,
  output logic              usb_pu       // drives the 1.5 kOhm D+ pull-up
);
  logic clk, locked, rst;

  ms_pll_ice40 u_pll (.clk12_i (clk_12mhz), .clk48_o (clk), .locked_o (locked));
  ms_reset_sync u_rst (.clk_i (clk), .arst_i (~btn_rst_n | ~locked), .rst_o (rst));

  // ---- USB pads: SB_IO, output with tristate enable, plain input
  logic dp_in, dn_in, dp_out, dn_out, usb_oe, usb_pu_en;
  SB_IO #(.PIN_TYPE (6'b1010_01), .PULLUP (1'b0)) u_io_dp (
    .PACKAGE_PIN (usb_dp), .OUTPUT_ENABLE (usb_oe), .D_OUT_0 (dp_out), .D_IN_0 (dp_in));
  SB_IO #(.PIN_TYPE (6'b1010_01), .PULLUP (1'b0)) u_io_dn (
    .PACKAGE_PIN (usb_dn), .OUTPUT_ENABLE (usb_oe), .D_OUT_0 (dn_out), .D_IN_0 (dn_in));
  assign usb_pu = usb_pu_en;

  logic        unused_strobe, unused_trap, unused_bus_err, unused_evt, unused_cfg;
  logic        unused_tl_valid, unused_tl_end;
  logic [7:0]  unused_tl_byte;
  logic [31:0] unused_sim_out;

  // PicoRV32 with the iterative multiplier: VexRiscv's caches alone would take the HX8K's whole
  // block RAM and the DSP-less single-cycle multiplier ~3 k SB_LUT4 (firmware/README.md)
  ms_system_usb #(.NUM_CH(NUM_CH), .RAM_WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE), .CPU("picorv32"),
                  .FAST_MUL(0), .NUM_VS(NUM_VS), .WSLOTS(WSLOTS)) u_system (
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
