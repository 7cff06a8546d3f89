// ms_soc: the soft-core SoC next to the sonar core.
//
// PicoRV32 (RV32IM: ENABLE_FAST_MUL or ENABLE_MUL, ENABLE_DIV; pythondata-cpu-picorv32) with
//   0x0000_0000  RAM_WORDS x 32 bit of block RAM holding the firmware image (INIT_FILE)
//   0x1000_0000  the sonar core's registers (passthrough master port sonar_*; ms_csr)
//   0x2000_0000  SoC peripherals (soc_regs.rdl): cycle timer, watchdog, host FIFO, mailbox
// Addresses come from rtl/regs/soc_map.rdl, which also generates the firmware's header.
//
// Watchdog: when WDT_TIMEOUT is non-zero and that many clocks pass without a write to
// WDT_KICK, the CPU alone is held in reset for 16 clocks and WDT_RESETS counts it; the
// registers, the sonar core and the host FIFO keep running (the sonar keeps firing).
// Host FIFO: each write to HOST_TX appends a word; host_* is its first-word-fall-through read
// side; a word written while full is dropped, counted in HOST_STATUS.drops, and the next
// stored word has bit 32 (host_rdata_o[32]) set.
module ms_soc #(
  parameter int    RAM_WORDS  = 16384,  // 64 KiB: firmware image + data + stack
  parameter string INIT_FILE  = "",
  parameter int    SONAR_AW   = 11,
  parameter int    FAST_MUL   = 1       // 1: PicoRV32 ENABLE_FAST_MUL (ECP5: 4 MULT18X18D, ~200 LUT4
                                        // fewer than the iterative multiplier); 0: ENABLE_MUL (iCE40:
                                        // the single-cycle multiplier would cost ~3 k SB_LUT4 more)
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
  // host FIFO read side
  input  logic                host_rd_i,
  output logic                host_rvalid_o,
  output logic [32:0]         host_rdata_o,
  // observation
  output logic                sim_out_strobe_o,  // firmware wrote SIM_OUT
  output logic [31:0]         sim_out_o,
  output logic                trap_o,
  output logic                bus_err_o
);
  localparam int RAM_AW = $clog2(RAM_WORDS);

  // ---- CPU
  logic        cpu_rst_q;
  logic [4:0]  cpu_rst_cnt_q;
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
    .resetn       (~(rst_i | cpu_rst_q)),
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

  // ---- address decode
  logic sel_ram, sel_sonar, sel_soc;
  assign sel_ram   = mem_addr[31:28] == 4'h0;
  assign sel_sonar = mem_addr[31:28] == 4'h1;
  assign sel_soc   = mem_addr[31:28] == 4'h2;

  // RAM answers one clock after the request; an address outside every region answers 0 and
  // flags a bus error rather than hanging the CPU.
  logic        ram_ready_q, bad_ready_q;
  logic [31:0] ram_rdata;
  ms_ram_sp_bytes #(.WORDS(RAM_WORDS), .INIT_FILE(INIT_FILE)) u_ram (
    .clk_i   (clk_i),
    .addr_i  (mem_addr[RAM_AW+1:2]),
    .we_i    ((mem_valid & sel_ram & ~ram_ready_q) ? mem_wstrb : 4'b0),
    .wdata_i (mem_wdata),
    .rdata_o (ram_rdata)
  );
  always_ff @(posedge clk_i) begin
    if (rst_i | cpu_rst_q) begin
      ram_ready_q <= 1'b0;
      bad_ready_q <= 1'b0;
    end else begin
      ram_ready_q <= mem_valid & sel_ram & ~ram_ready_q;
      bad_ready_q <= mem_valid & ~(sel_ram | sel_sonar | sel_soc) & ~bad_ready_q;
    end
  end

  logic        sonar_ready, soc_ready, sonar_err, soc_err;
  logic [31:0] sonar_rdata, soc_rdata;

  ms_pico_bridge #(.ADDR_W(SONAR_AW)) u_sonar_bridge (
    .clk_i (clk_i), .rst_i (rst_i | cpu_rst_q), .sel_i (sel_sonar),
    .mem_valid_i (mem_valid), .mem_addr_i (mem_addr), .mem_wdata_i (mem_wdata), .mem_wstrb_i (mem_wstrb),
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
  logic [5:0]  soc_addr;
  logic [31:0] soc_wr_data, soc_wr_biten, soc_rd_data;

  ms_pico_bridge #(.ADDR_W(6)) u_soc_bridge (
    .clk_i (clk_i), .rst_i (rst_i | cpu_rst_q), .sel_i (sel_soc),
    .mem_valid_i (mem_valid), .mem_addr_i (mem_addr), .mem_wdata_i (mem_wdata), .mem_wstrb_i (mem_wstrb),
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

  // host FIFO (33 bits: the word and the "words were dropped before me" flag)
  logic        host_push, host_overflow;
  logic [11:0] host_level;
  logic        host_wr_ack_q;
  assign host_push = hwif_out.HOST_TX.req & hwif_out.HOST_TX.req_is_wr;
  ms_event_fifo #(.WIDTH(33), .DEPTH_W(9), .OVF_BIT(32), .LEVEL_W(12)) u_host_fifo (
    .clk_i (clk_i), .rst_i (rst_i),
    .wr_i (host_push), .wdata_i ({1'b0, hwif_out.HOST_TX.wr_data.data}),
    .rd_i (host_rd_i), .rvalid_o (host_rvalid_o), .rdata_o (host_rdata_o),
    .overflow_o (host_overflow), .level_o (host_level)
  );
  always_ff @(posedge clk_i) begin
    if (rst_i) host_wr_ack_q <= 1'b0;
    else       host_wr_ack_q <= host_push;
  end

  always_comb begin
    hwif_in.TIMER_LO.count.next        = cycles_q[31:0];
    hwif_in.TIMER_HI.count.next        = cycles_q[63:32];
    hwif_in.WDT_RESETS.count.incr      = wdt_fire;
    hwif_in.HOST_TX.wr_ack             = host_wr_ack_q;
    hwif_in.HOST_STATUS.waiting.next   = host_level;
    hwif_in.HOST_STATUS.drops.incr     = host_overflow;
  end

  // mailbox: the strobe follows the write by one clock, when the register holds the value
  logic sim_out_strobe_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) sim_out_strobe_q <= 1'b0;
    else       sim_out_strobe_q <= hwif_out.SIM_OUT.value.swmod;
  end
  assign sim_out_strobe_o = sim_out_strobe_q;
  assign sim_out_o        = hwif_out.SIM_OUT.value.value;

  // ---- read mux back to the CPU
  always_comb begin
    mem_ready = ram_ready_q | bad_ready_q | sonar_ready | soc_ready;
    mem_rdata = ram_ready_q ? ram_rdata : sonar_ready ? sonar_rdata : soc_ready ? soc_rdata : 32'd0;
  end
  assign bus_err_o = bad_ready_q | sonar_err | soc_err;
endmodule
