// ms_sched_div: the scheduler engine's divider unit (docs/sched_engine.md): floor(x / n) for
// the order search (T_s = floor((te_min - T_V - D) / n)), a restoring divider that produces
// one quotient bit per clock. Its golden model is multisonar.tools.sched_program.DivUnit.
//
// Timing contract (clocks of clk_i):
//   - start_i (one clock, with x_i and n_i): busy_o is high from the next clock for XW clocks;
//     q_o = floor(x_i / n_i) from the clock busy_o falls until the next start_i. n_i = 0
//     divides by 1. A start while busy restarts the division.
//   - So the quotient is ready XW + 1 clocks after the start clock: within the engine's
//     DIV_LATENCY (26) for XW = 24.
module ms_sched_div #(
  parameter int XW = 24,  // dividend width
  parameter int NW = 4,   // divisor width
  localparam int CW = $clog2(XW + 1)
) (
  input  logic          clk_i,
  input  logic          rst_i,
  input  logic          start_i,
  input  logic [XW-1:0] x_i,
  input  logic [NW-1:0] n_i,
  output logic          busy_o,
  output logic [XW-1:0] q_o
);
  logic [XW-1:0] q_q, q_d;     // dividend bits still to come, then the quotient (shifted in)
  logic [NW-1:0] n_q, n_d;
  logic [NW:0]   r_q, r_d;     // partial remainder (< n, one bit wider while a bit enters)
  logic [CW-1:0] cnt_q, cnt_d; // quotient bits still to produce
  logic [NW:0]   r_sh;

  // two-process: the next state from the current one, then registers only
  always_comb begin
    q_d   = q_q;
    n_d   = n_q;
    r_d   = r_q;
    cnt_d = cnt_q;
    r_sh  = {r_q[NW-1:0], q_q[XW-1]};
    if (start_i) begin
      q_d   = x_i;
      n_d   = (n_i == '0) ? NW'(1) : n_i;
      r_d   = '0;
      cnt_d = CW'(XW);
    end else if (cnt_q != '0) begin
      if (r_sh >= {1'b0, n_q}) begin
        r_d = r_sh - {1'b0, n_q};
        q_d = {q_q[XW-2:0], 1'b1};
      end else begin
        r_d = r_sh;
        q_d = {q_q[XW-2:0], 1'b0};
      end
      cnt_d = cnt_q - CW'(1);
    end
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      cnt_q <= '0;
    end else begin
      cnt_q <= cnt_d;
    end
    q_q <= q_d;
    n_q <= n_d;
    r_q <= r_d;
  end

  assign busy_o = cnt_q != '0;
  assign q_o    = q_q;
endmodule
