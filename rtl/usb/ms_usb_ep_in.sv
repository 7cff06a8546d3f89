// ms_usb_ep_in: transmit buffer of the bulk IN endpoint (EP 0x81) with retry and short/zero-
// length packets on flush.
//
// Timing contract:
// - Application side: in_valid_i/in_data_i, a byte is taken on a clock with in_ready_o high
//   (DEPTH bytes of storage). in_flush_i (pulse): send what is queued even if it is less than
//   64 bytes; when the data since the last short packet is an exact multiple of 64 a zero-length
//   packet follows. Without a flush only full 64-byte packets are sent.
// - Engine side (IN token): has_pkt_o (else NAK) and len_o are registered-state functions.
//   start_i begins a packet: a new one takes start_len_i bytes (the len_o the engine saw at the
//   token, so bytes arriving in between cannot change it), an un-ACKed one is re-sent with the
//   same bytes and length. rd_i (from ms_usb_tx) fetches the next byte; data_o has it
//   from the next clock until the next rd_i. ack_i (host ACKed) frees the bytes.
//   drop_pending_i (bus reset) forgets an un-ACKed packet (its bytes stay queued).
module ms_usb_ep_in #(
  parameter int DEPTH = 128,
  parameter int AW    = $clog2(DEPTH)
) (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic [7:0] in_data_i,
  input  logic       in_valid_i,
  output logic       in_ready_o,
  input  logic       in_flush_i,
  output logic       has_pkt_o,
  output logic [6:0] len_o,
  input  logic       start_i,
  input  logic [6:0] start_len_i,
  input  logic       rd_i,
  output logic [7:0] data_o,
  input  logic       ack_i,
  input  logic       drop_pending_i
);
  logic [7:0]  mem_q [DEPTH];
  logic [AW:0] wp_q, base_q, rp_q, count;
  logic        pend_q, flush_q, flush_late_q, last_full_q;
  logic [6:0]  pend_len_q, avail;

  assign count      = wp_q - base_q;
  assign in_ready_o = (count != (AW + 1)'(DEPTH));
  assign avail      = (count >= (AW + 1)'(64)) ? 7'd64 : count[6:0];
  assign has_pkt_o  = pend_q || (count >= (AW + 1)'(64)) || flush_q;
  assign len_o      = pend_q ? pend_len_q : avail;

  always_ff @(posedge clk_i) begin
    if (in_valid_i && in_ready_o) mem_q[wp_q[AW-1:0]] <= in_data_i;
    if (rd_i) data_o <= mem_q[rp_q[AW-1:0]];
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      wp_q         <= '0;
      base_q       <= '0;
      rp_q         <= '0;
      pend_q       <= 1'b0;
      pend_len_q   <= '0;
      flush_q      <= 1'b0;
      flush_late_q <= 1'b0;
      last_full_q  <= 1'b0;
    end else begin
      if (in_valid_i && in_ready_o) wp_q <= wp_q + 1'b1;
      if (in_flush_i) begin
        if (pend_q) flush_late_q <= 1'b1;
        if (count != '0 || last_full_q) flush_q <= 1'b1;
      end
      if (drop_pending_i) begin
        pend_q <= 1'b0;
      end else if (start_i) begin
        rp_q <= base_q;
        if (!pend_q) begin
          pend_q     <= 1'b1;
          pend_len_q <= start_len_i;
        end
      end else if (rd_i) begin
        rp_q <= rp_q + 1'b1;
      end else if (ack_i && pend_q) begin
        pend_q       <= 1'b0;
        base_q       <= base_q + (AW + 1)'(pend_len_q);
        last_full_q  <= (pend_len_q == 7'd64);
        flush_late_q <= 1'b0;
        if (pend_len_q != 7'd64) flush_q <= flush_late_q || in_flush_i;
      end
    end
  end
endmodule
