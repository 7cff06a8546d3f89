// ms_pll_ice40: 12 MHz board clock -> 48 MHz system clock (iCE40 SB_PLL40_CORE).
//
// Parameters from `yowasp-icepll -i 12 -o 48`: DIVR 0, DIVF 63, DIVQ 4 -> VCO 768 MHz,
// 768 / 16 = 48.000 MHz exactly (the USB full-speed clock). The clock pin is a
// global input; J3 on the HX8K ct256 is not a PLL pad, so SB_PLL40_CORE takes it from the
// fabric. locked_o goes high when the PLL has locked.
module ms_pll_ice40 (
  input  logic clk12_i,
  output logic clk48_o,
  output logic locked_o
);
  SB_PLL40_CORE #(
    .FEEDBACK_PATH ("SIMPLE"),
    .DIVR          (4'b0000),
    .DIVF          (7'b0111111),
    .DIVQ          (3'b100),
    .FILTER_RANGE  (3'b001)
  ) u_pll (
    .REFERENCECLK  (clk12_i),
    .PLLOUTCORE    (),
    .PLLOUTGLOBAL  (clk48_o),
    .EXTFEEDBACK   (1'b0),
    .DYNAMICDELAY  (8'd0),
    .LOCK          (locked_o),
    .BYPASS        (1'b0),
    .RESETB        (1'b1),
    .LATCHINPUTVALUE (1'b0),
    .SDO           (),
    .SDI           (1'b0),
    .SCLK          (1'b0)
  );
endmodule
