// ms_ram_sp_bytes: single-port 32-bit RAM with byte write enables, optionally preloaded.
//
// Timing contract: synchronous; rdata_o shows the word at addr_i of the previous clock
// (read-before-write). INIT_FILE (hex words for $readmemh, one per line) preloads it: the
// firmware image in simulation and in the FPGA bitstream.
//
// WORDS not a power of two: the RAM is built from one bank per set bit of WORDS, largest
// first at address 0 (15360 = 8192 + 4096 + 2048 + 1024 words). Each bank maps to whole
// block RAMs (ECP5: 16, 8, 4, 2 DP16KD for those four; 60 KiB in 30 DP16KD instead of 32 for
// 64 KiB), where one array of 15360 words would take 30 DP16KD and ~800 LUT4 of read
// multiplexer. Each bank is built from columns of the width its depth gives one block RAM
// (below); column c of bank k is preloaded from "INIT_FILE.k.c" (multisonar.tools.bin2memh
// writes them). Writes at WORDS and above are ignored; reads there return a word of the
// last bank.
module ms_ram_sp_bytes #(
  parameter int    WORDS     = 8192,
  parameter int    AW        = $clog2(WORDS),
  parameter string INIT_FILE = ""
) (
  input  logic          clk_i,
  input  logic [AW-1:0] addr_i,
  input  logic [3:0]    we_i,
  input  logic [31:0]   wdata_i,
  output logic [31:0]   rdata_o
);
  // bank k: 2^BANK_BIT(k) words from word BANK_BASE(k), for the set bits of WORDS, high first
  function automatic int bank_bit(input int k);
    int n;
    n = 0;
    for (int b = AW - 1; b >= 0; b--) begin
      if (WORDS[b]) begin
        if (n == k) return b;
        n++;
      end
    end
    return -1;
  endfunction
  function automatic int bank_base(input int k);
    int base;
    base = 0;
    for (int j = 0; j < k; j++) base += 1 << bank_bit(j);
    return base;
  endfunction

  if ((WORDS & (WORDS - 1)) == 0) begin : g_one
    logic [31:0] mem_q [WORDS];

    initial begin
      if (INIT_FILE != "") $readmemh(INIT_FILE, mem_q);
    end

    always_ff @(posedge clk_i) begin
      for (int b = 0; b < 4; b++) begin
        if (we_i[b]) mem_q[addr_i][8*b +: 8] <= wdata_i[8*b +: 8];
      end
      rdata_o <= mem_q[addr_i];
    end
  end else begin : g_banked
    localparam int NB = $countones(WORDS);

    localparam int KW = NB > 1 ? $clog2(NB) : 1;
    logic [NB-1:0]       sel;
    logic [KW-1:0]       bank, bank_q;  // the bank addr_i falls in (the last one past the end)
    logic [NB-1:0][31:0] rd;  // packed: an unpacked array would be a memory to Yosys
    for (genvar k = 0; k < NB; k++) begin : g_bank
      localparam int B    = bank_bit(k);
      localparam int BASE = bank_base(k);
      // Columns of W bits, one block RAM each in the ECP5 mode of this depth (8192 x 2,
      // 4096 x 4, 2048 x 9, 1024 x 18, 512 x 36): as one 32-bit array Yosys used the widest
      // mode and stacked rows behind a multiplexer (~300 LUT4 for 60 KiB).
      localparam int W    = (16384 >> B) >= 32 ? 32 : (16384 >> B);
      logic [31:0] rd_q;  // the columns' registered read data

      // the bank's address range: the bits above B equal BASE's
      assign sel[k] = (addr_i >> B) == AW'(BASE >> B);
      for (genvar c = 0; c < 32 / W; c++) begin : g_col
        logic [W-1:0] mem_q [1 << B];

        initial begin
          if (INIT_FILE != "") $readmemh($sformatf("%s.%0d.%0d", INIT_FILE, k, c), mem_q);
        end

        // write and read in one process: one read/write port of the block RAM, of width W
        // (with a separate read process Yosys read 18 bits and multiplexed them by address)
        logic [W-1:0] col_rd_q;
        if (W >= 8) begin : g_bytes  // whole bytes per column: byte enables
          always_ff @(posedge clk_i) begin
            for (int b = 0; b < W / 8; b++)
              if (sel[k] && we_i[c * W / 8 + b]) mem_q[addr_i[B-1:0]][8*b +: 8] <= wdata_i[c * W + 8*b +: 8];
            col_rd_q <= mem_q[addr_i[B-1:0]];
          end
        end else begin : g_bits      // part of a byte per column: that byte's enable
          always_ff @(posedge clk_i) begin
            if (sel[k] && we_i[c * W / 8]) mem_q[addr_i[B-1:0]] <= wdata_i[c * W +: W];
            col_rd_q <= mem_q[addr_i[B-1:0]];
          end
        end
        assign rd_q[c * W +: W] = col_rd_q;
      end
      assign rd[k] = rd_q;
    end

    // a binary bank index, so the read multiplexer is a plain NB:1 (a one-hot AND-OR of the
    // four banks took ABC 9 LUT4 per bit)
    always_comb begin
      bank = KW'(NB - 1);
      for (int k = NB - 1; k >= 0; k--) if (sel[k]) bank = KW'(k);
    end
    always_ff @(posedge clk_i) bank_q <= bank;
    assign rdata_o = rd[bank_q];
  end
endmodule
