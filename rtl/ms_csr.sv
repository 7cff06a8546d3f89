// ms_csr: the sonar core's control/status registers as flat, named signals.
//
// Wraps the PeakRDL-generated register block (rtl/regs/sonar_regs.rdl -> build/gen/sv) so
// the rest of the RTL never touches its hwif structs, holds the phasing-delay table in
// block RAM (the regblock treats it as external memory) and the virtual-sensor table VS[8]
// (an external regfile of the regblock) in distributed RAM: 9 words per implemented entry
// (NUM_VS of the map's 8; the others read as zero and ignore writes), written per byte lane.
// Both tables are the firmware's: it checks them and writes the scheduler's load image through
// LOAD_ADDR / LOAD_DATA (one ld_we_o strobe per LOAD_DATA write, a clock after it).
// CAPS reports the build's parameters (NUM_CH, NUM_VS, WSLOTS, EVT_DEPTH_W).
// After a reset the table is refilled with its reset values, one word per clock (VS_WORDS
// clocks); the bus is stalled meanwhile.
//
// Bus: PeakRDL "passthrough" protocol. A request is accepted on a clock with req high and
// no stall; rd_ack / wr_ack answer three or more clocks later (the request and the answer
// each pass a register slice by the regblock; inside it a register access answers on
// the next clock, a VS-table write one clock later and a read two clocks later (a written
// value is in effect from the clock after the request, as for the other registers), a
// delay-table access one clock after the RAM read). VS-table writes take byte lanes: byte k
// is written when wr_biten bit 8k is set (the SoC bridges only make whole-byte enables).
// Unmapped addresses and writes to read-only registers answer with rd_err / wr_err.
//
// Counters (events, pulses, overflows) increment on one-clock strobes from the core and
// clear together on CTRL.clear_counters; the overflow counter saturates instead of wrapping.
module ms_csr
  import sonar_regs_pkg::*;
#(
  parameter int NUM_CH  = ms_layout_pkg::NUM_CH,
  parameter int DELAY_W = 16,
  parameter int ADDR_W  = 11,
  parameter int NUM_VS  = 8,   // VS entries the scheduler runs (1..VS_ENTRIES; CAPS.num_vs)
  parameter int WSLOTS  = 16,  // the scheduler's window slots per element (CAPS.win_slots)
  parameter int EVT_DEPTH_W = 9,  // log2 of the event FIFO depth (CAPS.fifo_depth_log2)
  // fixed by the register map (regfile VS[8] in sonar_regs.rdl)
  localparam int unsigned VS_ENTRIES = 8
) (
  input  logic                          clk_i,
  input  logic                          rst_i,
  // register bus (passthrough)
  input  logic                          bus_req_i,
  input  logic                          bus_req_is_wr_i,
  input  logic [ADDR_W-1:0]             bus_addr_i,
  input  logic [31:0]                   bus_wr_data_i,
  input  logic [31:0]                   bus_wr_biten_i,
  output logic                          bus_req_stall_wr_o,
  output logic                          bus_req_stall_rd_o,
  output logic                          bus_rd_ack_o,
  output logic                          bus_rd_err_o,
  output logic [31:0]                   bus_rd_data_o,
  output logic                          bus_wr_ack_o,
  output logic                          bus_wr_err_o,
  // settings to the core
  output logic                          enable_o,
  output logic                          hold_o,            // one-clock strobes
  output logic                          start_o,
  output logic                          clear_counters_o,  // one-clock strobe
  output logic [15:0]                   burst_half_period_o,
  output logic [7:0]                    burst_cycles_o,
  output logic [7:0]                    glitch_min_o,
  // the scheduler's load port: LOAD_DATA written with LOAD_ADDR, a clock after the write
  output logic                          ld_we_o,
  output logic [11:0]                   ld_addr_o,
  output logic [31:0]                   ld_data_o,
  // event FIFO head (first-word-fall-through) read through EVT_LO / EVT_HI
  input  logic                          evt_rvalid_i,
  input  logic [63:0]                   evt_rdata_i,
  output logic                          evt_pop_o,         // a read of EVT_HI took the head
  // status and event strobes from the core
  input  logic                          running_i,
  input  logic                          sched_overrun_i,
  input  logic                          tx_collision_i,
  input  logic [11:0]                   fifo_level_i,
  input  logic                          event_i,
  input  logic                          overflow_i,
  input  logic                          pulse_i
);
  sonar_regs__in_t  hwif_in;
  sonar_regs__out_t hwif_out;

  // ---- bus slice: the request is registered here, by the register block, and so is the
  // answer on its way back. The bus master (the SoC bridge) sits by the CPU, across the chip:
  // without the slice its wires and the regblock's address decode and readback shared one
  // clock (the board top's slowest path, about 19 ns of wire). Costs two clocks per access.
  // The slot holds a request while the regblock stalls it; the master is stalled only then.
  logic              rq_valid_q, rq_is_wr_q;
  logic [ADDR_W-1:0] rq_addr_q;
  logic [31:0]       rq_wr_data_q, rq_wr_biten_q;
  logic              rb_stall_wr, rb_stall_rd, rq_held;
  logic              rb_rd_ack, rb_rd_err, rb_wr_ack, rb_wr_err;
  logic [31:0]       rb_rd_data;
  logic              rs_rd_ack_q, rs_rd_err_q, rs_wr_ack_q, rs_wr_err_q;
  logic [31:0]       rs_rd_data_q;

  logic vs_init_busy;  // the VS table is being refilled after a reset (below): every request waits
  assign rq_held = rq_valid_q && (vs_init_busy || (rq_is_wr_q ? rb_stall_wr : rb_stall_rd));
  always_ff @(posedge clk_i) begin
    if (rst_i) rq_valid_q <= 1'b0;
    else if (!rq_held) rq_valid_q <= bus_req_i;
  end
  always_ff @(posedge clk_i) begin
    if (!rq_held) begin
      rq_is_wr_q    <= bus_req_is_wr_i;
      rq_addr_q     <= bus_addr_i;
      rq_wr_data_q  <= bus_wr_data_i;
      rq_wr_biten_q <= bus_wr_biten_i;
    end
  end
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      rs_rd_ack_q <= 1'b0;
      rs_rd_err_q <= 1'b0;
      rs_wr_ack_q <= 1'b0;
      rs_wr_err_q <= 1'b0;
    end else begin
      rs_rd_ack_q <= rb_rd_ack;
      rs_rd_err_q <= rb_rd_err;
      rs_wr_ack_q <= rb_wr_ack;
      rs_wr_err_q <= rb_wr_err;
    end
  end
  always_ff @(posedge clk_i) rs_rd_data_q <= rb_rd_data;
  assign bus_req_stall_wr_o = rq_held;
  assign bus_req_stall_rd_o = rq_held;
  assign bus_rd_ack_o  = rs_rd_ack_q;
  assign bus_rd_err_o  = rs_rd_err_q;
  assign bus_rd_data_o = rs_rd_data_q;
  assign bus_wr_ack_o  = rs_wr_ack_q;
  assign bus_wr_err_o  = rs_wr_err_q;

  sonar_regs u_regs (
    .clk                  (clk_i),
    .rst                  (rst_i),
    .s_cpuif_req          (rq_valid_q && !vs_init_busy),
    .s_cpuif_req_is_wr    (rq_is_wr_q),
    .s_cpuif_addr         (rq_addr_q),
    .s_cpuif_wr_data      (rq_wr_data_q),
    .s_cpuif_wr_biten     (rq_wr_biten_q),
    .s_cpuif_req_stall_wr (rb_stall_wr),
    .s_cpuif_req_stall_rd (rb_stall_rd),
    .s_cpuif_rd_ack       (rb_rd_ack),
    .s_cpuif_rd_err       (rb_rd_err),
    .s_cpuif_rd_data      (rb_rd_data),
    .s_cpuif_wr_ack       (rb_wr_ack),
    .s_cpuif_wr_err       (rb_wr_err),
    .hwif_in              (hwif_in),
    .hwif_out             (hwif_out)
  );

  // delay-table handshake (see the RAM below); declared first because the hwif_in block uses it
  logic                 delay_rd_pending_q, delay_wr_pending_q;
  logic [DELAY_W-1:0]   delay_rdata_a;
  // event readout: the head is sampled on the request clock and answered on the next one.
  // An EVT_LO read also samples the head's high word (evt_snap_q) and arms the next EVT_HI read
  // to answer that sample and pop only if it was valid: the two words then always belong to
  // one event, even when the FIFO was empty at the EVT_LO read and an event arrived before the
  // EVT_HI read (it was read as lo = 0 and popped with the new event's high word).
  logic                 evt_lo_ack_q, evt_hi_ack_q;
  logic [31:0]          evt_lo_q;
  logic [31:0]          evt_hi_q;    // {valid, bits 62:32}
  logic [31:0]          evt_snap_q;  // {valid, bits 62:32} of the head at the last EVT_LO read
  logic                 evt_armed_q; // an EVT_LO read came since the last EVT_HI read
  logic                 evt_head_valid;
  // VS table: NUM_VS entries of VS_REGS registers (TX_MASK .. PHASE at offsets 0x00 .. 0x20)
  localparam int VS_REGS = 9;
  logic [VS_ENTRIES-1:0] vs_rd_ack_q, vs_wr_ack_q;
  logic [31:0]          vs_rdata_bus;

  // ---- status, counters and the delay-table answers: one process drives all of hwif_in
  // (Verilator treats the struct as one variable).
  always_comb begin
    hwif_in.STATUS.running.next      = running_i;
    hwif_in.STATUS.sched_overrun.next = sched_overrun_i;
    hwif_in.TX_COLLISIONS.count.incr  = tx_collision_i;
    hwif_in.TX_COLLISIONS.count.hwclr = hwif_out.CTRL.clear_counters.value;
    hwif_in.STATUS.fifo_level.next   = fifo_level_i;
    hwif_in.EVENTS.count.incr        = event_i;
    hwif_in.EVENTS.count.hwclr       = hwif_out.CTRL.clear_counters.value;
    hwif_in.OVERFLOWS.count.incr     = overflow_i;
    hwif_in.OVERFLOWS.count.hwclr    = hwif_out.CTRL.clear_counters.value;
    hwif_in.PULSES.count.incr        = pulse_i;
    hwif_in.PULSES.count.hwclr       = hwif_out.CTRL.clear_counters.value;
    hwif_in.DELAY.rd_ack             = delay_rd_pending_q;
    hwif_in.DELAY.rd_data            = 32'(delay_rdata_a);
    hwif_in.DELAY.wr_ack             = delay_wr_pending_q;
    hwif_in.EVT_LO.rd_ack            = evt_lo_ack_q;
    hwif_in.EVT_LO.rd_data.data      = evt_lo_q;
    hwif_in.EVT_HI.rd_ack            = evt_hi_ack_q;
    hwif_in.EVT_HI.rd_data.valid     = evt_hi_q[31];
    hwif_in.EVT_HI.rd_data.data      = evt_hi_q[30:0];
    hwif_in.CAPS.num_ch.next          = 8'(NUM_CH);
    hwif_in.CAPS.num_vs.next          = 8'(NUM_VS);
    hwif_in.CAPS.fifo_depth_log2.next = 4'(EVT_DEPTH_W);
    hwif_in.CAPS.win_slots.next       = 8'(WSLOTS);
    for (int v = 0; v < int'(VS_ENTRIES); v++) begin
      hwif_in.VS[v].rd_ack  = vs_rd_ack_q[v];
      hwif_in.VS[v].rd_data = vs_rdata_bus;
      hwif_in.VS[v].wr_ack  = vs_wr_ack_q[v];
    end
  end

  // only EVT_HI pops, so an armed snapshot that was valid is still the head
  assign evt_head_valid = evt_armed_q ? evt_snap_q[31] : evt_rvalid_i;
  assign evt_pop_o      = hwif_out.EVT_HI.req & ~hwif_out.EVT_HI.req_is_wr & evt_head_valid;

  // Bit 63 of an event word is always zero (docs/fast_firing.md section 6), so EVT_HI carries
  // bits 62:32 and uses its top bit for "valid".
  logic unused_evt_bit63;
  assign unused_evt_bit63 = evt_rdata_i[63];

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      evt_lo_ack_q <= 1'b0;
      evt_hi_ack_q <= 1'b0;
      evt_lo_q     <= '0;
      evt_hi_q     <= '0;
      evt_snap_q   <= '0;
      evt_armed_q  <= 1'b0;
    end else begin
      evt_lo_ack_q <= hwif_out.EVT_LO.req & ~hwif_out.EVT_LO.req_is_wr;
      evt_hi_ack_q <= hwif_out.EVT_HI.req & ~hwif_out.EVT_HI.req_is_wr;
      if (hwif_out.EVT_LO.req && !hwif_out.EVT_LO.req_is_wr) begin
        evt_lo_q    <= evt_rvalid_i ? evt_rdata_i[31:0] : 32'd0;
        evt_snap_q  <= evt_rvalid_i ? {1'b1, evt_rdata_i[62:32]} : 32'd0;
        evt_armed_q <= 1'b1;
      end
      if (hwif_out.EVT_HI.req && !hwif_out.EVT_HI.req_is_wr) begin
        evt_hi_q    <= evt_armed_q ? evt_snap_q : (evt_rvalid_i ? {1'b1, evt_rdata_i[62:32]} : 32'd0);
        evt_armed_q <= 1'b0;
      end
    end
  end

  assign enable_o            = hwif_out.CTRL.enable.value;
  assign hold_o              = hwif_out.CTRL.hold.value;
  assign start_o             = hwif_out.CTRL.start.value;
  assign clear_counters_o    = hwif_out.CTRL.clear_counters.value;
  assign burst_half_period_o = hwif_out.BURST.half_period.value;
  assign burst_cycles_o      = hwif_out.BURST.cycles.value;
  assign glitch_min_o        = hwif_out.RX_FILTER.glitch_min.value;
  // RX_FILTER.miss_gate and .miss_hold reach the scheduler through the firmware's load image;
  // named here for the testbenches that read the register file's contents through the hierarchy
  logic [15:0] miss_gate;
  logic        miss_hold;
  logic        unused_miss_rules;
  assign miss_gate         = hwif_out.RX_FILTER.miss_gate.value;
  assign miss_hold         = hwif_out.RX_FILTER.miss_hold.value;
  assign unused_miss_rules = ^{miss_gate, miss_hold};
  // LOAD_DATA's value is the written word from the clock after its swmod strobe
  always_ff @(posedge clk_i) ld_we_o <= !rst_i && hwif_out.LOAD_DATA.data.swmod;
  assign ld_addr_o           = hwif_out.LOAD_ADDR.addr.value;
  assign ld_data_o           = hwif_out.LOAD_DATA.data.value;

  // ---- virtual-sensor table (external regfile VS[8] of sonar_regs.rdl). Field layout and
  // reset values are the register map's; tests/rtl/tb_ms_csr.py checks every field's reset,
  // read-back mask and output against the generated constants.
  function automatic logic [31:0] vs_fields(input int r);  // implemented bits of register r
    unique case (r)
      0, 1:    vs_fields = 32'((64'd1 << NUM_CH) - 64'd1);  // TX_MASK, RX_MASK: mask[NUM_CH-1:0]
      2:       vs_fields = 32'h000F_FFF3;                   // MODE: reinit_every[19:12] miss_limit[11:8] order[7:4] mode[1:0]
      3:       vs_fields = 32'hFFFF_FFFF;                   // WINDOW: t_n[31:16] t_v[15:0]
      4:       vs_fields = 32'h0007_FFFF;                   // T_DEAD: ticks[18:0]
      5:       vs_fields = 32'h00FF_FFFF;                   // MAX_TOF: ticks[23:0]
      6:       vs_fields = 32'h0037_FFFF;                   // XTALK: nb[21:20] t_xtalk[18:0]
      7:       vs_fields = 32'h00FF_FFFF;                   // TRACK: burst_cycles[23:16] vmax[15:0]
      default: vs_fields = 32'h00FF_FFFF;                   // PHASE: ticks[23:0]
    endcase
  endfunction
  function automatic logic [31:0] vs_reset(input int r);
    unique case (r)
      2:       vs_reset = 32'h0000_0310;   // order 1, miss_limit 3, mode 0 (off)
      3:       vs_reset = {16'd24000, 16'd24000};
      4:       vs_reset = 32'd72000;
      5:       vs_reset = 32'd1200000;
      6:       vs_reset = {10'd0, 2'd1, 20'd72000};
      7:       vs_reset = {8'd0, 8'd8, 16'd24000};
      default: vs_reset = 32'd0;           // masks, phase
    endcase
  endfunction

  localparam int VS_WORDS = int'(NUM_VS) * VS_REGS;
  localparam int VS_AW    = $clog2(VS_WORDS);  // word address bits of the implemented entries
  // word addresses are 7 bits (8 entries); a reduced build's table needs fewer, the top ones
  // are zero whenever vs_m is accessed
  logic unused_vs_hi;
  // word entry * VS_REGS + register. On the ECP5 the synthesis script asks for distributed RAM
  // (mk/synth.mk: a block RAM would be one more DP16KD); no attribute here: simulation and
  // lint do not need it. One read port (a second one would be a second copy of the RAM).
  logic [31:0] vs_m [VS_WORDS];
  logic [3:0]  vs_reg;   // register within the entry: byte offset / 4
  logic [2:0]  vs_sel;   // entry of the held request
  logic        vs_wr;    // the regblock accepts a write to the VS table in this clock
  // The entry and the write come from the held request's address bits, decoded as the slice
  // registers it (rq_vs_q), not from the regblock's VS[v].req: that is a range compare per
  // entry (carry chains) and was the start of the board top's slowest path. VS[v] spans
  // 0x100 + 0x40 v .. + 0x23 (0x100 .. 0x2E3), so the hit is addr[10:8] = 1 or 2 with
  // addr[5:0] <= 0x23, and the entry is {addr[9], addr[7:6]}. The regblock accepts a write when it does not stall it
  // (cpuif_req_masked), so vs_wr equals OR_v(VS[v].req & req_is_wr).
  logic        rq_vs_q;
  always_ff @(posedge clk_i) begin
    if (!rq_held) rq_vs_q <= !bus_addr_i[10] && (bus_addr_i[9] ^ bus_addr_i[8])
                             && (!bus_addr_i[5] || bus_addr_i[4:2] == 3'd0);
  end
  assign vs_reg = rq_addr_q[5:2];
  assign vs_sel = {rq_addr_q[9], rq_addr_q[7:6]};
  // the bus's write strobe into the table: the regblock still acknowledges writes to entries
  // the build does not implement (vs_sel >= NUM_VS), which change nothing
  assign vs_wr  = rq_valid_q && rq_is_wr_q && !rb_stall_wr && rq_vs_q && !vs_init_busy
                  && 32'(vs_sel) < 32'(NUM_VS);
  // offsets 0x24..0x3F of an entry are outside the table (the regblock answers rd_err and
  // ignores the data), so they may address register 8
  logic [3:0] vs_reg_c;
  logic [6:0] vs_word;
  assign vs_reg_c = vs_reg[3] ? 4'(VS_REGS - 1) : vs_reg;
  assign vs_word  = {1'b0, vs_sel, 3'b0} + 7'(vs_sel) + 7'(vs_reg_c);  // entry * 9 + register
  // After a reset: every word back to its register's reset value, one per clock (vs_init_q
  // counts the words, vs_ir_q the register of the word), the bus stalled until done.
  logic [6:0] vs_init_q;
  logic [3:0] vs_ir_q;
  assign vs_init_busy = vs_init_q != 7'(VS_WORDS);
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      vs_init_q <= '0;
      vs_ir_q   <= '0;
    end else if (vs_init_busy) begin
      vs_init_q <= vs_init_q + 7'd1;
      vs_ir_q   <= (vs_ir_q == 4'(VS_REGS - 1)) ? 4'd0 : vs_ir_q + 4'd1;
    end
  end
  logic [31:0] vs_reset_w;  // the reset value of register vs_ir_q
  always_comb begin
    vs_reset_w = '0;
    for (int r = 0; r < VS_REGS; r++) if (vs_ir_q == 4'(r)) vs_reset_w = vs_reset(r);
  end
  logic [31:0] vs_fields_w;  // the implemented bits of the written register
  always_comb begin
    vs_fields_w = '0;
    for (int r = 0; r < VS_REGS; r++) if (vs_reg_c == 4'(r)) vs_fields_w = vs_fields(r);
  end
  always_ff @(posedge clk_i) begin
    if (!rst_i && vs_init_busy) begin
      vs_m[VS_AW'(vs_init_q)] <= vs_reset_w;
    end else if (!rst_i && vs_wr) begin
      for (int b = 0; b < 4; b++)
        if (rq_wr_biten_q[8*b]) vs_m[VS_AW'(vs_word)][8*b +: 8] <= rq_wr_data_q[8*b +: 8] & vs_fields_w[8*b +: 8];
    end
  end
  // The bus's read: the word address is registered (vs_word_q), the RAM read a clock later
  // (vs_rd_q), so the answer (vs_rd_ack_q) comes two clocks after the request.
  logic [6:0]              vs_word_q;
  logic                    vs_impl_q;  // the read's entry is implemented (< NUM_VS), else it reads 0
  logic [31:0]             vs_rd_q;
  logic                    vs_rd_impl_q;  // vs_impl_q of the word in vs_rd_q
  logic [VS_ENTRIES-1:0]   vs_rd_req_q;
  assign unused_vs_hi = ^vs_word_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      vs_rd_req_q  <= '0;
      vs_rd_ack_q  <= '0;
      vs_wr_ack_q  <= '0;
    end else begin
      for (int v = 0; v < int'(VS_ENTRIES); v++) begin
        vs_rd_req_q[v] <= hwif_out.VS[v].req && !hwif_out.VS[v].req_is_wr;
        vs_wr_ack_q[v] <= hwif_out.VS[v].req && hwif_out.VS[v].req_is_wr;
      end
      vs_rd_ack_q <= vs_rd_req_q;
    end
    vs_word_q    <= vs_word;
    vs_impl_q    <= 32'(vs_sel) < 32'(NUM_VS);
    vs_rd_q      <= vs_m[VS_AW'(vs_word_q)];
    vs_rd_impl_q <= vs_impl_q;
  end
  assign vs_rdata_bus = vs_rd_impl_q ? vs_rd_q : 32'd0;

  // ---- phasing-delay table: external memory of the regblock, kept in block RAM (one
  // DP16KD). The RAM stores DELAY_W bits per entry; the upper bits of a bus write are dropped
  // (the firmware refuses a table whose delays do not fit) and read back as zero.
  logic [DELAY_W-1:0] delay_m [256];
  always_ff @(posedge clk_i) begin
    if (hwif_out.DELAY.req && hwif_out.DELAY.req_is_wr)
      delay_m[hwif_out.DELAY.addr[9:2]] <= hwif_out.DELAY.wr_data[DELAY_W-1:0];
    delay_rdata_a <= delay_m[hwif_out.DELAY.addr[9:2]];
  end

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      delay_rd_pending_q <= 1'b0;
      delay_wr_pending_q <= 1'b0;
    end else begin
      delay_rd_pending_q <= hwif_out.DELAY.req & ~hwif_out.DELAY.req_is_wr;
      delay_wr_pending_q <= hwif_out.DELAY.req &  hwif_out.DELAY.req_is_wr;
    end
  end
endmodule
