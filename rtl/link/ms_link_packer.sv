// ms_link_packer: turns the packets of two ms_link_txq queues (replies, frames) into bulk IN
// transfers of the USB device core (ms_usb_device in_*): the packet's 12 + length bytes
// (length from its header, bits 31:16 of word 1), then the CRC-32 it computes over them
// (docs/protocol.md section 2), then an in_flush pulse, so every packet ends with a short
// packet or a zero-length packet and is exactly one USB transfer.
//
// Between packets (and only there) it picks the next one: a committed reply first, else a
// committed frame (docs/protocol.md section 3: replies go ahead of queued frames at transfer
// boundaries). A pending frame discard (ms_link_txq discard_i) is carried out there first.
//
// Timing contract: one clock, synchronous rst_i. Queue side: start (one clock) when a packet
// is begun, rd (one clock) per word, the word arrives one clock later (ms_link_txq rdata_o).
// USB side: in_valid_o / in_data_o move on clocks with in_ready_i; in_flush_o is one clock,
// after the packet's last byte was taken. Throughput: 4 bytes per 5 clocks at best, far above
// the 1.5 MB/s of full speed. sent_o pulses (one clock) when a packet of queue sent_frame_o
// (0 reply, 1 frame) was handed over whole.
module ms_link_packer (
  input  logic        clk_i,
  input  logic        rst_i,
  // reply queue
  input  logic        rep_have_i,
  output logic        rep_start_o,
  output logic        rep_rd_o,
  input  logic [31:0] rep_rdata_i,
  // frame queue
  input  logic        frm_have_i,
  output logic        frm_start_o,
  output logic        frm_rd_o,
  input  logic [31:0] frm_rdata_i,
  output logic        boundary_o,   // between packets: a pending frame discard may happen now
  // USB bulk IN
  output logic        in_valid_o,
  output logic [7:0]  in_data_o,
  input  logic        in_ready_i,
  output logic        in_flush_o,
  output logic        sent_o,
  output logic        sent_frame_o
);
  import ms_link_pkg::*;
  typedef enum logic [2:0] {S_IDLE, S_FETCH, S_BYTES, S_CRC, S_FLUSH} state_e;
  state_e      state_q;
  logic        sel_q;        // 0 reply, 1 frame
  logic [31:0] word_q, crc_q;
  logic [1:0]  bi_q;         // byte index within word_q / the CRC
  logic [10:0] left_q;       // bytes of header + payload not yet sent
  logic [1:0]  wi_q;         // index of the next word fetched, saturating at 2
  logic [31:0] rdata;
  logic        fire;

  // The queue's RAM shows its head word continuously (one clock after its read pointer
  // moved): S_FETCH latches it and pops it; the next fetch is >= 4 clocks later.
  assign rdata      = sel_q ? frm_rdata_i : rep_rdata_i;
  assign boundary_o = state_q == S_IDLE;
  assign fire       = in_valid_o && in_ready_i;

  always_comb begin
    in_valid_o = 1'b0;
    in_data_o  = word_q[8*bi_q +: 8];
    if (state_q == S_BYTES) in_valid_o = 1'b1;
    if (state_q == S_CRC) begin
      in_valid_o = 1'b1;
      in_data_o  = ~crc_q[8*bi_q +: 8];
    end
  end

  always_ff @(posedge clk_i) begin
    rep_start_o <= 1'b0;
    frm_start_o <= 1'b0;
    rep_rd_o    <= 1'b0;
    frm_rd_o    <= 1'b0;
    in_flush_o  <= 1'b0;
    sent_o      <= 1'b0;
    if (rst_i) begin
      state_q      <= S_IDLE;
      sel_q        <= 1'b0;
      word_q       <= '0;
      crc_q        <= CRC32_INIT;
      bi_q         <= '0;
      left_q       <= '0;
      wi_q         <= '0;
      sent_frame_o <= 1'b0;
    end else begin
      case (state_q)
        S_IDLE: begin
          // a discard pending in the frame queue happens in this clock (boundary_o)
          if (rep_have_i || frm_have_i) begin
            sel_q       <= !rep_have_i;
            rep_start_o <= rep_have_i;
            frm_start_o <= !rep_have_i;
            crc_q       <= CRC32_INIT;
            left_q      <= 11'(HEADER_BYTES);
            wi_q        <= '0;
            state_q     <= S_FETCH;
          end
        end
        S_FETCH: begin
          word_q   <= rdata;
          rep_rd_o <= !sel_q;
          frm_rd_o <= sel_q;
          bi_q     <= '0;
          if (wi_q != 2'd2) wi_q <= wi_q + 2'd1;
          // word 1 (bytes 4..7): its bits 31:16 are the payload length (<= 1024, ms_link_txq)
          if (wi_q == 2'd1) left_q <= left_q + 11'(rdata[26:16]);
          state_q  <= S_BYTES;
        end
        S_BYTES: begin
          if (fire) begin
            crc_q  <= crc32_byte(crc_q, in_data_o);
            bi_q   <= bi_q + 2'd1;
            left_q <= left_q - 11'd1;
            if (left_q == 11'd1) begin
              state_q <= S_CRC;
              bi_q    <= '0;
            end else if (bi_q == 2'd3) begin
              state_q <= S_FETCH;
            end
          end
        end
        S_CRC: begin
          if (fire) begin
            bi_q <= bi_q + 2'd1;
            if (bi_q == 2'd3) state_q <= S_FLUSH;
          end
        end
        default: begin  // S_FLUSH
          in_flush_o   <= 1'b1;
          sent_o       <= 1'b1;
          sent_frame_o <= sel_q;
          state_q      <= S_IDLE;
        end
      endcase
    end
  end
endmodule
