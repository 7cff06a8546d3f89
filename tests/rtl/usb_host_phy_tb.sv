// usb_host_phy_tb: wire-level USB host model for the cocotb tests of the USB device core.
// Keeps all per-bit work out of Python: Python hands over a whole packet as line symbols and
// gets the device's answer back as sampled line symbols (tests/rtl/usb_host.py encodes/decodes).
//
// Runs on its own clock hclk_i = 4x the host's bit rate (48 MHz * (1 + clock error)), so the
// host's bit timing is independent of the device clock.
// - go_i high (while done_o is low): send tx_nsym_i symbols from tx_syms_i (2 bits each, symbol
//   i at [2i+1:2i]: 0 SE0, 1 J, 2 K, 3 bus released), one per 4 hclk, then release the bus.
//   With listen_i != 0 the host then waits up to listen_i bit times for a packet from the device
//   and records it (rx_syms_o, rx_nsym_o: symbols sampled mid-bit by an edge-aligned DPLL, from
//   the first K to the J after SE0); resp_delay_o counts hclk from the bus release to that
//   first K (synchroniser latency included). done_o goes high at the end, low after go_i low.
// - skew_i (0..3): D- reaches the bus skew_i hclk later than D+ (single-ended receivers on an
//   FPGA see such skew as short SE0/SE1 states at every transition).
module usb_host_phy_tb #(
  parameter int NSYM = 1024
) (
  input  logic              hclk_i,
  input  logic              go_i,
  input  logic [2*NSYM-1:0] tx_syms_i,
  input  logic [15:0]       tx_nsym_i,
  input  logic [15:0]       listen_i,
  input  logic [1:0]        skew_i,
  output logic              done_o,
  output logic [2*NSYM-1:0] rx_syms_o,
  output logic [15:0]       rx_nsym_o,
  output logic [15:0]       resp_delay_o,
  input  logic              bus_dp_i,
  input  logic              bus_dn_i,
  output logic              dp_o,
  output logic              dn_o,
  output logic              oe_o
);
  logic dn_q = 1'b0;           // undelayed D- (dn_o is it after skew_i hclk)
  logic [2:0] dn_dly = '0;
  always_ff @(posedge hclk_i) dn_dly <= {dn_dly[1:0], dn_q};
  always_comb begin
    case (skew_i)
      2'd0:    dn_o = dn_q;
      2'd1:    dn_o = dn_dly[0];
      2'd2:    dn_o = dn_dly[1];
      default: dn_o = dn_dly[2];
    endcase
  end
  typedef enum logic [1:0] {H_IDLE, H_TX, H_LISTEN, H_RX} state_e;
  state_e      state_q = H_IDLE;
  logic [1:0]  div_q = '0, phase_q = '0;
  logic [15:0] idx_q = '0;
  logic [19:0] timer_q = '0;
  logic [2:0]  dp_s = '0, dn_s = '0;
  logic        se0_seen_q = 1'b0;
  logic [1:0]  sym;
  logic        edge_seen;

  initial begin
    done_o = 1'b0; oe_o = 1'b0; dp_o = 1'b1;
    rx_syms_o = '0; rx_nsym_o = '0; resp_delay_o = '0;
  end

  always_ff @(posedge hclk_i) begin
    dp_s <= {dp_s[1:0], bus_dp_i};
    dn_s <= {dn_s[1:0], bus_dn_i};
  end
  assign sym       = {dp_s[1], dn_s[1]};
  assign edge_seen = (dp_s[1] ^ dp_s[2]) | (dn_s[1] ^ dn_s[2]);

  always_ff @(posedge hclk_i) begin
    case (state_q)
      H_IDLE: begin
        if (!go_i) done_o <= 1'b0;
        else if (!done_o) begin
          state_q   <= H_TX;
          idx_q     <= '0;
          div_q     <= '0;
          rx_nsym_o <= '0;
          rx_syms_o <= '0;
          resp_delay_o <= '0;
        end
      end
      H_TX: begin
        div_q <= div_q + 2'd1;
        if (div_q == 2'd0) begin
          if (idx_q == tx_nsym_i) begin
            oe_o    <= 1'b0;
            timer_q <= '0;
            if (listen_i == 16'd0) begin
              state_q <= H_IDLE;
              done_o  <= 1'b1;
            end else begin
              state_q <= H_LISTEN;
            end
          end else begin
            case (tx_syms_i[2*idx_q +: 2])
              2'd0: begin oe_o <= 1'b1; dp_o <= 1'b0; dn_q <= 1'b0; end
              2'd1: begin oe_o <= 1'b1; dp_o <= 1'b1; dn_q <= 1'b0; end
              2'd2: begin oe_o <= 1'b1; dp_o <= 1'b0; dn_q <= 1'b1; end
              default: oe_o <= 1'b0;
            endcase
            idx_q <= idx_q + 16'd1;
          end
        end
      end
      H_LISTEN: begin
        timer_q <= timer_q + 20'd1;
        if (sym == 2'b01) begin       // first K: start of SYNC
          state_q      <= H_RX;
          resp_delay_o <= timer_q[15:0];
          phase_q      <= 2'd0;
          rx_nsym_o    <= '0;
          se0_seen_q   <= 1'b0;
        end else if (timer_q >= {2'b0, listen_i, 2'b00}) begin
          state_q <= H_IDLE;
          done_o  <= 1'b1;
        end
      end
      default: begin                  // H_RX
        phase_q <= edge_seen ? 2'd0 : phase_q + 2'd1;
        if (!edge_seen && phase_q == 2'd1) begin
          if (rx_nsym_o < 16'(NSYM)) begin
            rx_syms_o[2*rx_nsym_o +: 2] <= (sym == 2'b00) ? 2'd0 : (sym == 2'b10) ? 2'd1 :
                                           (sym == 2'b01) ? 2'd2 : 2'd3;
            rx_nsym_o <= rx_nsym_o + 16'd1;
          end
          if (sym == 2'b00) se0_seen_q <= 1'b1;
          if ((se0_seen_q && sym == 2'b10) || rx_nsym_o >= 16'(NSYM - 1)) begin
            state_q <= H_IDLE;
            done_o  <= 1'b1;
          end
        end
      end
    endcase
  end
endmodule
