// usb_link_tb: cocotb top for the whole device behind USB (tests/rtl/test_usb_link.py):
// ms_system_usb (SoC running firmware/app/sonar, sonar core, host link, USB device core)
// with both host models of tests/rtl/usb_host.py on its bus: the transaction-level host
// (usb_tl_host_tb on the wire-less port, tl_en_i = 1: the unchanged host driver through the
// real endpoint logic) and the wire-level host (usb_host_phy_tb on D+/D-, tl_en_i = 0).
// Port names are those UsbHost drives (as tests/rtl/usb_device_tb.sv). The host bit clock
// hclk_i is only needed for the wire-level host (feed it from the device clock's frequency).
module usb_link_tb #(
  parameter string INIT_FILE = "",
  parameter int    NSYM      = 1024
) (
  input  logic              clk_i,
  input  logic              hclk_i,
  input  logic              rst_i,
  input  logic [23:0]       echo_i,
  output logic [23:0]       drive_o,
  // wire-level host
  input  logic              go_i,
  input  logic [2*NSYM-1:0] tx_syms_i,
  input  logic [15:0]       tx_nsym_i,
  input  logic [15:0]       listen_i,
  input  logic [1:0]        skew_i,
  output logic              done_o,
  output logic [2*NSYM-1:0] rx_syms_o,
  output logic [15:0]       rx_nsym_o,
  output logic [15:0]       resp_delay_o,
  output logic              collision_o,
  // transaction-level host
  input  logic              tl_en_i,
  input  logic              tl_bus_reset_i,
  input  logic              tl_go_i,
  input  logic [8*72-1:0]   tl_tx_bytes_i,
  input  logic [7:0]        tl_tx_len_i,
  input  logic [15:0]       tl_listen_i,
  output logic              tl_done_o,
  output logic [8*72-1:0]   tl_rx_bytes_o,
  output logic [7:0]        tl_rx_len_o,
  output logic [15:0]       tl_resp_delay_o,
  // device status
  output logic              configured_o,
  output logic              pullup_o,
  output logic              sim_out_strobe_o,
  output logic [31:0]       sim_out_o,
  output logic              trap_o,
  output logic              bus_err_o
);
  logic       dev_dp, dev_dn, dev_oe, host_dp, host_dn, host_oe, bus_dp, bus_dn;
  logic       tl_rx_start, tl_rx_valid, tl_rx_end, tl_tx_valid, tl_tx_end, unused_evt;
  logic [7:0] tl_rx_byte, tl_tx_byte, led;

  assign bus_dp = dev_oe ? dev_dp : host_oe ? host_dp : pullup_o;
  assign bus_dn = dev_oe ? dev_dn : host_oe ? host_dn : 1'b0;

  always_ff @(posedge clk_i) begin
    if (rst_i)                 collision_o <= 1'b0;
    else if (dev_oe && host_oe) collision_o <= 1'b1;
  end

  ms_system_usb #(.NUM_CH(24), .INIT_FILE(INIT_FILE), .STRETCH_W(4)) u_dev (
    .clk_i, .rst_i, .echo_i, .drive_o,
    .usb_dp_i (bus_dp), .usb_dn_i (bus_dn), .usb_dp_o (dev_dp), .usb_dn_o (dev_dn), .usb_oe_o (dev_oe),
    .usb_pullup_o (pullup_o), .usb_configured_o (configured_o),
    .tl_en_i, .tl_bus_reset_i, .tl_rx_start_i (tl_rx_start), .tl_rx_valid_i (tl_rx_valid),
    .tl_rx_byte_i (tl_rx_byte), .tl_rx_end_i (tl_rx_end), .tl_tx_valid_o (tl_tx_valid),
    .tl_tx_byte_o (tl_tx_byte), .tl_tx_end_o (tl_tx_end),
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o, .evt_available_o (unused_evt), .led_o (led)
  );

  usb_tl_host_tb #(.NB(72)) u_tl_host (
    .clk_i, .rst_i, .go_i (tl_go_i), .tx_bytes_i (tl_tx_bytes_i), .tx_len_i (tl_tx_len_i),
    .listen_i (tl_listen_i), .done_o (tl_done_o), .rx_bytes_o (tl_rx_bytes_o), .rx_len_o (tl_rx_len_o),
    .resp_delay_o (tl_resp_delay_o), .tl_rx_start_o (tl_rx_start), .tl_rx_valid_o (tl_rx_valid),
    .tl_rx_byte_o (tl_rx_byte), .tl_rx_end_o (tl_rx_end), .tl_tx_valid_i (tl_tx_valid),
    .tl_tx_byte_i (tl_tx_byte), .tl_tx_end_i (tl_tx_end)
  );

  usb_host_phy_tb #(.NSYM(NSYM)) u_host (
    .hclk_i, .go_i, .tx_syms_i, .tx_nsym_i, .listen_i, .skew_i, .done_o, .rx_syms_o, .rx_nsym_o,
    .resp_delay_o, .bus_dp_i (bus_dp), .bus_dn_i (bus_dn), .dp_o (host_dp), .dn_o (host_dn), .oe_o (host_oe)
  );
endmodule
