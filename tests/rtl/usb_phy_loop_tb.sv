// usb_phy_loop_tb: cocotb top for the unit test of the USB PHY blocks (tests/rtl/tb_usb_phy.py):
// ms_usb_tx drives the line, ms_usb_rx + ms_usb_pkt_rx receive it.
// - go_i rising: send pid_i (with_data_i: + len_i bytes of buf_i, byte k at [8k+7:8k], + CRC16).
// - raw_o/raw_count_o: the bytes ms_usb_rx recovered (PID and CRC included); eop_o / err_o count
//   its packet endings; pay_o/pay_count_o: payload bytes from ms_usb_pkt_rx, dat_ok_o/dat_end_o
//   its verdict, hs_o the count of handshakes decoded; line_clks_o counts clocks with oe high.
module usb_phy_loop_tb (
  input  logic         clk_i,
  input  logic         rst_i,
  input  logic         go_i,
  input  logic [3:0]   pid_i,
  input  logic         with_data_i,
  input  logic [6:0]   len_i,
  input  logic [511:0] buf_i,
  output logic         busy_o,
  output logic [575:0] raw_o,
  output logic [7:0]   raw_count_o,
  output logic [511:0] pay_o,
  output logic [7:0]   pay_count_o,
  output logic [7:0]   eop_o,
  output logic [7:0]   err_o,
  output logic [7:0]   dat_end_o,
  output logic [7:0]   dat_ok_o,
  output logic [7:0]   hs_o,
  output logic [15:0]  line_clks_o
);
  logic go_q, start, rd, done, dp, dn, oe, tx_busy;
  logic [6:0] idx_q;
  logic [7:0] byte_q;
  logic rx_start, rx_valid, rx_eop, rx_err, bus_reset;
  logic [7:0] rx_byte;
  logic pkt_start, tok_valid, dat_start, dat_pid1, dat_valid, dat_end, dat_ok, hs_valid;
  logic [3:0] tok_pid, tok_ep, hs_pid;
  logic [6:0] tok_addr;
  logic [7:0] dat_byte;

  always_ff @(posedge clk_i) go_q <= go_i;
  assign start = go_i && !go_q;

  always_ff @(posedge clk_i) begin
    if (rst_i || start) idx_q <= '0;
    else if (rd) begin
      byte_q <= buf_i[8*idx_q +: 8];
      idx_q  <= idx_q + 7'd1;
    end
  end

  ms_usb_tx u_tx (
    .clk_i(clk_i), .rst_i(rst_i), .start_i(start), .pid_i(pid_i), .with_data_i(with_data_i),
    .len_i(len_i), .rd_o(rd), .byte_i(byte_q), .busy_o(tx_busy), .done_o(done),
    .dp_o(dp), .dn_o(dn), .oe_o(oe)
  );

  ms_usb_rx u_rx (
    .clk_i(clk_i), .rst_i(rst_i), .dp_i(oe ? dp : 1'b1), .dn_i(oe ? dn : 1'b0), .block_i(1'b0),
    .start_o(rx_start), .byte_valid_o(rx_valid), .byte_o(rx_byte), .eop_o(rx_eop),
    .err_o(rx_err), .bus_reset_o(bus_reset)
  );

  ms_usb_pkt_rx u_pkt (
    .clk_i(clk_i), .rst_i(rst_i), .rx_start_i(rx_start), .rx_valid_i(rx_valid), .rx_byte_i(rx_byte),
    .rx_eop_i(rx_eop), .rx_err_i(rx_err), .pkt_start_o(pkt_start),
    .tok_valid_o(tok_valid), .tok_pid_o(tok_pid), .tok_addr_o(tok_addr), .tok_ep_o(tok_ep),
    .dat_start_o(dat_start), .dat_pid1_o(dat_pid1), .dat_valid_o(dat_valid), .dat_byte_o(dat_byte),
    .dat_end_o(dat_end), .dat_ok_o(dat_ok), .hs_valid_o(hs_valid), .hs_pid_o(hs_pid)
  );

  always_ff @(posedge clk_i) begin
    if (rst_i || start) begin
      raw_count_o <= '0; pay_count_o <= '0; eop_o <= '0; err_o <= '0; dat_end_o <= '0;
      dat_ok_o <= '0; hs_o <= '0; line_clks_o <= '0;
      if (rst_i) begin raw_o <= '0; pay_o <= '0; end
    end else begin
      if (rx_valid && raw_count_o < 8'd72) begin
        raw_o[8*raw_count_o +: 8] <= rx_byte;
        raw_count_o <= raw_count_o + 8'd1;
      end
      if (dat_valid && pay_count_o < 8'd64) begin
        pay_o[8*pay_count_o +: 8] <= dat_byte;
        pay_count_o <= pay_count_o + 8'd1;
      end
      if (rx_eop) eop_o <= eop_o + 8'd1;
      if (rx_err) err_o <= err_o + 8'd1;
      if (dat_end) dat_end_o <= dat_end_o + 8'd1;
      if (dat_end && dat_ok) dat_ok_o <= dat_ok_o + 8'd1;
      if (hs_valid) hs_o <= hs_o + 8'd1;
      if (oe) line_clks_o <= line_clks_o + 16'd1;
    end
  end
  assign busy_o = tx_busy || go_q != go_i;
endmodule
