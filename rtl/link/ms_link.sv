// ms_link: the host link between the USB device core's bulk endpoints and the soft-core
// (docs/protocol.md section 8): command receive buffer (ms_link_cmd_rx), reply and frame
// packet queues with commit / roll-back (ms_link_txq) and the packer that sends each packet
// as one bulk IN transfer with the CRC-32 appended in hardware (ms_link_packer), replies
// ahead of frames at packet boundaries. ms_soc maps the firmware side onto its registers
// (rtl/regs/soc_regs.rdl: CMD_*, REPLY_TX, HOST_TX, HOST_CTRL, HOST_STATUS, FRAMES_*).
//
// Timing contract: one clock (48 MHz), synchronous rst_i. USB side: ms_usb_device's out_* /
// in_* (first-word-fall-through OUT entries, IN bytes on in_ready_i, in_flush_o one clock
// per packet). Firmware side: one-clock strobes from the register block; cmd_rd_ack_o /
// cmd_rd_data_o one clock after cmd_rd_i; counters and levels are registered.
// frames_dropped_o counts frames rolled back at commit (queue full or malformed) and frames
// discarded by frm_discard_i; frames_sent_o frames handed whole to the endpoint;
// replies_dropped_o replies rolled back (a firmware error: replies fit unless ~2 maximal
// replies wait). clear_i zeroes the three counters.
module ms_link #(
  parameter int CMD_DEPTH_W = 9,  // command buffer, 2^n words
  parameter int REP_DEPTH_W = 9,  // reply queue, 2^n words
  parameter int FRM_DEPTH_W = 9   // frame queue, 2^n words
) (
  input  logic                 clk_i,
  input  logic                 rst_i,
  // USB bulk OUT (commands)
  input  logic                 out_valid_i,
  input  logic [7:0]           out_data_i,
  input  logic                 out_end_i,
  input  logic                 out_zlp_i,
  output logic                 out_ready_o,
  // USB bulk IN (replies, frames)
  output logic                 in_valid_o,
  output logic [7:0]           in_data_o,
  input  logic                 in_ready_i,
  output logic                 in_flush_o,
  // firmware: commands
  output logic                 cmd_avail_o,
  output logic [15:0]          cmd_bytes_o,
  output logic                 cmd_crc_ok_o,
  output logic                 cmd_overlong_o,
  input  logic                 cmd_rd_i,
  output logic                 cmd_rd_ack_o,
  output logic [31:0]          cmd_rd_data_o,
  input  logic                 cmd_next_i,
  // firmware: replies and frames
  input  logic                 rep_wr_i,
  input  logic [31:0]          rep_wdata_i,
  input  logic                 rep_end_i,
  input  logic                 frm_wr_i,
  input  logic [31:0]          frm_wdata_i,
  input  logic                 frm_end_i,
  input  logic                 frm_discard_i,
  input  logic                 clear_i,
  output logic [FRM_DEPTH_W:0] frm_level_o,
  output logic [31:0]          frames_sent_o,
  output logic [31:0]          frames_dropped_o,
  output logic [15:0]          replies_dropped_o
);
  logic                 rep_start, rep_rd, frm_start, frm_rd, boundary, sent, sent_frame;
  logic                 rep_dropped, frm_dropped, frm_discarded, unused_rep_disc, unused_commit;
  logic [31:0]          rep_rdata, frm_rdata;
  logic [REP_DEPTH_W:0] rep_pkts, unused_rep_disc_n, unused_rep_level;
  logic [FRM_DEPTH_W:0] frm_pkts, frm_discarded_n;
  logic                 unused_rep_commit;

  ms_link_cmd_rx #(.DEPTH_W(CMD_DEPTH_W)) u_cmd (
    .clk_i, .rst_i,
    .out_valid_i, .out_data_i, .out_end_i, .out_zlp_i, .out_ready_o,
    .avail_o (cmd_avail_o), .bytes_o (cmd_bytes_o), .crc_ok_o (cmd_crc_ok_o),
    .overlong_o (cmd_overlong_o), .rd_i (cmd_rd_i), .rd_ack_o (cmd_rd_ack_o),
    .rd_data_o (cmd_rd_data_o), .next_i (cmd_next_i)
  );

  ms_link_txq #(.DEPTH_W(REP_DEPTH_W)) u_rep (
    .clk_i, .rst_i,
    .wr_i (rep_wr_i), .wdata_i (rep_wdata_i), .commit_i (rep_end_i),
    .committed_o (unused_rep_commit), .dropped_o (rep_dropped),
    .discard_i (1'b0), .boundary_i (boundary), .discarded_o (unused_rep_disc),
    .discarded_n_o (unused_rep_disc_n), .pkts_o (rep_pkts),
    .start_i (rep_start), .rd_i (rep_rd), .rdata_o (rep_rdata), .level_o (unused_rep_level)
  );

  ms_link_txq #(.DEPTH_W(FRM_DEPTH_W)) u_frm (
    .clk_i, .rst_i,
    .wr_i (frm_wr_i), .wdata_i (frm_wdata_i), .commit_i (frm_end_i),
    .committed_o (unused_commit), .dropped_o (frm_dropped),
    .discard_i (frm_discard_i), .boundary_i (boundary), .discarded_o (frm_discarded),
    .discarded_n_o (frm_discarded_n), .pkts_o (frm_pkts),
    .start_i (frm_start), .rd_i (frm_rd), .rdata_o (frm_rdata), .level_o (frm_level_o)
  );

  ms_link_packer u_pack (
    .clk_i, .rst_i,
    .rep_have_i (rep_pkts != '0), .rep_start_o (rep_start), .rep_rd_o (rep_rd), .rep_rdata_i (rep_rdata),
    .frm_have_i (frm_pkts != '0), .frm_start_o (frm_start), .frm_rd_o (frm_rd), .frm_rdata_i (frm_rdata),
    .boundary_o (boundary),
    .in_valid_o, .in_data_o, .in_ready_i, .in_flush_o,
    .sent_o (sent), .sent_frame_o (sent_frame)
  );

  always_ff @(posedge clk_i) begin
    if (rst_i || clear_i) begin
      frames_sent_o     <= '0;
      frames_dropped_o  <= '0;
      replies_dropped_o <= '0;
    end else begin
      if (sent && sent_frame) frames_sent_o <= frames_sent_o + 32'd1;
      frames_dropped_o <= frames_dropped_o + 32'(frm_dropped) + (frm_discarded ? 32'(frm_discarded_n) : 32'd0);
      if (rep_dropped) replies_dropped_o <= replies_dropped_o + 16'd1;
    end
  end
endmodule
