// ms_soc: the soft-core SoC next to the sonar core.
//
// CPU (parameter): "vexriscv" (default: the standard VexRiscv of pythondata-cpu-vexriscv,
// pipelined RV32IM, 4 KiB D cache and a 16 KiB I cache derived by scripts/gen_vex_icache.py so the
// per-pulse geometry meets its cycle budget, firmware/README.md; ms_vex_bridge, see the g_vex
// block) or "picorv32" (RV32IM: ENABLE_FAST_MUL or ENABLE_MUL, ENABLE_DIV; pythondata-cpu-picorv32;
// CPI ~5 with its one-wait-state RAM; smaller), with
//   0x0000_0000  RAM_WORDS x 32 bit of block RAM holding the firmware image (INIT_FILE)
//   0x1000_0000  the sonar core's registers (passthrough master port sonar_*; ms_csr)
//   0x2000_0000  SoC peripherals (soc_regs.rdl): cycle timer, watchdog, host link, mailbox
//   0x9000_0000, 0xA000_0000: the same registers again (bit 31 is not decoded): uncached
//                for VexRiscv, whose data cache bypasses only addresses with bit 31 set
// Addresses come from rtl/regs/soc_map.rdl, which also generates the firmware's header.
//
// Watchdog: when WDT_TIMEOUT is non-zero and that many clocks pass without a write to
// WDT_KICK, the CPU alone is held in reset for 16 clocks and WDT_RESETS counts it; the
// registers, the sonar core and the host link keep running (the sonar keeps firing).
// Idle wait: a read of WAIT stalls the CPU until wake_evt_i (the sonar core's event FIFO is not
// empty), a complete command transfer, or the cycle timer's low word reaching WAKE_AT; a
// watchdog reset of the CPU ends it too (the register block's read must complete).
// Host link (rtl/link/ms_link.sv, docs/protocol.md section 8): cmd_* takes the bytes of the USB
// bulk OUT endpoint (ms_usb_device out_*), the firmware reads whole command transfers through
// CMD_STATUS / CMD_DATA; it writes reply packets to REPLY_TX and frame packets to HOST_TX
// (header + payload words, committed by HOST_CTRL), and host_* is the byte stream towards the
// bulk IN endpoint (ms_usb_device in_*): host_rvalid_o / host_rdata_o a byte, taken on a clock
// with host_rd_i (in_ready); host_flush_o (one clock) ends each packet (in_flush), after its
// CRC-32, which the link appends.
module ms_soc #(
  parameter int    RAM_WORDS  = 16384,  // 64 KiB: firmware image + data + stack
  parameter string INIT_FILE  = "",
  parameter int    SONAR_AW   = 11,
  parameter int    FAST_MUL   = 1,      // (PicoRV32 only) 1: PicoRV32 ENABLE_FAST_MUL (ECP5: 4 MULT18X18D, ~200 LUT4
                                        // fewer than the iterative multiplier); 0: ENABLE_MUL (for a
                                        // device without DSP blocks)
  parameter string CPU        = "vexriscv"  // "vexriscv" or "picorv32" (see above)
) (
  input  logic                clk_i,
  input  logic                rst_i,
  // sonar core register bus (passthrough master)
  output logic                sonar_req_o,
  output logic                sonar_req_is_wr_o,
  output logic [SONAR_AW-1:0] sonar_addr_o,
  output logic [31:0]         sonar_wr_data_o,
  output logic [31:0]         sonar_wr_biten_o,
  input  logic                sonar_req_stall_wr_i,
  input  logic                sonar_req_stall_rd_i,
  input  logic                sonar_rd_ack_i,
  input  logic                sonar_rd_err_i,
  input  logic [31:0]         sonar_rd_data_i,
  input  logic                sonar_wr_ack_i,
  input  logic                sonar_wr_err_i,
  input  logic                wake_evt_i,        // an event word waits (ends a WAIT read)
  // host link: bulk OUT bytes in (ms_usb_device out_*), bulk IN bytes out (in_*)
  input  logic                cmd_valid_i,
  input  logic [7:0]          cmd_data_i,
  input  logic                cmd_end_i,
  input  logic                cmd_zlp_i,
  output logic                cmd_ready_o,
  input  logic                host_rd_i,
  output logic                host_rvalid_o,
  output logic [7:0]          host_rdata_o,
  output logic                host_flush_o,
  // observation
  output logic                sim_out_strobe_o,  // firmware wrote SIM_OUT
  output logic [31:0]         sim_out_o,
  output logic                trap_o,
  output logic                bus_err_o
);
  localparam int RAM_AW = $clog2(RAM_WORDS);

  // ---- CPU and RAM. Both CPUs leave every access outside their RAM on the native port
  // per_* (PicoRV32's mem_valid / mem_ready protocol), decoded into the peripherals below.
  logic        cpu_rst;
  logic        cpu_rst_q;
  logic [4:0]  cpu_rst_cnt_q;
  logic        per_valid, per_ready;
  logic [31:0] per_addr, per_wdata, per_rdata;
  logic [3:0]  per_wstrb;
  assign cpu_rst = rst_i | cpu_rst_q;

  if (CPU == "picorv32") begin : g_pico
    logic        mem_valid, mem_instr, mem_ready;
    logic [31:0] mem_addr, mem_wdata, mem_rdata;
    logic [3:0]  mem_wstrb;
    logic        unused_cpu;
    logic        unused_la_read, unused_la_write, unused_pcpi_valid, unused_trace_valid;
    logic [31:0] unused_la_addr, unused_la_wdata, unused_pcpi_insn, unused_pcpi_rs1, unused_pcpi_rs2, unused_eoi;
    logic [3:0]  unused_la_wstrb;
    logic [35:0] unused_trace_data;

    picorv32 #(
      .ENABLE_MUL      (FAST_MUL == 0),  // iterative multiplier, ~40 cycles per MUL
      .ENABLE_FAST_MUL (FAST_MUL != 0),  // 33x33 multiplier, a MUL/MULH in ~5 cycles (geometry firmware)
      .ENABLE_DIV      (1),
      .ENABLE_IRQ      (0),
      .COMPRESSED_ISA  (0),
      .BARREL_SHIFTER  (1),
      .PROGADDR_RESET  (32'h0000_0000),
      .STACKADDR       (32'(RAM_WORDS * 4))
    ) u_cpu (
      .clk          (clk_i),
      .resetn       (~cpu_rst),
      .trap         (trap_o),
      .mem_valid    (mem_valid),
      .mem_instr    (mem_instr),
      .mem_ready    (mem_ready),
      .mem_addr     (mem_addr),
      .mem_wdata    (mem_wdata),
      .mem_wstrb    (mem_wstrb),
      .mem_rdata    (mem_rdata),
      .mem_la_read  (unused_la_read),
      .mem_la_write (unused_la_write),
      .mem_la_addr  (unused_la_addr),
      .mem_la_wdata (unused_la_wdata),
      .mem_la_wstrb (unused_la_wstrb),
      .pcpi_valid   (unused_pcpi_valid),
      .pcpi_insn    (unused_pcpi_insn),
      .pcpi_rs1     (unused_pcpi_rs1),
      .pcpi_rs2     (unused_pcpi_rs2),
      .pcpi_wr      (1'b0),
      .pcpi_rd      (32'd0),
      .pcpi_wait    (1'b0),
      .pcpi_ready   (1'b0),
      .irq          (32'd0),
      .eoi          (unused_eoi),
      .trace_valid  (unused_trace_valid),
      .trace_data   (unused_trace_data)
    );
    assign unused_cpu = mem_instr;

    // RAM answers one clock after the request (one wait state: PicoRV32 holds mem_valid in
    // the mem_ready clock)
    logic        sel_ram, ram_ready_q;
    logic [31:0] ram_rdata;
    assign sel_ram = mem_addr[31:28] == 4'h0;
    ms_ram_sp_bytes #(.WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE)) u_ram (
      .clk_i   (clk_i),
      .addr_i  (mem_addr[RAM_AW+1:2]),
      .we_i    ((mem_valid & sel_ram & ~ram_ready_q) ? mem_wstrb : 4'b0),
      .wdata_i (mem_wdata),
      .rdata_o (ram_rdata)
    );
    always_ff @(posedge clk_i) begin
      if (cpu_rst) ram_ready_q <= 1'b0;
      else         ram_ready_q <= mem_valid & sel_ram & ~ram_ready_q;
    end

    assign per_valid = mem_valid & ~sel_ram;
    assign per_addr  = mem_addr;
    assign per_wdata = mem_wdata;
    assign per_wstrb = mem_wstrb;
    assign mem_ready = ram_ready_q | per_ready;
    assign mem_rdata = ram_ready_q ? ram_rdata : per_rdata;
  end else if (CPU == "vexriscv") begin : g_vex
    // VexRiscv, the pinned standard configuration (pythondata-cpu-vexriscv VexRiscv.v):
    // 5-stage pipeline with bypassing, 16 KiB instruction cache (scripts/gen_vex_icache.py)
    // and 4 KiB write-through data cache (32-byte lines), single-cycle MUL (DSP), iterative
    // DIV, machine-mode CSRs for traps but no readable counters (rdcycle / rdinstret trap:
    // the SoC's cycle timer counts instead); ms_vex_bridge shares the RAM. VexRiscv_Full
    // (every CSR) limited the board to 55.8 MHz through its CSR plugin (docs/synthesis.md).
    // Its data cache bypasses only addresses with bit 31 set (its I/O range): firmware
    // reaches the peripherals uncached through their aliases 0x9000_0000 / 0xA000_0000 (the
    // decode below ignores bit 31).
    // It has no trap output: an exception jumps to mtvec, which the firmware does not set,
    // so trap_o flags an instruction fetch outside RAM (sticky until the CPU reset).
    logic        ibus_cyc, ibus_stb, ibus_ack, ibus_err, ibus_we;
    logic        dbus_cyc, dbus_stb, dbus_ack, dbus_we, dbus_err;
    logic [29:0] ibus_adr, dbus_adr;
    logic [31:0] ibus_miso, ibus_mosi, dbus_miso, dbus_mosi;
    logic [3:0]  ibus_sel, dbus_sel;
    logic [2:0]  ibus_cti, dbus_cti;
    logic [1:0]  ibus_bte, dbus_bte;
    logic        unused_vex;
    logic [RAM_AW-1:0] ram_addr;
    logic [3:0]  ram_we;
    logic [31:0] ram_wdata, ram_rdata;
    logic        ifetch_err, trap_q;
    logic        cpu_clk;

`ifdef MS_TWIN_CPU_GATE
    // Simulation only (the full-system twin, sim/twin): the harness drives the CPU's clock with
    // the device's, and holds it in clocks where the CPU is stalled in the WAIT read and none of
    // its inputs changes, so its state would not change either (docs/twin.md). Never defined for
    // synthesis or the RTL tests.
    logic twin_cpu_clk;
    assign cpu_clk = twin_cpu_clk;
`else
    assign cpu_clk = clk_i;
`endif

    VexRiscv u_cpu (
      .externalResetVector    (32'h0000_0000),
      .timerInterrupt         (1'b0),
      .softwareInterrupt      (1'b0),
      .externalInterruptArray (32'd0),
      .iBusWishbone_CYC       (ibus_cyc),
      .iBusWishbone_STB       (ibus_stb),
      .iBusWishbone_ACK       (ibus_ack),
      .iBusWishbone_WE        (ibus_we),
      .iBusWishbone_ADR       (ibus_adr),
      .iBusWishbone_DAT_MISO  (ibus_miso),
      .iBusWishbone_DAT_MOSI  (ibus_mosi),
      .iBusWishbone_SEL       (ibus_sel),
      .iBusWishbone_ERR       (ibus_err),
      .iBusWishbone_CTI       (ibus_cti),
      .iBusWishbone_BTE       (ibus_bte),
      .dBusWishbone_CYC       (dbus_cyc),
      .dBusWishbone_STB       (dbus_stb),
      .dBusWishbone_ACK       (dbus_ack),
      .dBusWishbone_WE        (dbus_we),
      .dBusWishbone_ADR       (dbus_adr),
      .dBusWishbone_DAT_MISO  (dbus_miso),
      .dBusWishbone_DAT_MOSI  (dbus_mosi),
      .dBusWishbone_SEL       (dbus_sel),
      .dBusWishbone_ERR       (dbus_err),
      .dBusWishbone_CTI       (dbus_cti),
      .dBusWishbone_BTE       (dbus_bte),
      .clk                    (cpu_clk),
      .reset                  (cpu_rst)
    );
    assign dbus_err   = 1'b0;  // a bad data address answers 0 and raises bus_err_o, as on PicoRV32
    assign unused_vex = ^{ibus_we, ibus_mosi, ibus_sel, ibus_bte, dbus_bte};

    ms_vex_bridge #(.RAM_AW(RAM_AW)) u_bridge (
      .clk_i (clk_i), .rst_i (cpu_rst),
      .ibus_cyc_i (ibus_cyc), .ibus_stb_i (ibus_stb), .ibus_adr_i (ibus_adr), .ibus_cti_i (ibus_cti),
      .ibus_ack_o (ibus_ack), .ibus_err_o (ibus_err), .ibus_dat_o (ibus_miso),
      .dbus_cyc_i (dbus_cyc), .dbus_stb_i (dbus_stb), .dbus_we_i (dbus_we), .dbus_adr_i (dbus_adr),
      .dbus_dat_i (dbus_mosi), .dbus_sel_i (dbus_sel), .dbus_cti_i (dbus_cti),
      .dbus_ack_o (dbus_ack), .dbus_dat_o (dbus_miso),
      .ram_addr_o (ram_addr), .ram_we_o (ram_we), .ram_wdata_o (ram_wdata), .ram_rdata_i (ram_rdata),
      .mem_valid_o (per_valid), .mem_addr_o (per_addr), .mem_wdata_o (per_wdata), .mem_wstrb_o (per_wstrb),
      .mem_ready_i (per_ready), .mem_rdata_i (per_rdata),
      .ifetch_err_o (ifetch_err)
    );

    // one RAM port shared by the instruction and the data bus (ms_vex_bridge): the same
    // block RAM as on the PicoRV32 path
    ms_ram_sp_bytes #(.WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE)) u_ram (
      .clk_i (clk_i), .addr_i (ram_addr), .we_i (ram_we), .wdata_i (ram_wdata), .rdata_o (ram_rdata)
    );

    always_ff @(posedge clk_i) begin
      if (cpu_rst)         trap_q <= 1'b0;
      else if (ifetch_err) trap_q <= 1'b1;
    end
    assign trap_o = trap_q;
  end else begin : g_bad_cpu
    $error("ms_soc: CPU must be \"picorv32\" or \"vexriscv\"");
  end

  // ---- address decode of the peripherals. Bit 31 is not decoded: 0x9000_0000 / 0xA000_0000
  // alias the sonar / SoC registers (VexRiscv's uncached I/O range). An address outside every
  // region answers 0 and flags a bus error rather than hanging the CPU.
  logic sel_sonar, sel_soc, bad_ready_q;
  assign sel_sonar = per_addr[30:28] == 3'h1;
  assign sel_soc   = per_addr[30:28] == 3'h2;
  always_ff @(posedge clk_i) begin
    if (cpu_rst) bad_ready_q <= 1'b0;
    else         bad_ready_q <= per_valid & ~(sel_sonar | sel_soc) & ~bad_ready_q;
  end

  logic        sonar_ready, soc_ready, sonar_err, soc_err;
  logic [31:0] sonar_rdata, soc_rdata;

  ms_pico_bridge #(.ADDR_W(SONAR_AW)) u_sonar_bridge (
    .clk_i (clk_i), .rst_i (cpu_rst), .sel_i (sel_sonar),
    .mem_valid_i (per_valid), .mem_addr_i (per_addr), .mem_wdata_i (per_wdata), .mem_wstrb_i (per_wstrb),
    .mem_ready_o (sonar_ready), .mem_rdata_o (sonar_rdata), .err_o (sonar_err),
    .req_o (sonar_req_o), .req_is_wr_o (sonar_req_is_wr_o), .addr_o (sonar_addr_o),
    .wr_data_o (sonar_wr_data_o), .wr_biten_o (sonar_wr_biten_o),
    .req_stall_wr_i (sonar_req_stall_wr_i), .req_stall_rd_i (sonar_req_stall_rd_i),
    .rd_ack_i (sonar_rd_ack_i), .rd_err_i (sonar_rd_err_i), .rd_data_i (sonar_rd_data_i),
    .wr_ack_i (sonar_wr_ack_i), .wr_err_i (sonar_wr_err_i)
  );

  // ---- peripherals
  logic        soc_req, soc_req_is_wr, soc_stall_wr, soc_stall_rd;
  logic        soc_rd_ack, soc_rd_err, soc_wr_ack, soc_wr_err;
  logic [6:0]  soc_addr;
  logic [31:0] soc_wr_data, soc_wr_biten, soc_rd_data;

  ms_pico_bridge #(.ADDR_W(7)) u_soc_bridge (
    .clk_i (clk_i), .rst_i (cpu_rst), .sel_i (sel_soc),
    .mem_valid_i (per_valid), .mem_addr_i (per_addr), .mem_wdata_i (per_wdata), .mem_wstrb_i (per_wstrb),
    .mem_ready_o (soc_ready), .mem_rdata_o (soc_rdata), .err_o (soc_err),
    .req_o (soc_req), .req_is_wr_o (soc_req_is_wr), .addr_o (soc_addr),
    .wr_data_o (soc_wr_data), .wr_biten_o (soc_wr_biten),
    .req_stall_wr_i (soc_stall_wr), .req_stall_rd_i (soc_stall_rd),
    .rd_ack_i (soc_rd_ack), .rd_err_i (soc_rd_err), .rd_data_i (soc_rd_data),
    .wr_ack_i (soc_wr_ack), .wr_err_i (soc_wr_err)
  );

  soc_regs_pkg::soc_regs__in_t  hwif_in;
  soc_regs_pkg::soc_regs__out_t hwif_out;

  soc_regs u_regs (
    .clk (clk_i), .rst (rst_i),
    .s_cpuif_req (soc_req), .s_cpuif_req_is_wr (soc_req_is_wr), .s_cpuif_addr (soc_addr),
    .s_cpuif_wr_data (soc_wr_data), .s_cpuif_wr_biten (soc_wr_biten),
    .s_cpuif_req_stall_wr (soc_stall_wr), .s_cpuif_req_stall_rd (soc_stall_rd),
    .s_cpuif_rd_ack (soc_rd_ack), .s_cpuif_rd_err (soc_rd_err), .s_cpuif_rd_data (soc_rd_data),
    .s_cpuif_wr_ack (soc_wr_ack), .s_cpuif_wr_err (soc_wr_err),
    .hwif_in (hwif_in), .hwif_out (hwif_out)
  );

  // cycle timer
  logic [63:0] cycles_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) cycles_q <= '0;
    else       cycles_q <= cycles_q + 64'd1;
  end

  // watchdog: counts clocks since the last kick; resets only the CPU
  logic [31:0] wdt_cnt_q;
  logic        wdt_fire;
  assign wdt_fire = (hwif_out.WDT_TIMEOUT.cycles.value != '0) && !cpu_rst_q
                    && (wdt_cnt_q >= hwif_out.WDT_TIMEOUT.cycles.value);
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      wdt_cnt_q     <= '0;
      cpu_rst_q     <= 1'b0;
      cpu_rst_cnt_q <= '0;
    end else begin
      if (hwif_out.WDT_KICK.kick.value || cpu_rst_q) wdt_cnt_q <= '0;
      else                                           wdt_cnt_q <= wdt_cnt_q + 32'd1;
      if (wdt_fire) begin
        cpu_rst_q     <= 1'b1;
        cpu_rst_cnt_q <= 5'd16;
      end else if (cpu_rst_q) begin
        cpu_rst_cnt_q <= cpu_rst_cnt_q - 5'd1;
        if (cpu_rst_cnt_q == 5'd1) cpu_rst_q <= 1'b0;
      end
    end
  end

  // host link: command buffer, reply / frame queues, packer (CRC-32 in hardware)
  logic [9:0]  frm_level;
  logic [31:0] frames_sent, frames_dropped;
  logic [15:0] reply_drops;
  logic        frm_wr_ack_q, rep_wr_ack_q, frm_wr, rep_wr, cmd_rd;
  logic        cmd_avail, cmd_crc_ok, cmd_overlong, cmd_rd_ack;
  logic [15:0] cmd_bytes;
  logic [31:0] cmd_rd_data;
  assign frm_wr = hwif_out.HOST_TX.req & hwif_out.HOST_TX.req_is_wr;
  assign rep_wr = hwif_out.REPLY_TX.req & hwif_out.REPLY_TX.req_is_wr;
  assign cmd_rd = hwif_out.CMD_DATA.req & ~hwif_out.CMD_DATA.req_is_wr;
  logic rst_link;
  ms_reset_copy u_rst_link (.clk_i, .rst_i, .rst_o (rst_link));
  ms_link u_link (
    .clk_i (clk_i), .rst_i (rst_link),
    .out_valid_i (cmd_valid_i), .out_data_i (cmd_data_i), .out_end_i (cmd_end_i),
    .out_zlp_i (cmd_zlp_i), .out_ready_o (cmd_ready_o),
    .in_valid_o (host_rvalid_o), .in_data_o (host_rdata_o), .in_ready_i (host_rd_i),
    .in_flush_o (host_flush_o),
    .cmd_avail_o (cmd_avail), .cmd_bytes_o (cmd_bytes), .cmd_crc_ok_o (cmd_crc_ok),
    .cmd_overlong_o (cmd_overlong), .cmd_rd_i (cmd_rd), .cmd_rd_ack_o (cmd_rd_ack),
    .cmd_rd_data_o (cmd_rd_data), .cmd_next_i (hwif_out.HOST_CTRL.cmd_next.value),
    .rep_wr_i (rep_wr), .rep_wdata_i (hwif_out.REPLY_TX.wr_data.data),
    .rep_end_i (hwif_out.HOST_CTRL.reply_end.value),
    .frm_wr_i (frm_wr), .frm_wdata_i (hwif_out.HOST_TX.wr_data.data),
    .frm_end_i (hwif_out.HOST_CTRL.frame_end.value), .frm_discard_i (hwif_out.HOST_CTRL.discard.value),
    .clear_i (hwif_out.HOST_CTRL.clear.value),
    .frm_level_o (frm_level), .frames_sent_o (frames_sent), .frames_dropped_o (frames_dropped),
    .replies_dropped_o (reply_drops)
  );
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      frm_wr_ack_q <= 1'b0;
      rep_wr_ack_q <= 1'b0;
    end else begin
      frm_wr_ack_q <= frm_wr;
      rep_wr_ack_q <= rep_wr;
    end
  end

  // idle wait: WAIT's read pends until one of its reasons holds (one clock at the least)
  logic        wait_q, wait_done;
  logic [2:0]  wait_why;
  logic [31:0] wake_left;  // WAKE_AT - TIMER_LO: negative or 0 once reached (wraps as C's)
  assign wake_left = hwif_out.WAKE_AT.cycles.value - cycles_q[31:0];
  assign wait_why  = {cmd_avail, wake_evt_i, wake_left[31] | (wake_left == '0)};
  assign wait_done = wait_q & ((wait_why != '0) | cpu_rst_q);
  always_ff @(posedge clk_i) begin
    if (rst_i)                                             wait_q <= 1'b0;
    else if (hwif_out.WAIT.req & ~hwif_out.WAIT.req_is_wr) wait_q <= 1'b1;
    else if (wait_done)                                    wait_q <= 1'b0;
  end

  always_comb begin
    hwif_in.TIMER_LO.count.next          = cycles_q[31:0];
    hwif_in.TIMER_HI.count.next          = cycles_q[63:32];
    hwif_in.WDT_RESETS.count.incr        = wdt_fire;
    hwif_in.HOST_TX.wr_ack               = frm_wr_ack_q;
    hwif_in.REPLY_TX.wr_ack              = rep_wr_ack_q;
    hwif_in.HOST_STATUS.waiting.next     = 12'(frm_level);
    hwif_in.HOST_STATUS.reply_drops.next = reply_drops;
    hwif_in.FRAMES_SENT.count.next       = frames_sent;
    hwif_in.FRAMES_DROPPED.count.next    = frames_dropped;
    hwif_in.CMD_STATUS.avail.next        = cmd_avail;
    hwif_in.CMD_STATUS.crc_ok.next       = cmd_crc_ok;
    hwif_in.CMD_STATUS.overlong.next     = cmd_overlong;
    hwif_in.CMD_STATUS.bytes.next        = cmd_bytes;
    hwif_in.CMD_DATA.rd_ack              = cmd_rd_ack;
    hwif_in.CMD_DATA.rd_data.data        = cmd_rd_data;
    hwif_in.WAIT.rd_ack                  = wait_done;
    hwif_in.WAIT.rd_data.timer           = wait_why[0];
    hwif_in.WAIT.rd_data.fifo            = wait_why[1];
    hwif_in.WAIT.rd_data.cmd             = wait_why[2];
  end

  // mailbox: the strobe follows the write by one clock, when the register holds the value
  logic sim_out_strobe_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) sim_out_strobe_q <= 1'b0;
    else       sim_out_strobe_q <= hwif_out.SIM_OUT.value.swmod;
  end
  assign sim_out_strobe_o = sim_out_strobe_q;
  assign sim_out_o        = hwif_out.SIM_OUT.value.value;

  // ---- answer back to the CPU
  always_comb begin
    per_ready = bad_ready_q | sonar_ready | soc_ready;
    per_rdata = sonar_ready ? sonar_rdata : soc_ready ? soc_rdata : 32'd0;
  end
  assign bus_err_o = bad_ready_q | sonar_err | soc_err;
endmodule
