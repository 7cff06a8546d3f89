// ms_sched_workq: the scheduler's per-tick work queue (docs/sonar_core.md, ms_scheduler).
//
// A small synchronous FIFO of WIDTH-bit words (one word per tick in which something
// happened: {tick, edge vector, close vector}). Storage is a plain array with one write and
// one asynchronous read port (distributed RAM); DEPTH is a power of two.
//
// Timing contract: a word presented with push_i on a clock edge is visible at head_o from
// the next cycle (empty_o low). pop_i on a clock edge with empty_o low removes the head.
// push_i while full drops the word and raises overflow_o (sticky until rst_i): the
// scheduler can no longer match the golden model and says so.
module ms_sched_workq #(
  parameter int WIDTH = 80,
  parameter int DEPTH = 16,
  localparam int AW = $clog2(DEPTH)
) (
  input  logic             clk_i,
  input  logic             rst_i,
  input  logic             push_i,
  input  logic [WIDTH-1:0] data_i,
  input  logic             pop_i,
  output logic [WIDTH-1:0] head_o,
  output logic             empty_o,
  output logic             overflow_o
);
  logic [WIDTH-1:0] mem_q [DEPTH];
  logic [AW:0]      wr_q, rd_q;
  logic             ovf_q;
  logic             full;

  assign full    = (wr_q[AW-1:0] == rd_q[AW-1:0]) && (wr_q[AW] != rd_q[AW]);
  assign empty_o = (wr_q == rd_q);
  assign head_o  = mem_q[rd_q[AW-1:0]];
  assign overflow_o = ovf_q;

  always_ff @(posedge clk_i) begin
    if (push_i && !full) mem_q[wr_q[AW-1:0]] <= data_i;
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      wr_q  <= '0;
      rd_q  <= '0;
      ovf_q <= 1'b0;
    end else begin
      if (push_i) begin
        if (full) ovf_q <= 1'b1;
        else      wr_q  <= wr_q + 1'b1;
      end
      if (pop_i && !empty_o) rd_q <= rd_q + 1'b1;
    end
  end
endmodule
