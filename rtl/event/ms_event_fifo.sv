// ms_event_fifo: the sonar core's time-of-flight event FIFO. Nothing is lost silently.
//
// Timing contract:
//   - wr_i/wdata_i: a word is stored on the clock it is presented, unless the FIFO is full
//     (DEPTH words in the RAM): then it is dropped, overflow_o strobes, and the
//     next word that is stored carries bit OVF_BIT set ("events were dropped before me").
//     overflow_o is registered: it strobes on the clock after the dropped write.
//   - Read side is first-word-fall-through: rvalid_o/rdata_o show the oldest word; rd_i with
//     rvalid_o pops it. After a pop the next word appears two clocks later (one RAM read in
//     flight at a time), plenty for event rates of at most a few per microsecond.
//   - level_o counts every stored word not yet popped (RAM + the word in flight + head).
// Storage is one block RAM (ms_ram_dp: write on port A, read on port B).
module ms_event_fifo #(
  parameter int WIDTH   = 64,
  parameter int DEPTH_W = 9,   // 2^9 = 512 words, CAPS.fifo_depth_log2
  parameter int OVF_BIT = 44,
  parameter int LEVEL_W = 12
) (
  input  logic               clk_i,
  input  logic               rst_i,
  input  logic               wr_i,
  input  logic [WIDTH-1:0]   wdata_i,
  input  logic               rd_i,
  output logic               rvalid_o,
  output logic [WIDTH-1:0]   rdata_o,
  output logic               overflow_o,
  output logic [LEVEL_W-1:0] level_o
);
  localparam int DEPTH = 1 << DEPTH_W;

  logic [DEPTH_W:0]   wr_ptr_q, rd_ptr_q;  // one extra bit tells full from empty
  logic [DEPTH_W:0]   stored;              // words in the RAM
  logic               ovf_pending_q, overflow_q;
  logic               fetch_q;             // a RAM read was issued last clock
  logic               out_valid_q;
  logic [WIDTH-1:0]   out_data_q;
  logic [WIDTH-1:0]   ram_rdata, wdata_flagged;
  logic               full, accept, pop, fetch;
  logic [WIDTH-1:0]   unused_rdata_a;  // port A only writes

  assign stored = wr_ptr_q - rd_ptr_q;
  assign full   = stored[DEPTH_W];  // == DEPTH
  assign accept = wr_i & ~full;
  assign pop    = rd_i & out_valid_q;
  assign fetch  = (stored != '0) & ~fetch_q & (~out_valid_q | pop);

  always_comb begin
    wdata_flagged = wdata_i;
    wdata_flagged[OVF_BIT] = wdata_i[OVF_BIT] | ovf_pending_q;
  end

  ms_ram_dp #(.WIDTH(WIDTH), .DEPTH(DEPTH), .AW(DEPTH_W)) u_ram (
    .clk_i     (clk_i),
    .we_a_i    (accept),
    .addr_a_i  (wr_ptr_q[DEPTH_W-1:0]),
    .wdata_a_i (wdata_flagged),
    .rdata_a_o (unused_rdata_a),
    .addr_b_i  (rd_ptr_q[DEPTH_W-1:0]),
    .rdata_b_o (ram_rdata)
  );

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      wr_ptr_q      <= '0;
      rd_ptr_q      <= '0;
      ovf_pending_q <= 1'b0;
      overflow_q    <= 1'b0;
      fetch_q       <= 1'b0;
      out_valid_q   <= 1'b0;
      out_data_q    <= '0;
    end else begin
      overflow_q <= wr_i & full;
      if (accept) begin
        wr_ptr_q      <= wr_ptr_q + 1'b1;
        ovf_pending_q <= 1'b0;
      end else if (wr_i) begin
        ovf_pending_q <= 1'b1;
      end
      fetch_q <= fetch;
      if (fetch) rd_ptr_q <= rd_ptr_q + 1'b1;
      if (fetch_q) begin
        out_valid_q <= 1'b1;
        out_data_q  <= ram_rdata;
      end else if (pop) begin
        out_valid_q <= 1'b0;
      end
    end
  end

  assign rvalid_o   = out_valid_q;
  assign rdata_o    = out_data_q;
  assign overflow_o = overflow_q;
  assign level_o    = LEVEL_W'(stored) + LEVEL_W'(fetch_q) + LEVEL_W'(out_valid_q);
endmodule
