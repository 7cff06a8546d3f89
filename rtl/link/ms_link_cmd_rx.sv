// ms_link_cmd_rx: command receive buffer between the USB bulk OUT endpoint (ms_usb_device
// out_*) and the firmware (SoC registers CMD_STATUS / CMD_DATA / CMD_CTRL).
//
// Each OUT transfer (bytes up to the short packet or zero-length packet that ends it,
// docs/protocol.md section 1) is packed little-endian into 32-bit words, starting at a word
// boundary (the last word zero-padded), in a RAM of 2^DEPTH_W words. When the transfer ends,
// its byte count, word count and CRC verdict go into a small descriptor FIFO; the firmware
// sees the oldest complete transfer (avail_o, bytes_o, crc_ok_o, overlong_o), pops its words
// with rd_i and releases it with next_i (words it did not read are skipped).
// - bytes_o counts every byte of the transfer (saturating at 65535). At most MAX_BYTES are
//   stored; the rest are counted, not stored, and overlong_o is set (the firmware answers
//   BAD_LENGTH): a transfer of any length never blocks the endpoint.
// - crc_ok_o: the CRC-32 register run over all bytes of the transfer ends at the residue,
//   i.e. the last four bytes are the CRC-32 of the ones before (the firmware still checks
//   the header; with fewer than 4 bytes crc_ok_o is meaningless).
//
// Timing contract: one clock, synchronous rst_i. out_* is first-word-fall-through: an entry
// moves on a clock with out_valid_i and out_ready_o high. out_ready_o is low while the RAM has
// no free word or the descriptor FIFO is full (the endpoint then NAKs the host). rd_i (one
// clock) pops a word: rd_ack_o follows one clock later with rd_data_o (0 when the transfer
// has no word left or none is available). next_i (one clock) releases the current transfer.
// A transfer is visible on avail_o the clock after its last entry was taken.
module ms_link_cmd_rx #(
  parameter int DEPTH_W   = 9,     // RAM: 2^DEPTH_W words
  parameter int MAX_BYTES = 1088,  // bytes stored per transfer (17 packets of 64)
  parameter int DESC_W    = 2      // descriptor FIFO: 2^DESC_W complete transfers
) (
  input  logic        clk_i,
  input  logic        rst_i,
  // USB bulk OUT endpoint
  input  logic        out_valid_i,
  input  logic [7:0]  out_data_i,
  input  logic        out_end_i,
  input  logic        out_zlp_i,
  output logic        out_ready_o,
  // firmware
  output logic        avail_o,
  output logic [15:0] bytes_o,
  output logic        crc_ok_o,
  output logic        overlong_o,
  input  logic        rd_i,
  output logic        rd_ack_o,
  output logic [31:0] rd_data_o,
  input  logic        next_i
);
  import ms_link_pkg::*;
  localparam int DEPTH = 1 << DEPTH_W;
  localparam int NDESC = 1 << DESC_W;
  localparam int WW    = DEPTH_W + 1;  // word counts and pointers (one wrap bit)

  // ---- write side
  logic [31:0]  acc_q, word;
  logic [1:0]   nb_q;
  logic [15:0]  cnt_q;
  logic [31:0]  crc_q, crc_n;
  logic         ovl_q;
  logic [WW-1:0] wr_q, rd_q, xw_q, xw_p1_q;  // xw_p1_q = xw_q + 1: no adder before the descriptor write
  logic         take, store, wr_word, room, desc_full;
  logic [DESC_W:0] dw_q, dr_q;

  assign room      = (wr_q - rd_q) != WW'(DEPTH);
  assign desc_full = (dw_q - dr_q) == (DESC_W + 1)'(NDESC);
  assign out_ready_o = room && !desc_full;
  assign take      = out_valid_i && out_ready_o;
  assign store     = take && !out_zlp_i && (cnt_q < 16'(MAX_BYTES));
  assign crc_n     = out_zlp_i ? crc_q : crc32_byte(crc_q, out_data_i);

  always_comb begin
    word = acc_q;
    if (store) word[8*nb_q +: 8] = out_data_i;
  end
  // a word goes to RAM when it is full, or partial at the end of the transfer
  assign wr_word = take && ((store && nb_q == 2'd3) || (out_end_i && (nb_q != 2'd0 || store)));

  // descriptor FIFO
  logic [15:0]   d_bytes_q [NDESC];
  logic [WW-1:0] d_words_q [NDESC];
  logic          d_crc_q   [NDESC];
  logic          d_ovl_q   [NDESC];

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      acc_q <= '0;
      nb_q  <= '0;
      cnt_q <= '0;
      crc_q <= CRC32_INIT;
      ovl_q <= 1'b0;
      wr_q  <= '0;
      xw_q  <= '0;
      xw_p1_q <= WW'(1);
      dw_q  <= '0;
    end else if (take) begin
      if (out_end_i) begin
        d_bytes_q[dw_q[DESC_W-1:0]] <= (out_zlp_i || cnt_q == 16'hFFFF) ? cnt_q : cnt_q + 16'd1;
        d_words_q[dw_q[DESC_W-1:0]] <= wr_word ? xw_p1_q : xw_q;
        d_crc_q[dw_q[DESC_W-1:0]]   <= crc_n == CRC32_RESIDUE;
        d_ovl_q[dw_q[DESC_W-1:0]]   <= ovl_q || (!out_zlp_i && !store);
        dw_q  <= dw_q + 1'b1;
        acc_q <= '0;
        nb_q  <= '0;
        cnt_q <= '0;
        crc_q <= CRC32_INIT;
        ovl_q <= 1'b0;
        xw_q  <= '0;
        xw_p1_q <= WW'(1);
      end else begin
        if (!out_zlp_i && cnt_q != 16'hFFFF) cnt_q <= cnt_q + 16'd1;
        crc_q <= crc_n;
        if (!out_zlp_i && !store) ovl_q <= 1'b1;
        if (store) begin
          acc_q <= (nb_q == 2'd3) ? 32'd0 : word;
          nb_q  <= nb_q + 2'd1;
        end
        if (wr_word) begin
          xw_q    <= xw_p1_q;
          xw_p1_q <= xw_p1_q + 1'b1;
        end
      end
      if (wr_word) wr_q <= wr_q + 1'b1;
    end
  end

  // ---- read side
  logic [WW-1:0] hrd_q, head_words;
  logic          ram_valid_q, rd_ok;
  logic [31:0]   ram_rdata, unused_rdata_a;

  assign avail_o    = dw_q != dr_q;
  assign bytes_o    = d_bytes_q[dr_q[DESC_W-1:0]];
  assign crc_ok_o   = d_crc_q[dr_q[DESC_W-1:0]];
  assign overlong_o = d_ovl_q[dr_q[DESC_W-1:0]];
  assign head_words = d_words_q[dr_q[DESC_W-1:0]];
  assign rd_ok      = rd_i && avail_o && (hrd_q != head_words);

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      rd_q        <= '0;
      hrd_q       <= '0;
      dr_q        <= '0;
      rd_ack_o    <= 1'b0;
      ram_valid_q <= 1'b0;
    end else begin
      rd_ack_o    <= rd_i;
      ram_valid_q <= rd_ok;
      if (rd_ok) begin
        rd_q  <= rd_q + 1'b1;
        hrd_q <= hrd_q + 1'b1;
      end else if (next_i && avail_o) begin
        rd_q  <= rd_q + (head_words - hrd_q);
        hrd_q <= '0;
        dr_q  <= dr_q + 1'b1;
      end
    end
  end
  assign rd_data_o = ram_valid_q ? ram_rdata : 32'd0;

  ms_ram_dp #(.WIDTH(32), .DEPTH(DEPTH)) u_ram (
    .clk_i     (clk_i),
    .we_a_i    (wr_word),
    .addr_a_i  (wr_q[DEPTH_W-1:0]),
    .wdata_a_i (word),
    .rdata_a_o (unused_rdata_a),
    .addr_b_i  (rd_q[DEPTH_W-1:0]),
    .rdata_b_o (ram_rdata)
  );
endmodule
