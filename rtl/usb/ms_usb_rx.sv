// ms_usb_rx: full-speed receive PHY: D+/D- synchroniser, clock/data recovery, NRZI decode,
// bit unstuffing, SYNC and EOP detection, SE0 bus-reset detection.
//
// Timing contract (clk_i = 48 MHz, 4 samples per 12 Mbit/s bit):
// - dp_i/dn_i are asynchronous; two flip-flops synchronise them (2 clocks of latency).
// - Clock recovery is an edge-aligned DPLL: every change of D+ or D- restarts a 4-clock phase
//   counter and the line is sampled 2 clocks after the edge was seen (mid-bit). Bit stuffing
//   guarantees an edge at least every 7 bits, so a +-0.25 % host clock drifts < 0.1 clock
//   between edges; +-1 clock of edge jitter is tolerated.
// - start_o pulses when a SYNC (>= 3 alternating bits then the KK) is recognised; then
//   byte_valid_o pulses once per received byte (LSB first on the wire) with byte_o; the packet
//   ends with exactly one pulse of eop_o (SE0 then J, whole number of bytes) or err_o (bit-stuff
//   error, SE1, K during EOP or an EOP not on a byte boundary).
// - block_i (the device is transmitting) holds the receiver idle: its own packets are not seen.
// - bus_reset_o is high while SE0 has lasted >= RESET_CYCLES clocks (120 = 2.5 us).
module ms_usb_rx #(
  parameter int RESET_CYCLES = 120
) (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       dp_i,
  input  logic       dn_i,
  input  logic       block_i,
  output logic       start_o,
  output logic       byte_valid_o,
  output logic [7:0] byte_o,
  output logic       eop_o,
  output logic       err_o,
  output logic       bus_reset_o
);
  import ms_usb_pkg::*;

  typedef enum logic [2:0] {S_IDLE, S_SYNC, S_DATA, S_EOP, S_ERR} state_e;

  // synchroniser (dp/dn_q[1] is the synchronised level, [2] the previous one)
  logic [2:0] dp_q, dn_q;
  always_ff @(posedge clk_i) begin
    dp_q <= {dp_q[1:0], dp_i};
    dn_q <= {dn_q[1:0], dn_i};
  end

  // DPLL: phase counter restarted by an edge; sample when it reads 1 (2 clocks after). Edges in
  // the 2 clocks after a restart belong to the same transition (D+/D- skew: the lines cross
  // through SE0/SE1) and are ignored, so the sample stays 2 clocks after the first one.
  logic [1:0] phase_q, age_q;
  logic       edge_seen, resync, sample;
  assign edge_seen = (dp_q[1] ^ dp_q[2]) | (dn_q[1] ^ dn_q[2]);
  assign resync    = edge_seen && (age_q == 2'd2);
  assign sample    = (phase_q == 2'd1);
  always_ff @(posedge clk_i) begin
    if (rst_i || resync) begin
      phase_q <= 2'd0;
      age_q   <= 2'd0;
    end else begin
      phase_q <= phase_q + 2'd1;
      if (age_q != 2'd2) age_q <= age_q + 2'd1;
    end
  end

  // bus reset: SE0 held long enough
  localparam int RCW = $clog2(RESET_CYCLES + 1);
  logic [RCW-1:0] se0_cnt_q;
  always_ff @(posedge clk_i) begin
    if (rst_i || dp_q[1] || dn_q[1]) se0_cnt_q <= '0;
    else if (se0_cnt_q != RCW'(RESET_CYCLES)) se0_cnt_q <= se0_cnt_q + 1'b1;
  end
  assign bus_reset_o = (se0_cnt_q == RCW'(RESET_CYCLES));

  state_e     state_q;
  logic [1:0] sym, prev_q;
  logic [2:0] ones_q, bitcnt_q, run_q;
  logic [3:0] zeros_q;
  logic [6:0] sh_q;
  logic       aligned_q, se0_seen_q, bit_v;
  assign sym   = {dp_q[1], dn_q[1]};
  assign bit_v = (sym == prev_q);

  always_ff @(posedge clk_i) begin
    start_o      <= 1'b0;
    byte_valid_o <= 1'b0;
    eop_o        <= 1'b0;
    err_o        <= 1'b0;
    if (rst_i || block_i) begin
      state_q    <= S_IDLE;
      prev_q     <= SYM_J;
      ones_q     <= '0;
      bitcnt_q   <= '0;
      zeros_q    <= '0;
      run_q      <= '0;
      sh_q       <= '0;
      aligned_q  <= 1'b0;
      se0_seen_q <= 1'b0;
      byte_o     <= '0;
    end else if (sample) begin
      case (state_q)
        S_IDLE: begin
          if (sym == SYM_K) begin
            state_q <= S_SYNC;
            prev_q  <= SYM_K;
            zeros_q <= 4'd1;
          end
        end
        S_SYNC: begin
          if (sym == SYM_SE0 || sym == 2'b11) begin
            state_q <= S_IDLE;
          end else if (bit_v) begin
            // the KK that ends SYNC; its 1 counts towards bit stuffing
            if (zeros_q >= 4'd3) begin
              state_q  <= S_DATA;
              start_o  <= 1'b1;
              ones_q   <= 3'd1;
              bitcnt_q <= '0;
            end else begin
              state_q <= S_IDLE;
            end
          end else begin
            prev_q <= sym;
            if (zeros_q != 4'd15) zeros_q <= zeros_q + 4'd1;
          end
        end
        S_DATA: begin
          if (sym == SYM_SE0) begin
            state_q    <= S_EOP;
            aligned_q  <= (bitcnt_q == 3'd0);
          end else if (sym == 2'b11) begin
            state_q    <= S_ERR;
            err_o      <= 1'b1;
            run_q      <= '0;
            se0_seen_q <= 1'b0;
          end else begin
            prev_q <= sym;
            if (ones_q == 3'd6) begin
              if (bit_v) begin  // seventh 1: bit-stuff error
                state_q    <= S_ERR;
                err_o      <= 1'b1;
                run_q      <= '0;
                se0_seen_q <= 1'b0;
              end
              ones_q <= '0;     // stuffed 0 dropped
            end else begin
              ones_q   <= bit_v ? ones_q + 3'd1 : 3'd0;
              sh_q     <= {bit_v, sh_q[6:1]};
              bitcnt_q <= bitcnt_q + 3'd1;
              if (bitcnt_q == 3'd7) begin
                byte_valid_o <= 1'b1;
                byte_o       <= {bit_v, sh_q};
              end
            end
          end
        end
        S_EOP: begin
          if (sym == SYM_J) begin
            state_q <= S_IDLE;
            prev_q  <= SYM_J;
            if (aligned_q) eop_o <= 1'b1;
            else           err_o <= 1'b1;
          end else if (sym != SYM_SE0) begin
            state_q    <= S_ERR;
            err_o      <= 1'b1;
            run_q      <= '0;
            se0_seen_q <= 1'b0;
          end
        end
        default: begin  // S_ERR: wait for an EOP or 8 J bits of idle
          if (sym == SYM_SE0) se0_seen_q <= 1'b1;
          if (sym == SYM_J) run_q <= (run_q == 3'd7) ? run_q : run_q + 3'd1;
          else              run_q <= '0;
          if (sym == SYM_J && (se0_seen_q || run_q == 3'd7)) begin
            state_q <= S_IDLE;
            prev_q  <= SYM_J;
          end
        end
      endcase
    end
  end

endmodule
