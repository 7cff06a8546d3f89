// usb_device_tb: cocotb top for the USB device core tests (tests/rtl/tb_usb_device.py).
// The device (ms_usb_device, clk_i 48 MHz) and the wire-level host (usb_host_phy_tb, hclk_i =
// 48 MHz * (1 + host clock error)) share the bus: a driven line wins, else the D+ pull-up gives
// J (SE0 without it). collision_o latches when both drive at once.
// Application side, kept in RTL so Python works per transfer:
// - OUT sink: every entry delivered on EP 0x01 is logged (out_log_o, byte i at [8i+7:8i]; its
//   out_last/out_end/out_zlp flags at out_*_log_o[i]); out_count_o counts them; out_ready_i
//   gates the sink.
// - IN source: on a rising src_go_i the bytes src_buf_i[0 .. src_len_i-1] are pushed into EP 0x81
//   as fast as it accepts them, then in_flush is pulsed when src_flush_i; src_busy_o meanwhile.
module usb_device_tb #(
  parameter int NSYM   = 1024,
  parameter int LOGLEN = 512,
  parameter int SRCLEN = 512,
  parameter int SERIAL = 'h00000001
) (
  input  logic                clk_i,
  input  logic                hclk_i,
  input  logic                rst_i,
  // host
  input  logic                go_i,
  input  logic [2*NSYM-1:0]   tx_syms_i,
  input  logic [15:0]         tx_nsym_i,
  input  logic [15:0]         listen_i,
  input  logic [1:0]          skew_i,
  output logic                done_o,
  output logic [2*NSYM-1:0]   rx_syms_o,
  output logic [15:0]         rx_nsym_o,
  output logic [15:0]         resp_delay_o,
  output logic                collision_o,
  output logic                dev_drove_o,   // the device enabled its drivers since reset
  // transaction-level host (usb_tl_host_tb) on the wire-less port, used when tl_en_i = 1
  input  logic                tl_en_i,
  input  logic                tl_bus_reset_i,
  input  logic                tl_go_i,
  input  logic [8*72-1:0]     tl_tx_bytes_i,
  input  logic [7:0]          tl_tx_len_i,
  input  logic [15:0]         tl_listen_i,
  output logic                tl_done_o,
  output logic [8*72-1:0]     tl_rx_bytes_o,
  output logic [7:0]          tl_rx_len_o,
  output logic [15:0]         tl_resp_delay_o,
  // device status
  output logic                configured_o,
  output logic                bus_reset_o,
  output logic                pullup_o,
  // application
  input  logic                out_ready_i,
  output logic [8*LOGLEN-1:0] out_log_o,
  output logic [LOGLEN-1:0]   out_last_log_o,
  output logic [LOGLEN-1:0]   out_end_log_o,
  output logic [LOGLEN-1:0]   out_zlp_log_o,
  output logic [15:0]         out_count_o,
  input  logic [8*SRCLEN-1:0] src_buf_i,
  input  logic [15:0]         src_len_i,
  input  logic                src_go_i,
  input  logic                src_flush_i,
  output logic                src_busy_o
);
  logic dev_dp, dev_dn, dev_oe, host_dp, host_dn, host_oe, bus_dp, bus_dn;
  logic [7:0] out_data, in_data;
  logic tl_rx_start, tl_rx_valid, tl_rx_end, tl_tx_valid, tl_tx_end;
  logic [7:0] tl_rx_byte, tl_tx_byte;
  logic out_valid, out_last, out_end, out_zlp, in_valid, in_ready, in_flush;

  assign bus_dp = dev_oe ? dev_dp : host_oe ? host_dp : pullup_o;
  assign bus_dn = dev_oe ? dev_dn : host_oe ? host_dn : 1'b0;

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      collision_o <= 1'b0;
      dev_drove_o <= 1'b0;
    end else begin
      if (dev_oe && host_oe) collision_o <= 1'b1;
      if (dev_oe) dev_drove_o <= 1'b1;
    end
  end

  ms_usb_device #(.SERIAL(SERIAL)) u_dev (
    .clk_i(clk_i), .rst_i(rst_i), .usb_dp_i(bus_dp), .usb_dn_i(bus_dn),
    .usb_dp_o(dev_dp), .usb_dn_o(dev_dn), .usb_oe_o(dev_oe), .usb_pullup_o(pullup_o),
    .configured_o(configured_o), .bus_reset_o(bus_reset_o),
    .out_data_o(out_data), .out_valid_o(out_valid), .out_last_o(out_last),
    .out_end_o(out_end), .out_zlp_o(out_zlp), .out_ready_i(out_ready_i),
    .in_data_i(in_data), .in_valid_i(in_valid), .in_ready_o(in_ready), .in_flush_i(in_flush),
    .tl_en_i(tl_en_i), .tl_bus_reset_i(tl_bus_reset_i), .tl_rx_start_i(tl_rx_start),
    .tl_rx_valid_i(tl_rx_valid), .tl_rx_byte_i(tl_rx_byte), .tl_rx_end_i(tl_rx_end),
    .tl_tx_valid_o(tl_tx_valid), .tl_tx_byte_o(tl_tx_byte), .tl_tx_end_o(tl_tx_end)
  );

  usb_tl_host_tb #(.NB(72)) u_tl_host (
    .clk_i(clk_i), .rst_i(rst_i), .go_i(tl_go_i), .tx_bytes_i(tl_tx_bytes_i), .tx_len_i(tl_tx_len_i),
    .listen_i(tl_listen_i), .done_o(tl_done_o), .rx_bytes_o(tl_rx_bytes_o), .rx_len_o(tl_rx_len_o),
    .resp_delay_o(tl_resp_delay_o), .tl_rx_start_o(tl_rx_start), .tl_rx_valid_o(tl_rx_valid),
    .tl_rx_byte_o(tl_rx_byte), .tl_rx_end_o(tl_rx_end), .tl_tx_valid_i(tl_tx_valid),
    .tl_tx_byte_i(tl_tx_byte), .tl_tx_end_i(tl_tx_end)
  );

  usb_host_phy_tb #(.NSYM(NSYM)) u_host (
    .hclk_i(hclk_i), .go_i(go_i), .tx_syms_i(tx_syms_i), .tx_nsym_i(tx_nsym_i), .listen_i(listen_i),
    .skew_i(skew_i), .done_o(done_o), .rx_syms_o(rx_syms_o), .rx_nsym_o(rx_nsym_o), .resp_delay_o(resp_delay_o),
    .bus_dp_i(bus_dp), .bus_dn_i(bus_dn), .dp_o(host_dp), .dn_o(host_dn), .oe_o(host_oe)
  );

  // OUT sink
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      out_count_o    <= '0;
      out_log_o      <= '0;
      out_last_log_o <= '0;
      out_end_log_o  <= '0;
      out_zlp_log_o  <= '0;
    end else if (out_valid && out_ready_i && out_count_o < 16'(LOGLEN)) begin
      out_log_o[8*out_count_o +: 8] <= out_data;
      out_last_log_o[out_count_o]   <= out_last;
      out_end_log_o[out_count_o]    <= out_end;
      out_zlp_log_o[out_count_o]    <= out_zlp;
      out_count_o                   <= out_count_o + 16'd1;
    end
  end

  // IN source
  logic        go_q, flush_q;
  logic [15:0] sidx_q;
  always_ff @(posedge clk_i) begin
    in_flush <= 1'b0;
    if (rst_i) begin
      go_q       <= 1'b0;
      src_busy_o <= 1'b0;
      sidx_q     <= '0;
      flush_q    <= 1'b0;
    end else begin
      go_q <= src_go_i;
      if (src_go_i && !go_q) begin
        src_busy_o <= 1'b1;
        sidx_q     <= '0;
        flush_q    <= src_flush_i;
      end else if (src_busy_o) begin
        if (in_valid && in_ready) sidx_q <= sidx_q + 16'd1;
        if (sidx_q == src_len_i) begin
          src_busy_o <= 1'b0;
          in_flush   <= flush_q;
        end
      end
    end
  end
  assign in_valid = src_busy_o && (sidx_q != src_len_i);
  assign in_data  = src_buf_i[8*sidx_q +: 8];
endmodule
