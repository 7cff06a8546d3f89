// ms_usb_device: USB 2.0 full-speed device core (top of rtl/usb/): one vendor interface with
// bulk OUT EP 0x01 (commands) and bulk IN EP 0x81 (frames), control EP0 in hardware with
// Microsoft OS 2.0 descriptors (WinUSB). Block diagram and contracts: docs/usb_core.md.
//
// Timing contract: one clock, clk_i = 48 MHz (4x the 12 Mbit/s bit rate), synchronous rst_i.
// - usb_dp_i/usb_dn_i: the bus lines, asynchronous (synchronised inside ms_usb_rx).
//   usb_dp_o/usb_dn_o are valid while usb_oe_o is high (drive the pads then, else tri-state);
//   usb_pullup_o enables the 1.5 kOhm D+ pull-up (high from the clock after reset).
// - configured_o: SET_CONFIGURATION(1) done and no bus reset since; bus_reset_o: SE0 >= 2.5 us.
// - OUT (EP 0x01): out_valid_o/out_data_o, an entry moves on each clock with out_ready_i high;
//   out_last_o marks the last byte of a USB packet, out_end_o the end of a transfer (short
//   packet); a zero-length packet is one entry with out_zlp_o (no data byte), out_last_o and
//   out_end_o. Only packets with a good CRC and the expected toggle are delivered; the host gets
//   NAK while fewer than 64 entries of OUT_DEPTH are free.
// - IN (EP 0x81): in_valid_i/in_data_i taken when in_ready_o; full 64-byte packets are sent as
//   soon as queued, in_flush_i pulses ask for the rest as a short packet (zero-length after an
//   exact multiple of 64). NAK when nothing is ready; data are re-sent until ACKed.
// - Transaction level (tl_en_i = 1, for the USB/IP simulation bridge): the wire is ignored and
//   the packet layer takes whole packets as bytes instead: tl_rx_start_i, then one byte per
//   tl_rx_valid_i (PID, fields/data, CRC bytes exactly as on the wire; up to one per clock),
//   then tl_rx_end_i. The device's packets come out as tl_tx_valid_o/tl_tx_byte_o (PID ... CRC,
//   one byte every 4 clocks) closed by tl_tx_end_o. CRC checks, toggles, handshakes, time-outs
//   and endpoints are the same logic as on the wire; switch tl_en_i only while the bus is idle.
//   tl_bus_reset_i (level) acts like SE0 on the wire for >= 2.5 us.
module ms_usb_device #(
  // the board's serial number; the rest of the identity (VID, PID, bcdDevice = the protocol
  // version, strings, MS OS 2.0 vendor code) is the generated descriptor image (ms_usb_desc_pkg)
  parameter int SERIAL         = 'h00000001,
  parameter int OUT_DEPTH      = 128,
  parameter int IN_DEPTH       = 256
) (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       usb_dp_i,
  input  logic       usb_dn_i,
  output logic       usb_dp_o,
  output logic       usb_dn_o,
  output logic       usb_oe_o,
  output logic       usb_pullup_o,
  output logic       configured_o,
  output logic       bus_reset_o,
  output logic [7:0] out_data_o,
  output logic       out_valid_o,
  output logic       out_last_o,
  output logic       out_end_o,
  output logic       out_zlp_o,
  input  logic       out_ready_i,
  input  logic [7:0] in_data_i,
  input  logic       in_valid_i,
  output logic       in_ready_o,
  input  logic       in_flush_i,
  // transaction-level entry point (simulation bridge; tie tl_en_i and tl_rx_* to 0 on a board)
  input  logic       tl_en_i,
  input  logic       tl_bus_reset_i,
  input  logic       tl_rx_start_i,
  input  logic       tl_rx_valid_i,
  input  logic [7:0] tl_rx_byte_i,
  input  logic       tl_rx_end_i,
  output logic       tl_tx_valid_o,
  output logic [7:0] tl_tx_byte_o,
  output logic       tl_tx_end_o
);
  // receive path
  logic       rx_start, rx_valid, rx_eop, rx_err, wire_reset, bus_reset, tx_busy;
  logic [7:0] rx_byte;
  // packet layer
  logic       pkt_start, tok_valid, dat_start, dat_pid1, dat_valid, dat_end, dat_ok, hs_valid;
  logic [3:0] tok_pid, tok_ep, hs_pid;
  logic [6:0] tok_addr;
  logic [7:0] dat_byte;
  // transmit
  logic       tx_start, tx_with_data, tx_rd, tx_done;  // tx_busy: wire transmitter only
  logic [3:0] tx_pid;
  logic [6:0] tx_len;
  logic [7:0] tx_byte;
  // EP0 / device state
  logic [6:0] addr, ep0_in_len;
  logic       configured;
  logic [1:0] halt, toggle_rst;
  logic       ep0_setup_begin, ep0_setup_valid, ep0_setup, ep0_in_stall, ep0_in_pid1;
  logic       ep0_in_start, ep0_rd, ep0_in_ack, ep0_out_stall, ep0_out_ack;
  logic [7:0] ep0_setup_byte, ep0_data;
  // bulk endpoints
  logic       out_room, out_begin, out_wvalid, out_commit, out_abort;
  logic [7:0] out_wbyte;
  logic       in_has_pkt, in_start, in_rd, in_ack, in_drop;
  logic [6:0] in_len;
  logic [7:0] in_rdata;

  ms_usb_rx u_rx (
    .clk_i(clk_i), .rst_i(rst_i), .dp_i(usb_dp_i), .dn_i(usb_dn_i), .block_i(tx_busy),
    .start_o(rx_start), .byte_valid_o(rx_valid), .byte_o(rx_byte),
    .eop_o(rx_eop), .err_o(rx_err), .bus_reset_o(wire_reset)
  );
  assign bus_reset = wire_reset | tl_bus_reset_i;

  // packet-layer input: the wire receiver or the transaction-level port
  logic       p_start, p_valid, p_eop, p_err;
  logic [7:0] p_byte;
  assign p_start = tl_en_i ? tl_rx_start_i : rx_start;
  assign p_valid = tl_en_i ? tl_rx_valid_i : rx_valid;
  assign p_byte  = tl_en_i ? tl_rx_byte_i  : rx_byte;
  assign p_eop   = tl_en_i ? tl_rx_end_i   : rx_eop;
  assign p_err   = tl_en_i ? 1'b0          : rx_err;

  ms_usb_pkt_rx u_pkt_rx (
    .clk_i(clk_i), .rst_i(rst_i), .rx_start_i(p_start), .rx_valid_i(p_valid), .rx_byte_i(p_byte),
    .rx_eop_i(p_eop), .rx_err_i(p_err), .pkt_start_o(pkt_start),
    .tok_valid_o(tok_valid), .tok_pid_o(tok_pid), .tok_addr_o(tok_addr), .tok_ep_o(tok_ep),
    .dat_start_o(dat_start), .dat_pid1_o(dat_pid1), .dat_valid_o(dat_valid), .dat_byte_o(dat_byte),
    .dat_end_o(dat_end), .dat_ok_o(dat_ok), .hs_valid_o(hs_valid), .hs_pid_o(hs_pid)
  );

  // transmit: on the wire, or as bytes at transaction level
  logic w_rd, w_done, t_rd, t_done;
  ms_usb_tx u_tx (
    .clk_i(clk_i), .rst_i(rst_i), .start_i(tx_start && !tl_en_i), .pid_i(tx_pid),
    .with_data_i(tx_with_data), .len_i(tx_len), .rd_o(w_rd), .byte_i(tx_byte), .busy_o(tx_busy),
    .done_o(w_done), .dp_o(usb_dp_o), .dn_o(usb_dn_o), .oe_o(usb_oe_o)
  );

  ms_usb_tx_tl u_tx_tl (
    .clk_i(clk_i), .rst_i(rst_i), .start_i(tx_start && tl_en_i), .pid_i(tx_pid),
    .with_data_i(tx_with_data), .len_i(tx_len), .rd_o(t_rd), .byte_i(tx_byte),
    .done_o(t_done), .byte_valid_o(tl_tx_valid_o), .byte_o(tl_tx_byte_o)
  );
  assign tx_rd       = w_rd | t_rd;
  assign tx_done     = w_done | t_done;
  assign tl_tx_end_o = t_done;

  ms_usb_xact u_xact (
    .clk_i(clk_i), .rst_i(rst_i), .bus_reset_i(bus_reset),
    .pkt_start_i(pkt_start), .tok_valid_i(tok_valid), .tok_pid_i(tok_pid), .tok_addr_i(tok_addr),
    .tok_ep_i(tok_ep), .dat_start_i(dat_start), .dat_pid1_i(dat_pid1), .dat_valid_i(dat_valid),
    .dat_byte_i(dat_byte), .dat_end_i(dat_end), .dat_ok_i(dat_ok), .hs_valid_i(hs_valid),
    .hs_pid_i(hs_pid),
    .tx_start_o(tx_start), .tx_pid_o(tx_pid), .tx_with_data_o(tx_with_data), .tx_len_o(tx_len),
    .tx_rd_i(tx_rd), .tx_byte_o(tx_byte), .tx_done_i(tx_done),
    .addr_i(addr), .configured_i(configured), .halt_i(halt), .toggle_rst_i(toggle_rst),
    .ep0_setup_begin_o(ep0_setup_begin), .ep0_setup_valid_o(ep0_setup_valid),
    .ep0_setup_byte_o(ep0_setup_byte), .ep0_setup_o(ep0_setup), .ep0_in_stall_i(ep0_in_stall),
    .ep0_in_len_i(ep0_in_len), .ep0_in_pid1_i(ep0_in_pid1), .ep0_in_start_o(ep0_in_start),
    .ep0_rd_o(ep0_rd), .ep0_data_i(ep0_data), .ep0_in_ack_o(ep0_in_ack),
    .ep0_out_stall_i(ep0_out_stall), .ep0_out_ack_o(ep0_out_ack),
    .out_room_i(out_room), .out_begin_o(out_begin), .out_valid_o(out_wvalid), .out_byte_o(out_wbyte),
    .out_commit_o(out_commit), .out_abort_o(out_abort),
    .in_has_pkt_i(in_has_pkt), .in_len_i(in_len), .in_start_o(in_start), .in_rd_o(in_rd),
    .in_data_i(in_rdata), .in_ack_o(in_ack), .in_drop_o(in_drop)
  );

  ms_usb_ep0 #(.SERIAL(SERIAL)) u_ep0 (
    .clk_i(clk_i), .rst_i(rst_i), .bus_reset_i(bus_reset),
    .setup_begin_i(ep0_setup_begin), .setup_valid_i(ep0_setup_valid), .setup_byte_i(ep0_setup_byte),
    .setup_i(ep0_setup), .in_stall_o(ep0_in_stall), .in_len_o(ep0_in_len),
    .in_pid1_o(ep0_in_pid1), .in_start_i(ep0_in_start), .rd_i(ep0_rd), .data_o(ep0_data),
    .in_ack_i(ep0_in_ack), .out_stall_o(ep0_out_stall), .out_ack_i(ep0_out_ack),
    .addr_o(addr), .configured_o(configured), .halt_o(halt), .toggle_rst_o(toggle_rst)
  );

  ms_usb_ep_out #(.DEPTH(OUT_DEPTH)) u_ep_out (
    .clk_i(clk_i), .rst_i(rst_i), .room_o(out_room), .wr_begin_i(out_begin), .wr_valid_i(out_wvalid),
    .wr_byte_i(out_wbyte), .wr_commit_i(out_commit), .wr_abort_i(out_abort),
    .out_data_o(out_data_o), .out_valid_o(out_valid_o), .out_last_o(out_last_o),
    .out_end_o(out_end_o), .out_zlp_o(out_zlp_o), .out_ready_i(out_ready_i)
  );

  ms_usb_ep_in #(.DEPTH(IN_DEPTH)) u_ep_in (
    .clk_i(clk_i), .rst_i(rst_i), .in_data_i(in_data_i), .in_valid_i(in_valid_i),
    .in_ready_o(in_ready_o), .in_flush_i(in_flush_i), .has_pkt_o(in_has_pkt), .len_o(in_len),
    .start_i(in_start), .start_len_i(tx_len), .rd_i(in_rd), .data_o(in_rdata), .ack_i(in_ack), .drop_pending_i(in_drop)
  );

  always_ff @(posedge clk_i) begin
    if (rst_i) usb_pullup_o <= 1'b0;
    else       usb_pullup_o <= 1'b1;
  end
  assign configured_o = configured;
  assign bus_reset_o  = bus_reset;
endmodule
