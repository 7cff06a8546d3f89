// ms_usb_ep0: control endpoint 0 in hardware: SETUP decode, standard requests, the MS OS 2.0
// vendor request, data/status stage sequencing with DATA0/DATA1, the device address and the
// configuration, halt bits of the bulk endpoints, and the descriptor ROM.
//
// Timing contract (driven by ms_usb_xact; pulses are one clock):
// - setup_begin_i, then setup_valid_i/setup_byte_i per payload byte of a SETUP data packet,
//   then setup_i if the packet was good (DATA0, CRC ok, 8 bytes): the request is decoded on that
//   clock and takes effect on the next. A SETUP always clears a protocol STALL.
// - IN token: in_stall_o (else data) / in_len_o / in_pid1_o are valid whenever the
//   engine looks (registered state). in_start_i when the data packet starts; rd_i from ms_usb_tx;
//   data_o is the byte 2 clocks after each rd_i (held until the next). in_ack_i when the host ACKed.
// - OUT token with a good data packet: out_stall_o says STALL (else ACK); out_ack_i when ACKed.
// - SET_ADDRESS takes effect (addr_o) when the status stage is ACKed; SET_CONFIGURATION,
//   SET/CLEAR_FEATURE(ENDPOINT_HALT), SET_INTERFACE act at decode. toggle_rst_o[0] (EP1 OUT),
//   [1] (EP1 IN) pulse when the data toggle of that endpoint must restart at DATA0.
// - bus_reset_i: address 0, unconfigured, halts cleared, idle.
module ms_usb_ep0 #(
  parameter int SERIAL = 'h00000001  // the board's serial number (ms_usb_desc_rom)
) (
  input  logic       clk_i,
  input  logic       rst_i,
  input  logic       bus_reset_i,
  input  logic       setup_begin_i,
  input  logic       setup_valid_i,
  input  logic [7:0] setup_byte_i,
  input  logic       setup_i,
  output logic       in_stall_o,
  output logic [6:0] in_len_o,
  output logic       in_pid1_o,
  input  logic       in_start_i,
  input  logic       rd_i,
  output logic [7:0] data_o,
  input  logic       in_ack_i,
  output logic       out_stall_o,
  input  logic       out_ack_i,
  output logic [6:0] addr_o,
  output logic       configured_o,
  output logic [1:0] halt_o,
  output logic [1:0] toggle_rst_o
);
  import ms_usb_pkg::*;
  import ms_usb_desc_pkg::*;

  typedef enum logic [2:0] {E_IDLE, E_DIN, E_SOUT, E_SIN, E_STALL} state_e;

  // ---------------------------------------------------------------- SETUP capture
  logic [7:0] req_q [8];
  logic [3:0] nbytes_q;
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      nbytes_q <= '0;
      for (int i = 0; i < 8; i++) req_q[i] <= '0;
    end else if (setup_begin_i) begin
      nbytes_q <= '0;
    end else if (setup_valid_i) begin
      if (nbytes_q < 4'd8) req_q[nbytes_q[2:0]] <= setup_byte_i;
      if (nbytes_q != 4'd15) nbytes_q <= nbytes_q + 4'd1;
    end
  end

  logic [7:0]  bm, breq;
  logic [15:0] wvalue, windex, wlength;
  assign bm      = req_q[0];
  assign breq    = req_q[1];
  assign wvalue  = {req_q[3], req_q[2]};
  assign windex  = {req_q[5], req_q[4]};
  assign wlength = {req_q[7], req_q[6]};

  state_e     state_q;
  logic       toggle_q, configured_q, short_q, use_imm_q;
  logic [1:0] halt_q;            // [0] EP1 OUT, [1] EP1 IN
  logic [6:0] addr_q, new_addr_q;
  logic       set_addr_q;
  logic [8:0] base_q, rom_addr_q;
  logic [7:0] remain_q, pos_q, rd_idx_q;
  logic [6:0] cur_len_q;
  logic [15:0] imm_q;
  logic [7:0] imm_byte_q, rom_data;

  // ---------------------------------------------------------------- request decode
  // d_*: what the request does; evaluated on the clock of setup_i
  logic        d_ok, d_data, d_imm, d_set_addr, d_set_cfg, d_clr_halt, d_set_halt, d_set_if;
  logic [8:0]  d_base;
  logic [7:0]  d_len;
  logic [15:0] d_imm_val;
  logic        d_ep_out, d_ep_in, d_ep0;  // wIndex names EP1 OUT / EP1 IN / EP0
  assign d_ep_out = (windex == 16'h0001) && configured_q;
  assign d_ep_in  = (windex == 16'h0081) && configured_q;
  assign d_ep0    = (windex == 16'h0000) || (windex == 16'h0080);

  always_comb begin
    d_ok = 1'b0; d_data = 1'b0; d_imm = 1'b0; d_set_addr = 1'b0; d_set_cfg = 1'b0;
    d_clr_halt = 1'b0; d_set_halt = 1'b0; d_set_if = 1'b0;
    d_base = '0; d_len = '0; d_imm_val = '0;
    case ({bm, breq})
      16'h8006: begin  // GET_DESCRIPTOR
        d_ok = 1'b1; d_data = 1'b1;
        case (wvalue[15:8])
          8'h01: begin d_base = 9'(DESC_DEV_OFF); d_len = 8'(DESC_DEV_LEN); end
          8'h02: begin
            d_base = 9'(DESC_CFG_OFF); d_len = 8'(DESC_CFG_LEN);
            d_ok = (wvalue[7:0] == 8'd0);
          end
          8'h03: begin
            case (wvalue[7:0])
              8'd0: begin d_base = 9'(DESC_STR0_OFF); d_len = 8'(DESC_STR0_LEN); end
              8'd1: begin d_base = 9'(DESC_STR1_OFF); d_len = 8'(DESC_STR1_LEN); end
              8'd2: begin d_base = 9'(DESC_STR2_OFF); d_len = 8'(DESC_STR2_LEN); end
              8'd3: begin d_base = 9'(DESC_STR3_OFF); d_len = 8'(DESC_STR3_LEN); end
              8'd4: begin d_base = 9'(DESC_STR4_OFF); d_len = 8'(DESC_STR4_LEN); end
              default: d_ok = 1'b0;
            endcase
          end
          8'h0F: begin d_base = 9'(DESC_BOS_OFF); d_len = 8'(DESC_BOS_LEN); end
          default: d_ok = 1'b0;  // device qualifier etc.: STALL (full-speed only device)
        endcase
      end
      16'h0005: begin d_ok = (wvalue[15:7] == '0); d_set_addr = 1'b1; end  // SET_ADDRESS
      16'h0009: begin d_ok = (wvalue[15:1] == '0); d_set_cfg = 1'b1; end   // SET_CONFIGURATION
      16'h8008: begin d_ok = 1'b1; d_data = 1'b1; d_imm = 1'b1; d_len = 8'd1;  // GET_CONFIGURATION
        d_imm_val = {15'd0, configured_q}; end
      16'h8000, 16'h8100: begin d_ok = 1'b1; d_data = 1'b1; d_imm = 1'b1; d_len = 8'd2; end  // GET_STATUS
      16'h8200: begin  // GET_STATUS endpoint
        d_ok = d_ep0 | d_ep_out | d_ep_in; d_data = 1'b1; d_imm = 1'b1; d_len = 8'd2;
        d_imm_val = {15'd0, (d_ep_out & halt_q[0]) | (d_ep_in & halt_q[1])};
      end
      16'h0201: begin d_ok = (wvalue == 16'd0) && (d_ep0 | d_ep_out | d_ep_in); d_clr_halt = 1'b1; end
      16'h0203: begin d_ok = (wvalue == 16'd0) && (d_ep0 | d_ep_out | d_ep_in); d_set_halt = 1'b1; end
      16'h810A: begin d_ok = configured_q && windex == 16'd0; d_data = 1'b1; d_imm = 1'b1; d_len = 8'd1; end
      16'h010B: begin d_ok = configured_q && windex == 16'd0 && wvalue == 16'd0; d_set_if = 1'b1; end
      default: begin
        if (bm == 8'hC0 && breq == 8'(MS_VENDOR_CODE) && windex == 16'(MS_OS_20_INDEX)) begin  // MS OS 2.0 set
          d_ok = 1'b1; d_data = 1'b1; d_base = 9'(DESC_MSOS_OFF); d_len = 8'(DESC_MSOS_LEN);
        end
      end
    endcase
    if (nbytes_q != 4'd8) d_ok = 1'b0;
  end

  // ---------------------------------------------------------------- state
  logic [7:0] total;
  assign total = (wlength < {8'd0, d_len}) ? wlength[7:0] : d_len;

  always_ff @(posedge clk_i) begin
    toggle_rst_o <= '0;
    if (rst_i || bus_reset_i) begin
      state_q      <= E_IDLE;
      toggle_q     <= 1'b0;
      configured_q <= 1'b0;
      halt_q       <= '0;
      addr_q       <= '0;
      new_addr_q   <= '0;
      set_addr_q   <= 1'b0;
      short_q      <= 1'b0;
      use_imm_q    <= 1'b0;
      base_q       <= '0;
      remain_q     <= '0;
      pos_q        <= '0;
      cur_len_q    <= '0;
      imm_q        <= '0;
      toggle_rst_o <= 2'b11;
    end else if (setup_i) begin
      toggle_q   <= 1'b1;
      set_addr_q <= 1'b0;
      pos_q      <= '0;
      base_q     <= d_base;
      use_imm_q  <= d_imm;
      imm_q      <= d_imm_val;
      remain_q   <= total;
      short_q    <= ({8'd0, d_len} < wlength);
      if (!d_ok) begin
        state_q <= E_STALL;
      end else if (d_data) begin
        state_q <= E_DIN;
      end else begin
        state_q <= E_SIN;
        if (d_set_addr) begin
          set_addr_q <= 1'b1;
          new_addr_q <= wvalue[6:0];
        end
        if (d_set_cfg) begin
          configured_q <= wvalue[0];
          halt_q       <= '0;
          toggle_rst_o <= 2'b11;
        end
        if (d_set_if) toggle_rst_o <= 2'b11;
        if (d_clr_halt) begin
          if (d_ep_out) begin halt_q[0] <= 1'b0; toggle_rst_o[0] <= 1'b1; end
          if (d_ep_in)  begin halt_q[1] <= 1'b0; toggle_rst_o[1] <= 1'b1; end
        end
        if (d_set_halt) begin
          if (d_ep_out) halt_q[0] <= 1'b1;
          if (d_ep_in)  halt_q[1] <= 1'b1;
        end
      end
    end else begin
      if (in_start_i) cur_len_q <= in_len_o;
      if (in_ack_i) begin
        case (state_q)
          E_DIN: begin
            toggle_q <= ~toggle_q;
            pos_q    <= pos_q + {1'b0, cur_len_q};
            remain_q <= remain_q - {1'b0, cur_len_q};
            if (cur_len_q != 7'd64 || (remain_q == 8'd64 && !short_q)) state_q <= E_SOUT;
          end
          E_SIN: begin
            state_q <= E_IDLE;
            if (set_addr_q) addr_q <= new_addr_q;
            set_addr_q <= 1'b0;
          end
          default: ;
        endcase
      end
      if (out_ack_i) state_q <= E_IDLE;
    end
  end

  assign in_stall_o  = !(state_q == E_DIN || state_q == E_SIN);
  assign in_len_o    = (state_q == E_SIN) ? 7'd0 : (remain_q > 8'd64) ? 7'd64 : remain_q[6:0];
  assign in_pid1_o   = toggle_q;
  assign out_stall_o = !(state_q == E_DIN || state_q == E_SOUT);

  // ---------------------------------------------------------------- data source
  always_ff @(posedge clk_i) begin
    if (rst_i) begin
      rd_idx_q   <= '0;
      rom_addr_q <= '0;
      imm_byte_q <= '0;
    end else if (in_start_i) begin
      rd_idx_q <= pos_q;
    end else if (rd_i) begin
      rd_idx_q   <= rd_idx_q + 8'd1;
      rom_addr_q <= base_q + {1'b0, rd_idx_q};
      imm_byte_q <= rd_idx_q[0] ? imm_q[15:8] : imm_q[7:0];
    end
  end

  ms_usb_desc_rom #(.SERIAL(SERIAL)) u_rom (
    .clk_i (clk_i),
    .addr_i(rom_addr_q),
    .data_o(rom_data)
  );

  assign data_o       = use_imm_q ? imm_byte_q : rom_data;
  assign addr_o       = addr_q;
  assign configured_o = configured_q;
  assign halt_o       = halt_q;
endmodule
