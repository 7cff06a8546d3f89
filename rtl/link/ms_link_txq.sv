// ms_link_txq: queue of whole protocol packets (header + payload, no CRC) from the firmware to
// the packer (ms_link_packer), with commit / roll-back, so a packet that does not fit is
// dropped whole and counted, never truncated.
//
// The firmware appends words (wr_i, wdata_i: header word 0, word 1 with the length in bits
// 31:16, word 2 seq, then the payload, the last word zero-padded) and then commits (commit_i).
// Only committed packets are visible to the packer. At the commit the packet is rolled back
// (its words forgotten, dropped_o pulses) if a word was written while the RAM was full or if
// the number of words differs from ceil((12 + length) / 4) or length > 1024 (the packer
// takes the packet size from the header: a malformed packet would desynchronise it).
// discard_i drops every packet committed so far that the packer has not started: the request
// is remembered and carried out when the packer is between packets (boundary_i), then
// discarded_o pulses with discarded_n_o packets; packets committed after the request stay.
//
// Timing contract: one clock, synchronous rst_i. The packer sees pkts_o (committed packets
// not started; valid the clock after the commit), says start_i (one clock) when it begins
// one, and pops its words with rd_i: rdata_o is the popped word one clock later. level_o:
// words held, committed or not.
module ms_link_txq #(
  parameter int DEPTH_W = 9
) (
  input  logic               clk_i,
  input  logic               rst_i,
  input  logic               wr_i,
  input  logic [31:0]        wdata_i,
  input  logic               commit_i,
  output logic               committed_o,
  output logic               dropped_o,
  input  logic               discard_i,
  input  logic               boundary_i,
  output logic               discarded_o,
  output logic [DEPTH_W:0]   discarded_n_o,
  output logic [DEPTH_W:0]   pkts_o,
  input  logic               start_i,
  input  logic               rd_i,
  output logic [31:0]        rdata_o,
  output logic [DEPTH_W:0]   level_o
);
  import ms_link_pkg::*;
  localparam int DEPTH = 1 << DEPTH_W;
  localparam int WW    = DEPTH_W + 1;

  logic [WW-1:0] wr_q, cm_q, rd_q, pkts_q, disc_ptr_q, disc_n_q;
  logic          ovf_q, disc_pend_q;
  logic [15:0]   len_q;
  logic          full, push, good, apply;
  logic [WW-1:0] n_words;
  logic [11:0]   want_words;
  logic [31:0]   unused_rdata_a;

  assign full       = (wr_q - rd_q) == WW'(DEPTH);
  assign push       = wr_i && !full;
  assign n_words    = wr_q - cm_q;
  assign want_words = 12'((32'(HEADER_BYTES) + 32'(len_q) + 32'd3) >> 2);
  assign good       = !ovf_q && (len_q <= 16'(MAX_PAYLOAD)) && (12'(n_words) == want_words)
                      && (32'(n_words) <= 32'(DEPTH));
  assign apply      = disc_pend_q && boundary_i;

  always_ff @(posedge clk_i) begin
    committed_o <= 1'b0;
    dropped_o   <= 1'b0;
    discarded_o <= 1'b0;
    if (rst_i) begin
      wr_q        <= '0;
      cm_q        <= '0;
      rd_q        <= '0;
      pkts_q      <= '0;
      ovf_q       <= 1'b0;
      len_q       <= '0;
      disc_pend_q <= 1'b0;
      disc_ptr_q  <= '0;
      disc_n_q    <= '0;
      discarded_n_o <= '0;
    end else begin
      // write side
      if (commit_i) begin
        if (good) begin
          cm_q        <= wr_q;
          committed_o <= 1'b1;
        end else begin
          wr_q      <= cm_q;
          dropped_o <= 1'b1;
        end
        ovf_q <= 1'b0;
        len_q <= '0;
      end else if (wr_i) begin
        if (full) ovf_q <= 1'b1;
        else begin
          wr_q <= wr_q + 1'b1;
          if (n_words == WW'(1)) len_q <= wdata_i[31:16];
        end
      end
      // packets: + commit, - start, - discarded
      pkts_q <= pkts_q + WW'(commit_i && good) - WW'(start_i) - (apply ? disc_n_q : WW'(0));
      // read side
      if (apply) begin
        rd_q          <= disc_ptr_q;
        disc_pend_q   <= 1'b0;
        discarded_o   <= 1'b1;
        discarded_n_o <= disc_n_q;
      end else if (rd_i) begin
        rd_q <= rd_q + 1'b1;
      end
      if (discard_i) begin
        disc_pend_q <= 1'b1;
        disc_ptr_q  <= cm_q;
        disc_n_q    <= pkts_q - WW'(start_i);
      end
    end
  end
  assign pkts_o  = pkts_q;
  assign level_o = wr_q - rd_q;

  ms_ram_dp #(.WIDTH(32), .DEPTH(DEPTH)) u_ram (
    .clk_i     (clk_i),
    .we_a_i    (push && !commit_i),
    .addr_a_i  (wr_q[DEPTH_W-1:0]),
    .wdata_a_i (wdata_i),
    .rdata_a_o (unused_rdata_a),
    .addr_b_i  (rd_q[DEPTH_W-1:0]),
    .rdata_b_o (rdata_o)
  );
endmodule
