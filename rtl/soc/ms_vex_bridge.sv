// ms_vex_bridge: VexRiscv's two Wishbone buses -> the SoC's single-port RAM (shared) and its
// native (PicoRV32-style mem_valid / mem_ready) port to the peripherals.
//
// Region: RAM is 0x0xxx_xxxx (word address truncated to RAM_AW bits, as on the PicoRV32 path).
// RAM sharing: the two buses take turns on the one RAM port (one block-RAM copy; a true
// dual-port 64 KiB RAM with byte enables takes twice the ECP5 DP16KD blocks). A bus keeps the
// port from its request until it drops CYC/STB (a whole burst); when both ask in the same
// clock of a free port the data bus goes first. The CPU's caches make that rare.
// Instruction bus (cache line refills, 8-beat incrementing bursts): the first word answers one
// clock after the granted request, then one word per clock (in the clock that acknowledges a
// word of a CTI=010 burst the RAM already reads the next one). A fetch outside RAM is answered
// with ERR (the CPU takes an instruction access fault) and strobes ifetch_err_o.
// Data bus: a RAM write is acknowledged in its granted request clock (the RAM writes at that
// clock's end); a RAM read one clock after it, bursts (data cache refills) then one word per
// clock as above. Every other address goes out on mem_* (mem_valid_o held until mem_ready_i,
// which completes the Wishbone cycle; mem_wstrb_o = 0 for a read).
module ms_vex_bridge #(
  parameter int RAM_AW = 14
) (
  input  logic              clk_i,
  input  logic              rst_i,
  // instruction bus (Wishbone slave, read-only)
  input  logic              ibus_cyc_i,
  input  logic              ibus_stb_i,
  input  logic [29:0]       ibus_adr_i,
  input  logic [2:0]        ibus_cti_i,
  output logic              ibus_ack_o,
  output logic              ibus_err_o,
  output logic [31:0]       ibus_dat_o,
  // data bus (Wishbone slave)
  input  logic              dbus_cyc_i,
  input  logic              dbus_stb_i,
  input  logic              dbus_we_i,
  input  logic [29:0]       dbus_adr_i,
  input  logic [31:0]       dbus_dat_i,
  input  logic [3:0]        dbus_sel_i,
  input  logic [2:0]        dbus_cti_i,
  output logic              dbus_ack_o,
  output logic [31:0]       dbus_dat_o,
  // RAM (one port, byte write enables, one clock read latency)
  output logic [RAM_AW-1:0] ram_addr_o,
  output logic [3:0]        ram_we_o,
  output logic [31:0]       ram_wdata_o,
  input  logic [31:0]       ram_rdata_i,
  // everything outside RAM
  output logic              mem_valid_o,
  output logic [31:0]       mem_addr_o,
  output logic [31:0]       mem_wdata_o,
  output logic [3:0]        mem_wstrb_o,
  input  logic              mem_ready_i,
  input  logic [31:0]       mem_rdata_i,
  output logic              ifetch_err_o
);
  localparam logic [2:0] CTI_INCR = 3'b010;

  // only the RAM's word address bits are decoded past the region nibble
  logic [25-RAM_AW:0] unused_i_adr, unused_d_adr;
  assign unused_i_adr = ibus_adr_i[25:RAM_AW];
  assign unused_d_adr = dbus_adr_i[25:RAM_AW];

  // ---- RAM port ownership
  logic i_req, i_ram, d_req, d_ram, gnt_i, gnt_d;
  logic own_i_q, own_d_q;
  assign i_req = ibus_cyc_i & ibus_stb_i;
  assign i_ram = ibus_adr_i[29:26] == 4'h0;
  assign d_req = dbus_cyc_i & dbus_stb_i;
  assign d_ram = dbus_adr_i[29:26] == 4'h0;
  assign gnt_d = d_req & d_ram & ~own_i_q;
  assign gnt_i = i_req & i_ram & ~own_d_q & ~gnt_d;
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      own_i_q <= 1'b0;
      own_d_q <= 1'b0;
    end else begin
      own_i_q <= gnt_i;
      own_d_q <= gnt_d;
    end
  end

  // ---- instruction bus
  logic i_ack_q, i_err_q;
  logic [RAM_AW-1:0] i_addr, d_addr;
  assign i_addr = (i_ack_q && ibus_cti_i == CTI_INCR) ? ibus_adr_i[RAM_AW-1:0] + RAM_AW'(1)
                                                      : ibus_adr_i[RAM_AW-1:0];
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      i_ack_q <= 1'b0;
      i_err_q <= 1'b0;
    end else begin
      i_ack_q <= gnt_i & (~i_ack_q | ibus_cti_i == CTI_INCR);
      i_err_q <= i_req & ~i_ram & ~i_err_q;
    end
  end
  assign ibus_ack_o   = i_ack_q & i_req;
  assign ibus_err_o   = i_err_q & i_req;
  assign ibus_dat_o   = ram_rdata_i;
  assign ifetch_err_o = i_err_q;

  // ---- data bus
  logic d_ack_q;
  assign d_addr = (d_ack_q && dbus_cti_i == CTI_INCR) ? dbus_adr_i[RAM_AW-1:0] + RAM_AW'(1)
                                                      : dbus_adr_i[RAM_AW-1:0];
  always_ff @(posedge clk_i) begin
    if (rst_i) d_ack_q <= 1'b0;
    else       d_ack_q <= gnt_d & ~dbus_we_i & (~d_ack_q | dbus_cti_i == CTI_INCR);
  end

  assign ram_addr_o  = gnt_d ? d_addr : i_addr;
  assign ram_we_o    = (gnt_d & dbus_we_i) ? dbus_sel_i : 4'b0;
  assign ram_wdata_o = dbus_dat_i;

  assign mem_valid_o = d_req & ~d_ram;
  assign mem_addr_o  = {dbus_adr_i, 2'b00};
  assign mem_wdata_o = dbus_dat_i;
  assign mem_wstrb_o = dbus_we_i ? dbus_sel_i : 4'b0;

  assign dbus_ack_o = (d_ack_q & d_req) | (gnt_d & dbus_we_i) | mem_ready_i;
  assign dbus_dat_o = d_ack_q ? ram_rdata_i : mem_rdata_i;
endmodule
