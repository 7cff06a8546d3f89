// ms_sched_cfg_tb: cocotb wrapper of ms_sched_cfg (tests/rtl/tb_ms_sched_cfg.py).
//
// The CSR's table and delay RAM are flat inputs (read with one clock of latency, as ms_csr
// answers); everything the load writes is logged into flat outputs the testbench reads after
// done_o: the record of every entry, every blank interval, the share matrix, write counts,
// and the clocks the last operation took.
module ms_sched_cfg_tb #(
  parameter int NUM_CH = 24,
  parameter int NUM_VS = 8,
  parameter int LEAD   = 4096,
  // record: {tx, rx, xt, use, act, track, order, k, reinit, tv, tn, vmax, rmax, phase, dbl, lo,
  // hi, burst}
  localparam int REC_W = 4 * 24 + 2 + 4 + 4 + 8 + 3 * 16 + 5 * 24 + 8
) (
  input  logic                  clk_i,
  input  logic                  rst_i,
  input  logic                  check_i,
  input  logic                  load_i,
  input  logic                  abort_i,
  input  logic [15:0]           burst_half_period_i,
  input  logic [72*32-1:0]      table_i,     // word entry * 9 + register
  input  logic [256*16-1:0]     delays_i,    // {entry, element}
  output logic                  busy_o,
  output logic                  done_o,
  output logic [3:0]            err_o,
  output logic [3:0]            err_vs_o,
  output logic [15:0]           clocks_o,    // clocks from the start strobe to done_o
  output logic [8*REC_W-1:0]    records_o,   // entry s at [s * REC_W +: REC_W]
  output logic [8*8-1:0]        ld_count_o,  // record writes per entry (8 bits each)
  output logic [256*36-1:0]     blk_o,       // {a[15:0], b[19:0]} per {entry, element}
  output logic [256-1:0]        blk_written_o,
  output logic [15:0]           blk_count_o,
  output logic [8*8-1:0]        share_o,     // entry a, b at bit a * 8 + b
  output logic [15:0]           share_count_o
);
  logic [6:0]  vs_raddr;
  logic [31:0] vs_rdata;
  logic [7:0]  dly_raddr;
  logic [15:0] dly_rdata;
  always_ff @(posedge clk_i) begin
    vs_rdata  <= (vs_raddr < 7'd72) ? table_i[int'(vs_raddr) * 32 +: 32] : 32'hDEAD_BEEF;
    dly_rdata <= delays_i[int'(dly_raddr) * 16 +: 16];
  end

  logic              ld_we, ld_act, ld_track, blk_we, share_we, share;
  logic [2:0]        ld_vs, share_a, share_b;
  logic [NUM_CH-1:0] ld_tx, ld_rx, ld_xt, ld_use;
  logic [3:0]        ld_order, ld_k;
  logic [7:0]        ld_reinit, ld_burst, blk_addr;
  logic [15:0]       ld_tv, ld_tn, ld_vmax, blk_a;
  logic [23:0]       ld_rmax, ld_phase, ld_dbl, ld_lo, ld_hi;
  logic [19:0]       blk_b;
  ms_sched_cfg #(.NUM_CH(NUM_CH), .NUM_VS(NUM_VS), .LEAD(LEAD)) u_dut (
    .clk_i, .rst_i, .check_i, .load_i, .abort_i, .busy_o, .done_o, .err_o, .err_vs_o,
    .vs_ren_o(), .vs_raddr_o(vs_raddr), .vs_rdata_i(vs_rdata),
    .delay_raddr_o(dly_raddr), .delay_rdata_i(dly_rdata),
    .burst_half_period_i,
    .ld_we_o(ld_we), .ld_vs_o(ld_vs), .ld_tx_o(ld_tx), .ld_rx_o(ld_rx), .ld_xt_o(ld_xt),
    .ld_use_o(ld_use), .ld_act_o(ld_act), .ld_track_o(ld_track), .ld_order_o(ld_order),
    .ld_k_o(ld_k), .ld_reinit_o(ld_reinit), .ld_tv_o(ld_tv), .ld_tn_o(ld_tn), .ld_vmax_o(ld_vmax),
    .ld_rmax_o(ld_rmax), .ld_phase_o(ld_phase), .ld_dbl_o(ld_dbl), .ld_lo_o(ld_lo), .ld_hi_o(ld_hi),
    .ld_burst_o(ld_burst),
    .blk_we_o(blk_we), .blk_addr_o(blk_addr), .blk_a_o(blk_a), .blk_b_o(blk_b),
    .share_we_o(share_we), .share_a_o(share_a), .share_b_o(share_b), .share_o(share)
  );

  always_ff @(posedge clk_i) begin
    if (rst_i || check_i || load_i) begin
      clocks_o      <= '0;
      ld_count_o    <= '0;
      blk_count_o   <= '0;
      blk_written_o <= '0;
      share_count_o <= '0;
      share_o       <= '0;
    end else begin
      if (busy_o && !done_o) clocks_o <= clocks_o + 16'd1;
      if (ld_we) begin
        records_o[int'(ld_vs) * REC_W +: REC_W] <= {ld_tx, ld_rx, ld_xt, ld_use, ld_act, ld_track,
            ld_order, ld_k, ld_reinit, ld_tv, ld_tn, ld_vmax, ld_rmax, ld_phase, ld_dbl, ld_lo, ld_hi,
            ld_burst};
        ld_count_o[int'(ld_vs) * 8 +: 8] <= ld_count_o[int'(ld_vs) * 8 +: 8] + 8'd1;
      end
      if (blk_we) begin
        blk_o[int'(blk_addr) * 36 +: 36] <= {blk_a, blk_b};
        blk_written_o[blk_addr]          <= 1'b1;
        blk_count_o                      <= blk_count_o + 16'd1;
      end
      if (share_we) begin
        share_o[int'(share_a) * 8 + int'(share_b)] <= share;
        share_o[int'(share_b) * 8 + int'(share_a)] <= share;
        share_count_o                              <= share_count_o + 16'd1;
      end
    end
  end
endmodule
