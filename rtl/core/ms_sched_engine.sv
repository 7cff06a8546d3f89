// ms_sched_engine: the scheduler's microcoded engine core (docs/sched_engine.md): one register
// file, one ALU, a byte rotator, a lowest-set-bit encoder and a multiplier shared by every
// step of a program in a microcode ROM. The instruction set is multisonar.tools.sched_ucode
// (opcodes from the generated ms_ucode_pkg); that module's Machine is this core's golden
// model, clock for clock.
//
// Timing contract (clocks of clk_i):
//   - rst_i: the pc is 0 and nothing executes; the instruction at address 0 is in the R stage
//     in the first clock with rst_i low, and every clock after that holds the next instruction
//     (one per clock, no stalls; a taken branch, call or return puts its target in the R stage
//     in the next clock).
//   - The instruction in the R stage in clock k reads the registers and flags and decides its
//     branch; in clock k + 1 (X stage) it computes and drives the bus (bus_re_o / bus_we_o,
//     bus_addr_o = ra + imm, bus_wdata_o = rb) and sets the flags; in clock k + 2 (W stage)
//     its result, or bus_rdata_i for a load (the data of the address read in the clock
//     before), is written to rd and forwarded to the instruction then in the R stage.
//   - bus_abs_o (ra is r0) and bus_imm_o (the sign-extended immediate, then the address) come
//     from registers in the X stage, bus_addr_o from an adder behind them: a bus with many
//     targets decodes its registers from an absolute access's immediate and keeps the sum
//     for the memories an indexed access reaches.
//   - So a result and the flags are usable from the second instruction after their producer;
//     the assembler puts a NOP between neighbours that would read too early (the core has no
//     interlocks and reads a stale value there).
//   - A compare-and-branch (OP_CB*) sets the flags in its X stage like its ALU operation and
//     decides in its W stage (clock k + 2) on them: taken, the pc is its target and the two
//     instructions behind it (R and X stages) are squashed (no bus access, no register, flag
//     or link write; the R stage's branch is overridden), so the target is in the R stage in
//     clock k + 3.
//   - UCODE_FILE: the ROM's $readmemh image (multisonar.tools.sched_ucode.Image.hex); empty:
//     the ROM is written by the testbench. With UCODE_BRAM < UCODE_WORDS the ROM is two: the
//     first UCODE_BRAM words (UCODE_FILE) in block RAM, the rest (UCODE_FILE_HI) a table in
//     logic, both read in the same clock (a 2:1 multiplexer behind their output registers):
//     the words beyond a power of two of block RAM cost a few LUTs instead of block RAMs.
module ms_sched_engine
  import ms_ucode_pkg::*;
#(
  parameter int    UCODE_WORDS = 512,  // ROM depth (one DP16KD of 36-bit words)
  parameter string UCODE_FILE  = "",
  parameter int    UCODE_BRAM  = UCODE_WORDS,  // of which in block RAM (a power of two)
  parameter string UCODE_FILE_HI = "",         // the words from UCODE_BRAM on
  parameter int    AW          = 12,   // bus address width
  localparam int   PW          = $clog2(UCODE_WORDS)
) (
  input  logic          clk_i,
  input  logic          rst_i,
  output logic          bus_re_o,
  output logic          bus_we_o,
  output logic [AW-1:0] bus_addr_o,
  output logic          bus_abs_o,
  output logic [AW-1:0] bus_imm_o,
  output logic [31:0]   bus_wdata_o,
  input  logic [31:0]   bus_rdata_i,
  output logic [PW-1:0] pc_o          // address of the instruction in the R stage
);
  localparam int IW = 15;              // immediate field width

  // ------------------------------------------------------------------ fetch (F) -> R
  localparam int HI_WORDS = UCODE_WORDS - UCODE_BRAM;
  localparam int BW       = $clog2(UCODE_BRAM);
  localparam int HW       = HI_WORDS > 1 ? $clog2(HI_WORDS) : 1;
  if (UCODE_BRAM < 1 || (1 << BW) != UCODE_BRAM || HI_WORDS < 0
      || (HI_WORDS > 0 && (1 << HW) > UCODE_BRAM)) begin : g_bad_rom
    $error("ms_sched_engine: UCODE_BRAM %0d must be a power of two <= UCODE_WORDS %0d, and the",
           " rest at most UCODE_BRAM", UCODE_BRAM, UCODE_WORDS);
  end
  logic [UC_WORD_BITS-1:0] rom_q [UCODE_BRAM];
  initial if (UCODE_FILE != "") $readmemh(UCODE_FILE, rom_q);

  logic [UC_WORD_BITS-1:0] ir_q;       // the instruction in the R stage (executed unless rst_i)
  logic [PW-1:0]           pc_q, pc_d, lr_q, lr_d;

  logic [5:0]    r_op;
  logic [4:0]    r_rd, r_ra, r_rb;
  logic [IW-1:0] r_imm;
  assign {r_op, r_rd, r_ra, r_rb, r_imm} = ir_q;

  // ------------------------------------------------------------------ R: decode, branch, read
  logic z_q, n_q;                      // flags, set in the X stage
  function automatic logic cond_holds(input logic [3:0] cc, input logic z, input logic n);
    unique case (cc)
      CC_AL:   cond_holds = 1'b1;
      CC_EQ:   cond_holds = z;
      CC_NE:   cond_holds = !z;
      CC_LT:   cond_holds = n;
      CC_GE:   cond_holds = !n;
      CC_LE:   cond_holds = n || z;
      CC_GT:   cond_holds = !n && !z;
      default: cond_holds = 1'b0;
    endcase
  endfunction
  logic          r_taken;
  assign r_taken = cond_holds(r_rd[3:0], z_q, n_q);

  // W stage of a compare-and-branch: taken squashes the R and X stages (kill). Its condition
  // is decided at the end of its X stage, on the flags it sets there, and registered: kill
  // gates the bus strobes, whose decode fans out across the scheduler
  logic          w_kill_q, kill;
  logic [PW-1:0] w_tgt_q;
  assign kill = w_kill_q;

  always_comb begin
    pc_d = pc_q + PW'(1);
    lr_d = lr_q;
    if (rst_i) begin
      pc_d = '0;
      lr_d = '0;
    end else if (kill) begin
      pc_d = w_tgt_q;
    end else begin
      unique case (r_op)
        OP_B:    if (r_taken) pc_d = r_imm[PW-1:0];
        OP_CALL: begin
          pc_d = r_imm[PW-1:0];
          lr_d = pc_q + PW'(1);
        end
        OP_RET:  pc_d = lr_q;
        default: ;
      endcase
    end
  end

  always_ff @(posedge clk_i) begin
    pc_q     <= pc_d;
    lr_q     <= lr_d;
  end
  assign pc_o = pc_q;

  if (HI_WORDS > 0) begin : g_rom_hi
    // the words from UCODE_BRAM on: pc_d[HW-1:0] indexes them (UCODE_BRAM is a multiple of
    // 2^HW), the flag says which table the R stage takes
    logic [UC_WORD_BITS-1:0] rom_hi_q [HI_WORDS];
    initial if (UCODE_FILE_HI != "") $readmemh(UCODE_FILE_HI, rom_hi_q);
    logic [UC_WORD_BITS-1:0] ir_lo_q, ir_hi_q;
    logic                    hi_q;
    always_ff @(posedge clk_i) begin
      ir_lo_q <= rom_q[pc_d[BW-1:0]];
      ir_hi_q <= rom_hi_q[pc_d[HW-1:0]];
      hi_q    <= pc_d >= PW'(UCODE_BRAM);
    end
    assign ir_q = hi_q ? ir_hi_q : ir_lo_q;
  end else begin : g_rom
    logic [UC_WORD_BITS-1:0] ir_lo_q;
    always_ff @(posedge clk_i) ir_lo_q <= rom_q[pc_d];
    assign ir_q = ir_lo_q;
  end

  // register file: two asynchronous read ports (distributed RAM), one write port (W stage);
  // r0 is never written and reads 0; all registers are 0 at power-up, a reset keeps them
  logic [31:0] rf_q [32];
  initial for (int i = 0; i < 32; i++) rf_q[i] = '0;

  logic        w_we_q, w_ld_q;
  logic [4:0]  w_rd_q;
  logic [31:0] w_res_q, w_data;
  assign w_data = w_ld_q ? bus_rdata_i : w_res_q;
  always_ff @(posedge clk_i) if (w_we_q) rf_q[w_rd_q] <= w_data;

  logic [31:0] r_a;                    // a operand, the W stage's result forwarded
  // r0 is never written, so `r_ra != 0` changes nothing here; it keeps Yosys from seeing a
  // transparent read port and merging x_a_q into it, which would put the register-file read
  // (behind an address register) into the X stage's path to the flags
  assign r_a = (w_we_q && w_rd_q == r_ra && r_ra != 5'd0) ? w_data : rf_q[r_ra];

  // decode into the X stage's controls
  typedef enum logic [3:0] {
    FN_ADD, FN_SUB, FN_AND, FN_OR, FN_XOR, FN_ANDN, FN_MUL, FN_LSB, FN_ROTB, FN_NONE
  } fn_e;
  fn_e         r_fn;
  logic        r_imm_b, r_u_b, r_ld, r_st, r_cb, r_k_b, r_bit_b;
  always_comb begin
    r_fn    = FN_NONE;
    r_imm_b = 1'b0;  // b operand: sign-extended imm15 (else rb)
    r_u_b   = 1'b0;  // b operand: {rb field, imm15} << 12
    r_k_b   = 1'b0;  // b operand: sign-extended {rb field, imm[14:11]} (OP_CBI)
    r_bit_b = 1'b0;  // b operand: 1 << rb field (OP_CBB)
    r_ld    = 1'b0;
    r_st    = 1'b0;
    r_cb    = 1'b0;
    unique case (r_op)
      OP_ADD:  r_fn = FN_ADD;
      OP_SUB:  r_fn = FN_SUB;
      OP_AND:  r_fn = FN_AND;
      OP_OR:   r_fn = FN_OR;
      OP_XOR:  r_fn = FN_XOR;
      OP_ANDN: r_fn = FN_ANDN;
      OP_MUL:  r_fn = FN_MUL;
      OP_ADDI: {r_fn, r_imm_b} = {FN_ADD, 1'b1};
      OP_ANDI: {r_fn, r_imm_b} = {FN_AND, 1'b1};
      OP_ORI:  {r_fn, r_imm_b} = {FN_OR, 1'b1};
      OP_XORI: {r_fn, r_imm_b} = {FN_XOR, 1'b1};
      OP_LUI:  {r_fn, r_u_b}   = {FN_OR, 1'b1};  // ra = r0
      OP_LSB:  r_fn = FN_LSB;
      OP_ROTB: r_fn = FN_ROTB;
      OP_LD:   {r_ld, r_imm_b} = 2'b11;
      OP_ST:   r_st = 1'b1;
      OP_CB:   {r_fn, r_cb} = {FN_SUB, 1'b1};
      OP_CBI:  {r_fn, r_cb, r_k_b} = {FN_SUB, 2'b11};
      OP_CBB:  {r_fn, r_cb, r_bit_b} = {FN_AND, 2'b11};
      OP_CBT:  {r_fn, r_cb} = {FN_AND, 1'b1};
      default: ;
    endcase
    if (rst_i || kill) begin
      r_fn = FN_NONE;
      r_ld = 1'b0;
      r_st = 1'b0;
      r_cb = 1'b0;
    end
  end

  // b operand: an immediate form, else rb (forwarded). rb enters last, one multiplexer before
  // x_b_q: a load's data comes from a block RAM's unregistered output
  logic        r_b_imm_form;
  logic [31:0] r_b, r_b_imm;
  assign r_b          = (w_we_q && w_rd_q == r_rb) ? w_data : rf_q[r_rb];
  assign r_b_imm_form = r_u_b || r_imm_b || r_k_b || r_bit_b;
  assign r_b_imm      = r_u_b ? {r_rb, r_imm, 12'd0} : r_imm_b ? 32'($signed(r_imm))
                      : r_k_b ? 32'($signed({r_rb, r_imm[14:11]})) : 32'd1 << r_rb;

  // ------------------------------------------------------------------ X: ALU, bus, flags
  fn_e           x_fn_q;
  logic          x_ld_q, x_st_q, x_we_q, x_cb_q;
  logic [3:0]    x_cc_q;
  logic [PW-1:0] x_tgt_q;
  logic [4:0]    x_rd_q;
  logic [31:0]   x_a_q, x_b_q;
  logic [AW-1:0] x_imm_q;              // the bus address's offset
  logic          x_abs_q;              // ra is r0: the address is x_imm_q
  logic [1:0]    x_rotb_q;             // ROTB: bytes to rotate by
  always_ff @(posedge clk_i) begin
    x_fn_q  <= r_fn;
    x_ld_q  <= r_ld;
    x_st_q  <= r_st;
    x_we_q  <= (r_fn != FN_NONE || r_ld) && r_rd != 5'd0 && !r_cb;
    x_cb_q  <= r_cb;
    x_cc_q  <= r_rd[3:0];
    x_tgt_q <= r_imm[PW-1:0];
    x_rd_q  <= r_rd;
    x_a_q   <= r_a;
    x_b_q   <= r_b_imm_form ? r_b_imm : r_b;
    x_imm_q <= AW'($signed(r_imm));
    x_abs_q <= r_ra == 5'd0;
    x_rotb_q <= r_imm[1:0];
  end

  // adder: a + b, a - b, and 0 - a for the lowest set bit (a & -a)
  logic [31:0] x_sum;
  always_comb begin
    unique case (x_fn_q)
      FN_SUB:  x_sum = x_a_q - x_b_q;
      FN_LSB:  x_sum = 32'd0 - x_a_q;
      default: x_sum = x_a_q + x_b_q;
    endcase
  end
  // lowest set bit: one-hot a & -a, encoded by OR trees
  logic [31:0] x_onehot;
  logic [4:0]  x_lsb;
  always_comb begin
    x_onehot = x_a_q & x_sum;
    x_lsb    = '0;
    for (int i = 0; i < 32; i++) if (x_onehot[i]) x_lsb = x_lsb | 5'(i);
  end
  // byte rotator: a rotated right by 0-3 bytes (a general rotator or field extractor costs
  // 250-500 LUT4 more; fields sit on byte boundaries instead, docs/sched_engine.md)
  logic [31:0] x_rot;
  always_comb begin
    unique case (x_rotb_q)
      2'd1:    x_rot = {x_a_q[7:0], x_a_q[31:8]};
      2'd2:    x_rot = {x_a_q[15:0], x_a_q[31:16]};
      2'd3:    x_rot = {x_a_q[23:0], x_a_q[31:24]};
      default: x_rot = x_a_q;
    endcase
  end
  // multiplier: signed 18 x 18, the low 32 bits of the product
  logic [31:0] x_prod;
  assign x_prod = 32'($signed(x_a_q[17:0]) * $signed(x_b_q[17:0]));

  // every result but the product: the flags' source (MUL keeps the flags), so the multiplier
  // is not on the path to them
  logic [31:0] x_alu, x_res;
  always_comb begin
    unique case (x_fn_q)
      FN_AND:  x_alu = x_a_q & x_b_q;
      FN_OR:   x_alu = x_a_q | x_b_q;
      FN_XOR:  x_alu = x_a_q ^ x_b_q;
      FN_ANDN: x_alu = x_a_q & ~x_b_q;
      FN_LSB:  x_alu = {27'd0, x_lsb};
      FN_ROTB: x_alu = x_rot;
      default: x_alu = x_sum;  // FN_ADD, FN_SUB (FN_MUL: x_res; FN_NONE: not written)
    endcase
  end
  assign x_res = (x_fn_q == FN_MUL) ? x_prod : x_alu;

  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      z_q <= 1'b0;
      n_q <= 1'b0;
    end else if (!kill && x_fn_q != FN_NONE && x_fn_q != FN_MUL) begin  // MUL keeps the flags
      z_q <= (x_fn_q == FN_LSB) ? (x_onehot == '0) : (x_alu == '0);
      n_q <= x_alu[31];
    end
    w_kill_q <= !rst_i && x_cb_q && !kill && cond_holds(x_cc_q, x_alu == '0, x_alu[31]);
    w_tgt_q <= x_tgt_q;
    w_we_q  <= x_we_q && !kill;
    w_ld_q  <= x_ld_q;
    w_rd_q  <= x_rd_q;
    w_res_q <= x_res;
  end

  assign bus_re_o    = x_ld_q && !kill;
  assign bus_we_o    = x_st_q && !kill;
  assign bus_addr_o  = AW'(x_a_q) + x_imm_q;
  assign bus_abs_o   = x_abs_q;
  assign bus_imm_o   = x_imm_q;
  assign bus_wdata_o = x_b_q;  // ST's b operand is rb (r_imm_b is low for it)

endmodule
