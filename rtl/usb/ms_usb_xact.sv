// ms_usb_xact: transaction engine (protocol layer) of the device: token dispatch with address
// and endpoint match, data-packet routing, handshakes (ACK/NAK/STALL), DATA0/DATA1 toggles of
// the bulk endpoints, turnaround and time-outs.
//
// Timing contract (48 MHz clocks):
// - A good token for our address is acted on the clock after tok_valid_i; tokens for other
//   addresses, unknown endpoints or EP1 while unconfigured are ignored (the host times out).
// - Responses start TURN_CLKS clocks after the token / data packet was decoded, which puts the
//   SYNC 2.5..3.5 bit times after the host's EOP (USB: >= 2, <= 6.5 bit times).
// - After SETUP/OUT tokens the data packet must start within RX_TIMEOUT clocks; after sending
//   data the engine waits ACK_TIMEOUT clocks (after the end of its own packet or the start of
//   the last packet heard) for the host's ACK. No ACK: nothing is freed and the same data are
//   sent again on the next IN (same toggle). A token arriving while waiting is served at once.
// - OUT EP1: NAK when the buffer had no room for 64 bytes at the token, STALL when halted, ACK
//   and drop when the toggle shows a repeated packet, ACK and commit otherwise; a bad CRC or a
//   payload > 64 bytes gets no handshake. SETUP always gets ACK when its packet is good.
// - bus_reset_i: idle, toggles DATA0, un-ACKed IN data kept for re-sending.
module ms_usb_xact #(
  parameter int TURN_CLKS   = 6,
  parameter int RX_TIMEOUT  = 100,
  parameter int ACK_TIMEOUT = 160
) (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       bus_reset_i,
  // ms_usb_pkt_rx
  input  logic       pkt_start_i,
  input  logic       tok_valid_i,
  input  logic [3:0] tok_pid_i,
  input  logic [6:0] tok_addr_i,
  input  logic [3:0] tok_ep_i,
  input  logic       dat_start_i,
  input  logic       dat_pid1_i,
  input  logic       dat_valid_i,
  input  logic [7:0] dat_byte_i,
  input  logic       dat_end_i,
  input  logic       dat_ok_i,
  input  logic       hs_valid_i,
  input  logic [3:0] hs_pid_i,
  // ms_usb_tx
  output logic       tx_start_o,
  output logic [3:0] tx_pid_o,
  output logic       tx_with_data_o,
  output logic [6:0] tx_len_o,
  input  logic       tx_rd_i,
  output logic [7:0] tx_byte_o,
  input  logic       tx_done_i,
  // device state (ms_usb_ep0)
  input  logic [6:0] addr_i,
  input  logic       configured_i,
  input  logic [1:0] halt_i,
  input  logic [1:0] toggle_rst_i,
  // ms_usb_ep0
  output logic       ep0_setup_begin_o,
  output logic       ep0_setup_valid_o,
  output logic [7:0] ep0_setup_byte_o,
  output logic       ep0_setup_o,
  input  logic       ep0_in_stall_i,
  input  logic [6:0] ep0_in_len_i,
  input  logic       ep0_in_pid1_i,
  output logic       ep0_in_start_o,
  output logic       ep0_rd_o,
  input  logic [7:0] ep0_data_i,
  output logic       ep0_in_ack_o,
  input  logic       ep0_out_stall_i,
  output logic       ep0_out_ack_o,
  // ms_usb_ep_out
  input  logic       out_room_i,
  output logic       out_begin_o,
  output logic       out_valid_o,
  output logic [7:0] out_byte_o,
  output logic       out_commit_o,
  output logic       out_abort_o,
  // ms_usb_ep_in
  input  logic       in_has_pkt_i,
  input  logic [6:0] in_len_i,
  output logic       in_start_o,
  output logic       in_rd_o,
  input  logic [7:0] in_data_i,
  output logic       in_ack_o,
  output logic       in_drop_o
);
  import ms_usb_pkg::*;

  typedef enum logic [2:0] {X_IDLE, X_RXDATA, X_TURN, X_TX, X_WAITACK} state_e;
  typedef enum logic [2:0] {G_NONE, G_SETUP, G_EP0OUT, G_EP1OUT, G_EP0IN, G_EP1IN} tgt_e;

  state_e      state_q;
  tgt_e        tgt_q;
  logic [7:0]  timer_q;
  logic        dat_seen_q, room_q, ovf_q;
  logic [6:0]  dcount_q;
  logic        tog_out_q, tog_in_q;
  logic [3:0]  pid_q;
  logic        with_data_q;
  logic [6:0]  len_q;
  logic        for_us;
  assign for_us = tok_valid_i && (tok_addr_i == addr_i)
               && (state_q == X_IDLE || state_q == X_RXDATA || state_q == X_WAITACK);

  assign ep0_setup_valid_o = (state_q == X_RXDATA) && (tgt_q == G_SETUP) && dat_valid_i;
  assign ep0_setup_byte_o  = dat_byte_i;
  // written only when a whole packet fits (room_q, from the token): a NAKed packet never
  // overwrites bytes the application has not read yet
  assign out_valid_o       = (state_q == X_RXDATA) && (tgt_q == G_EP1OUT) && dat_valid_i
                          && room_q && dcount_q != 7'd64;
  assign out_byte_o        = dat_byte_i;
  assign ep0_rd_o          = (tgt_q == G_EP0IN) && tx_rd_i;
  assign in_rd_o           = (tgt_q == G_EP1IN) && tx_rd_i;
  assign tx_byte_o         = (tgt_q == G_EP1IN) ? in_data_i : ep0_data_i;
  assign tx_pid_o          = pid_q;
  assign tx_with_data_o    = with_data_q;
  assign tx_len_o          = len_q;

  // respond: go to the turnaround wait, then send pid (with data when wd)
  task automatic respond(input logic [3:0] pid, input logic wd, input logic [6:0] len);
    state_q     <= X_TURN;
    timer_q     <= '0;
    pid_q       <= pid;
    with_data_q <= wd;
    len_q       <= len;
  endtask

  always_ff @(posedge clk_i) begin
    tx_start_o        <= 1'b0;
    ep0_setup_begin_o <= 1'b0;
    ep0_setup_o       <= 1'b0;
    ep0_in_start_o    <= 1'b0;
    ep0_in_ack_o      <= 1'b0;
    ep0_out_ack_o     <= 1'b0;
    out_begin_o       <= 1'b0;
    out_commit_o      <= 1'b0;
    out_abort_o       <= 1'b0;
    in_start_o        <= 1'b0;
    in_ack_o          <= 1'b0;
    in_drop_o         <= 1'b0;
    if (rst_i || bus_reset_i) begin
      state_q     <= X_IDLE;
      tgt_q       <= G_NONE;
      timer_q     <= '0;
      dat_seen_q  <= 1'b0;
      room_q      <= 1'b0;
      ovf_q       <= 1'b0;
      dcount_q    <= '0;
      tog_out_q   <= 1'b0;
      tog_in_q    <= 1'b0;
      pid_q       <= '0;
      with_data_q <= 1'b0;
      len_q       <= '0;
      in_drop_o   <= 1'b1;
      out_abort_o <= 1'b1;
    end else begin
      if (toggle_rst_i[0]) tog_out_q <= 1'b0;
      if (toggle_rst_i[1]) tog_in_q  <= 1'b0;
      if (timer_q != 8'hFF) timer_q <= timer_q + 8'd1;

      if (for_us) begin
        // a token for us: served whatever we were waiting for
        if (state_q == X_RXDATA && tgt_q == G_EP1OUT) out_abort_o <= 1'b1;
        timer_q    <= '0;
        dat_seen_q <= 1'b0;
        dcount_q   <= '0;
        ovf_q      <= 1'b0;
        state_q    <= X_IDLE;
        tgt_q      <= G_NONE;
        case (tok_pid_i)
          PID_SETUP: if (tok_ep_i == 4'd0) begin
            state_q           <= X_RXDATA;
            tgt_q             <= G_SETUP;
            ep0_setup_begin_o <= 1'b1;
          end
          PID_OUT: begin
            if (tok_ep_i == 4'd0) begin
              state_q <= X_RXDATA;
              tgt_q   <= G_EP0OUT;
            end else if (tok_ep_i == 4'd1 && configured_i) begin
              state_q     <= X_RXDATA;
              tgt_q       <= G_EP1OUT;
              room_q      <= out_room_i;
              out_begin_o <= 1'b1;
            end
          end
          PID_IN: begin
            if (tok_ep_i == 4'd0) begin
              tgt_q <= G_EP0IN;
              if (ep0_in_stall_i) respond(PID_STALL, 1'b0, '0);
              else begin
                respond(ep0_in_pid1_i ? PID_DATA1 : PID_DATA0, 1'b1, ep0_in_len_i);
                ep0_in_start_o <= 1'b1;
              end
            end else if (tok_ep_i == 4'd1 && configured_i) begin
              tgt_q <= G_EP1IN;
              if (halt_i[1]) respond(PID_STALL, 1'b0, '0);
              else if (!in_has_pkt_i) respond(PID_NAK, 1'b0, '0);
              else begin
                respond(tog_in_q ? PID_DATA1 : PID_DATA0, 1'b1, in_len_i);
                in_start_o <= 1'b1;
              end
            end
          end
          default: ;
        endcase
      end else begin
        case (state_q)
          X_RXDATA: begin
            if (dat_start_i) dat_seen_q <= 1'b1;
            if (dat_valid_i) begin
              if (dcount_q == 7'd64) ovf_q <= 1'b1;
              else                   dcount_q <= dcount_q + 7'd1;
            end
            if (dat_end_i) begin
              state_q <= X_IDLE;
              if (!dat_ok_i || ovf_q) begin
                if (tgt_q == G_EP1OUT) out_abort_o <= 1'b1;
              end else begin
                case (tgt_q)
                  G_SETUP: if (!dat_pid1_i) begin
                    ep0_setup_o <= 1'b1;
                    respond(PID_ACK, 1'b0, '0);
                  end
                  G_EP0OUT: begin
                    if (ep0_out_stall_i) respond(PID_STALL, 1'b0, '0);
                    else begin
                      respond(PID_ACK, 1'b0, '0);
                      ep0_out_ack_o <= 1'b1;
                    end
                  end
                  default: begin  // G_EP1OUT
                    if (halt_i[0]) begin
                      out_abort_o <= 1'b1;
                      respond(PID_STALL, 1'b0, '0);
                    end else if (!room_q) begin
                      out_abort_o <= 1'b1;
                      respond(PID_NAK, 1'b0, '0);
                    end else if (dat_pid1_i != tog_out_q) begin
                      out_abort_o <= 1'b1;   // repeated packet: our ACK was lost
                      respond(PID_ACK, 1'b0, '0);
                    end else begin
                      out_commit_o <= 1'b1;
                      tog_out_q    <= ~tog_out_q;
                      respond(PID_ACK, 1'b0, '0);
                    end
                  end
                endcase
              end
            end else if (hs_valid_i || (!dat_seen_q && timer_q == 8'(RX_TIMEOUT))) begin
              state_q <= X_IDLE;
              if (tgt_q == G_EP1OUT) out_abort_o <= 1'b1;
            end
          end
          X_TURN: begin
            if (timer_q == 8'(TURN_CLKS)) begin
              state_q    <= X_TX;
              tx_start_o <= 1'b1;
            end
          end
          X_TX: begin
            if (tx_done_i) begin
              state_q <= with_data_q ? X_WAITACK : X_IDLE;
              timer_q <= '0;
            end
          end
          X_WAITACK: begin
            if (pkt_start_i) timer_q <= '0;
            if (hs_valid_i) begin
              state_q <= X_IDLE;
              if (hs_pid_i == PID_ACK) begin
                if (tgt_q == G_EP1IN) begin
                  in_ack_o <= 1'b1;
                  tog_in_q <= ~tog_in_q;
                end else begin
                  ep0_in_ack_o <= 1'b1;
                end
              end
            end else if (dat_end_i || timer_q == 8'(ACK_TIMEOUT)) begin
              state_q <= X_IDLE;
            end
          end
          default: ;
        endcase
      end
    end
  end
endmodule
