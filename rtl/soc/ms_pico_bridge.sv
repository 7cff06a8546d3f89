// ms_pico_bridge: PicoRV32 native memory port -> PeakRDL passthrough register bus.
//
// Timing contract: while mem_valid_i is high and sel_i selects this bridge, the request
// (address, write data, strobes) is registered, and one bus request is issued from those
// registers in the next clock (held while the slave stalls), so no path runs from the CPU
// through the register block's decode. The bridge then takes rd_ack/wr_ack (in the request
// clock or any later one: the regblock answers some reads combinationally) and answers
// mem_ready_o for exactly one clock with the read data. A slave error still completes the
// access (read data 0) and strobes err_o, so a wrong address never hangs the CPU.
module ms_pico_bridge #(
  parameter int ADDR_W = 11
) (
  input  logic              clk_i,
  input  logic              rst_i,
  input  logic              sel_i,
  input  logic              mem_valid_i,
  input  logic [31:0]       mem_addr_i,
  input  logic [31:0]       mem_wdata_i,
  input  logic [3:0]        mem_wstrb_i,
  output logic              mem_ready_o,
  output logic [31:0]       mem_rdata_o,
  output logic              err_o,
  // passthrough master
  output logic              req_o,
  output logic              req_is_wr_o,
  output logic [ADDR_W-1:0] addr_o,
  output logic [31:0]       wr_data_o,
  output logic [31:0]       wr_biten_o,
  input  logic              req_stall_wr_i,
  input  logic              req_stall_rd_i,
  input  logic              rd_ack_i,
  input  logic              rd_err_i,
  input  logic [31:0]       rd_data_i,
  input  logic              wr_ack_i,
  input  logic              wr_err_i
);
  typedef enum logic [1:0] {IDLE, REQ, WAIT_ACK, DONE} state_e;
  state_e state_q;
  logic   stall, ack, nack;
  logic              is_wr_q;
  logic [ADDR_W-1:0] addr_q;
  logic [31:0]       wdata_q;
  logic [3:0]        wstrb_q;
  logic   [31:0] rdata_q;
  logic   ready_q, err_q;

  // the region decode (sel_i) already used the upper address bits
  logic [31-ADDR_W:0] unused_addr_hi;
  assign unused_addr_hi = mem_addr_i[31:ADDR_W];

  assign stall = is_wr_q ? req_stall_wr_i : req_stall_rd_i;
  assign ack   = rd_ack_i | wr_ack_i;
  assign nack  = rd_err_i | wr_err_i;

  assign req_o       = (state_q == REQ);
  assign req_is_wr_o = is_wr_q;
  assign addr_o      = addr_q;
  assign wr_data_o   = wdata_q;
  assign wr_biten_o  = {{8{wstrb_q[3]}}, {8{wstrb_q[2]}}, {8{wstrb_q[1]}}, {8{wstrb_q[0]}}};
  // the request, registered while the bridge is idle (no enable from the CPU's decode)
  always_ff @(posedge clk_i) begin
    if (state_q == IDLE) begin
      is_wr_q <= |mem_wstrb_i;
      addr_q  <= mem_addr_i[ADDR_W-1:0];
      wdata_q <= mem_wdata_i;
      wstrb_q <= mem_wstrb_i;
    end
  end

  // The read data is sampled every clock, with no enable: it is what the slave answers in the
  // clock ready_q is set, and only read while ready_q is high. (An enable would put the CPU's
  // address decode and the slave's ack in front of 32 CE pins: late in the board top.)
  always_ff @(posedge clk_i) rdata_q <= nack ? 32'd0 : rd_data_i;
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      state_q <= IDLE;
      ready_q <= 1'b0;
      err_q   <= 1'b0;
    end else begin
      ready_q <= 1'b0;
      err_q   <= 1'b0;
      unique case (state_q)
        IDLE:     if (sel_i && mem_valid_i) state_q <= REQ;
        REQ:      if (!stall) begin
                    if (ack) begin  // the regblock may answer a read in the request clock
                      ready_q <= 1'b1;
                      err_q   <= nack;
                      state_q <= DONE;
                    end else begin
                      state_q <= WAIT_ACK;
                    end
                  end
        WAIT_ACK: if (ack) begin
                    ready_q <= 1'b1;
                    err_q   <= nack;
                    state_q <= DONE;
                  end
        DONE:     state_q <= IDLE;  // mem_valid drops in the clock after mem_ready
        default:  state_q <= IDLE;
      endcase
    end
  end

  assign mem_ready_o = ready_q;
  assign mem_rdata_o = rdata_q;
  assign err_o       = err_q;
endmodule
