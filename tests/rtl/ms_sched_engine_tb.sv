// ms_sched_engine_tb: cocotb wrapper of ms_sched_engine (tests/rtl/tb_ms_sched_engine.py).
//
// The engine's bus is a plain RAM of 2^AW words (read data one clock after the address, as
// the scheduler's block RAMs answer). The testbench writes the microcode ROM (u_eng.rom_q) and
// the RAM (mem_q) through the simulator before reset and watches the bus.
module ms_sched_engine_tb #(
  parameter int UCODE_WORDS = 1024,
  parameter int AW          = 12,
  localparam int PW         = $clog2(UCODE_WORDS)
) (
  input  logic          clk_i,
  input  logic          rst_i,
  output logic          bus_re_o,
  output logic          bus_we_o,
  output logic [AW-1:0] bus_addr_o,
  output logic          bus_abs_o,
  output logic [AW-1:0] bus_imm_o,
  output logic [31:0]   bus_wdata_o,
  output logic [PW-1:0] pc_o
);
  logic [31:0] mem_q [2**AW];
  logic [31:0] rdata_q;
  initial for (int i = 0; i < 2**AW; i++) mem_q[i] = '0;
  always_ff @(posedge clk_i) begin
    if (bus_we_o) mem_q[bus_addr_o] <= bus_wdata_o;
    rdata_q <= mem_q[bus_addr_o];
  end

  ms_sched_engine #(.UCODE_WORDS(UCODE_WORDS), .AW(AW)) u_eng (
    .clk_i      (clk_i),
    .rst_i      (rst_i),
    .bus_re_o   (bus_re_o),
    .bus_we_o   (bus_we_o),
    .bus_addr_o (bus_addr_o),
    .bus_abs_o  (bus_abs_o),
    .bus_imm_o  (bus_imm_o),
    .bus_wdata_o(bus_wdata_o),
    .bus_rdata_i(rdata_q),
    .pc_o       (pc_o)
  );
endmodule
