// cmd_fuzz_tb: cocotb top for command fuzzing and the firmware-hang test (tests/rtl/test_cmd_fuzz.py):
// ms_system (SoC running firmware/app/sonar, sonar core, host link) with its command input
// fed from an SV-side transfer buffer and its reply / frame byte stream captured SV-side, so no
// per-byte work happens in Python.
//
// Feeder: on go_i while busy_o is low, the transfer tx_bytes_i[8*tx_len_i-1:0] is latched and
// presented to the link as the USB bulk OUT endpoint would (ms_usb_device out_*): one byte per
// accepted entry, out_end on the last byte of a short packet; a transfer whose size is a
// multiple of 64 (0 included) ends with a zero-length-packet entry (zlp = end = 1, no byte).
// Each transfer's end cycle is appended to CMD_FILE ("<cycle>\n").
// Capture: the bulk IN side takes every byte at once (host_rd_i = 1); at each host_flush_o the
// packet's bytes are appended to CAP_FILE as "<cycle> <hex bytes>\n" (the file is flushed), and
// n_replies_o / n_frames_o count packets whose magic is "MR" / "MF".
// drive_edges_o counts rising edges of |drive_o (transducer bursts) since reset.
// The clock clk_i is made here (Verilator --timing, tests/rtl/cocotb_run.py OWN_CLOCK_TOPS): no
// VPI call per edge. The bench writes its inputs at falling edges.
module cmd_fuzz_tb #(
  parameter int    CLK_HALF_PS = 10417,  // tests/rtl/tbutil.py CLK_PERIOD_PS / 2
  parameter string INIT_FILE = "",
  parameter string CAP_FILE  = "cmd_fuzz_cap.txt",
  parameter string CMD_FILE  = "cmd_fuzz_cmd.txt",
  parameter int    NB        = 1200
) (
  input  logic            rst_i,
  input  logic [23:0]     echo_i,
  output logic [23:0]     drive_o,
  input  logic            go_i,
  input  logic [8*NB-1:0] tx_bytes_i,
  input  logic [15:0]     tx_len_i,
  output logic            busy_o,
  output logic [31:0]     n_replies_o,
  output logic [31:0]     n_frames_o,
  output logic [31:0]     n_cmds_o,
  output logic [31:0]     drive_edges_o,
  output logic [31:0]     cycle_o,
  output logic            sim_out_strobe_o,
  output logic [31:0]     sim_out_o,
  output logic            trap_o,
  output logic            bus_err_o
);
  logic clk_i = 1'b0;
  always #(CLK_HALF_PS * 1ps) clk_i = ~clk_i;

  logic            cmd_valid, cmd_end, cmd_zlp, cmd_ready, host_rvalid, host_flush, evt, zlp_q;
  logic [7:0]      cmd_data, host_rdata, led;
  logic [8*NB-1:0] buf_q;
  logic [15:0]     len_q, idx_q;
  logic [15:0]     cap_n_q;
  logic [7:0]      cap_b0_q, cap_b1_q;
  logic            drv_q;
  integer          fd_cap, fd_cmd;

  initial begin
    fd_cap = $fopen(CAP_FILE, "w");
    fd_cmd = $fopen(CMD_FILE, "w");
  end

  ms_system #(.NUM_CH(24), .INIT_FILE(INIT_FILE), .STRETCH_W(4)) u_sys (
    .clk_i, .rst_i, .echo_i, .drive_o,
    .cmd_valid_i (cmd_valid), .cmd_data_i (cmd_data), .cmd_end_i (cmd_end), .cmd_zlp_i (cmd_zlp),
    .cmd_ready_o (cmd_ready),
    .host_rd_i (1'b1), .host_rvalid_o (host_rvalid), .host_rdata_o (host_rdata), .host_flush_o (host_flush),
    .sim_out_strobe_o, .sim_out_o, .trap_o, .bus_err_o, .evt_available_o (evt), .led_o (led)
  );

  // ---- feeder
  assign cmd_valid = busy_o;
  assign cmd_zlp   = zlp_q;
  assign cmd_data  = zlp_q ? 8'd0 : buf_q[8*idx_q +: 8];
  assign cmd_end   = zlp_q || (idx_q + 16'd1 == len_q && len_q[5:0] != 6'd0);

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      busy_o   <= 1'b0;
      zlp_q    <= 1'b0;
      idx_q    <= '0;
      len_q    <= '0;
      n_cmds_o <= '0;
      cycle_o  <= '0;
    end else begin
      cycle_o <= cycle_o + 32'd1;
      if (!busy_o) begin
        if (go_i) begin
          buf_q  <= tx_bytes_i;
          len_q  <= tx_len_i;
          idx_q  <= '0;
          zlp_q  <= tx_len_i == 16'd0;
          busy_o <= 1'b1;
        end
      end else if (cmd_ready) begin
        if (cmd_end) begin
          busy_o   <= 1'b0;
          zlp_q    <= 1'b0;
          n_cmds_o <= n_cmds_o + 32'd1;
          $fwrite(fd_cmd, "%0d\n", cycle_o);
          $fflush(fd_cmd);
        end else begin
          idx_q <= idx_q + 16'd1;
          if (idx_q + 16'd1 == len_q) zlp_q <= 1'b1;  // size multiple of 64: a ZLP ends it
        end
      end
    end
  end

  // ---- capture
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      cap_n_q       <= '0;
      n_replies_o   <= '0;
      n_frames_o    <= '0;
      drive_edges_o <= '0;
      drv_q         <= 1'b0;
    end else begin
      drv_q <= |drive_o;
      if (|drive_o && !drv_q) drive_edges_o <= drive_edges_o + 32'd1;
      if (host_rvalid) begin
        if (cap_n_q == 16'd0) begin
          $fwrite(fd_cap, "%0d ", cycle_o);
          cap_b0_q <= host_rdata;
        end
        if (cap_n_q == 16'd1) cap_b1_q <= host_rdata;
        $fwrite(fd_cap, "%02x", host_rdata);
        cap_n_q <= cap_n_q + 16'd1;
      end
      if (host_flush) begin
        $fwrite(fd_cap, "\n");
        $fflush(fd_cap);
        cap_n_q <= '0;
        if (cap_b0_q == 8'h4D && cap_b1_q == 8'h52) n_replies_o <= n_replies_o + 32'd1;
        if (cap_b0_q == 8'h4D && cap_b1_q == 8'h46) n_frames_o <= n_frames_o + 32'd1;
      end
    end
  end

  logic unused;
  assign unused = ^{evt, led};
endmodule
