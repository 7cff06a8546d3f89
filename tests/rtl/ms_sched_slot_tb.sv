// ms_sched_slot_tb: cocotb wrapper of ms_sched_slot (tests/rtl/tb_ms_sched_slot.py) with the
// WIN RAM it reads: NUM_CH * WSLOTS slots {t0, we, len, sensor}, written by the testbench
// through wr_*_i, read one clock after the unit's address (a registered block-RAM read).
module ms_sched_slot_tb #(
  parameter int NUM_CH = 24,
  parameter int WSLOTS = 16,
  localparam int EW = $clog2(NUM_CH),
  localparam int AW = $clog2(NUM_CH * WSLOTS)
) (
  input  logic              clk_i,
  input  logic              rst_i,
  input  logic              wr_en_i,
  input  logic [AW-1:0]     wr_addr_i,
  input  logic [31:0]       wr_t0_i,
  input  logic [23:0]       wr_len_i,
  input  logic [23:0]       wr_we_i,
  input  logic [2:0]        wr_sensor_i,
  input  logic              go_i,
  input  logic [1:0]        mode_i,
  input  logic [EW-1:0]     el_i,
  input  logic              bon_i,
  input  logic              won_i,
  input  logic [WSLOTS-1:0] valid_i,
  input  logic [31:0]       ta_i,
  input  logic [31:0]       tb_i,
  input  logic [31:0]       twa_i,
  input  logic [31:0]       twb_i,
  input  logic [7:0]        latm1_i,
  output logic              busy_o,
  output logic [31:0]       x_o,
  output logic [7:0]        flags_o,
  output logic [31:0]       minc_o
);
  typedef struct packed {
    logic [31:0] t0;
    logic [23:0] we;
    logic [23:0] len;
    logic [2:0]  sensor;
  } slot_t;
  slot_t         mem_q [NUM_CH * WSLOTS];
  slot_t         rd_q;
  logic [AW-1:0] ra;
  logic          re;
  always_ff @(posedge clk_i) begin
    if (wr_en_i) mem_q[wr_addr_i] <= '{t0: wr_t0_i, we: wr_we_i, len: wr_len_i,
                                        sensor: wr_sensor_i};
    if (re) rd_q <= mem_q[ra];
  end

  ms_sched_slot #(.NUM_CH(NUM_CH), .WSLOTS(WSLOTS)) u_slot (
    .clk_i, .rst_i, .go_i, .mode_i, .el_i, .bon_i, .won_i, .valid_i, .ta_i, .tb_i, .twa_i, .twb_i,
    .latm1_i, .win_ra_o(ra), .win_re_o(re), .win_t0_i(rd_q.t0), .win_len_i(rd_q.len),
    .win_we_i(rd_q.we), .win_sensor_i(rd_q.sensor), .busy_o, .x_o, .flags_o, .minc_o
  );
endmodule
