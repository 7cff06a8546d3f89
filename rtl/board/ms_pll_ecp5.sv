// ms_pll_ecp5: 25 MHz board clock -> exactly 48 MHz system clock (ECP5 EHXPLLL).
//
// Parameters from `yowasp-ecppll -i 25 -o 48 --highres`: PFD 25/5 = 5 MHz, CLKOP (feedback)
// 5 x 2 = 10 MHz, VCO 10 x 48 = 480 MHz, CLKOS 480/10 = 48.000 MHz (the USB full-speed
// clock must be exact: 4 x 12 Mbit/s). locked_o goes high when the PLL has locked.
module ms_pll_ecp5 (
  input  logic clk25_i,
  output logic clk48_o,
  output logic locked_o
);
  logic clkfb;
  (* FREQUENCY_PIN_CLKI="25" *)
  (* FREQUENCY_PIN_CLKOP="10" *)
  (* FREQUENCY_PIN_CLKOS="48" *)
  (* ICP_CURRENT="12" *) (* LPF_RESISTOR="8" *) (* MFG_ENABLE_FILTEROPAMP="1" *) (* MFG_GMCREF_SEL="2" *)
  EHXPLLL #(
    .PLLRST_ENA       ("DISABLED"),
    .INTFB_WAKE       ("DISABLED"),
    .STDBY_ENABLE     ("DISABLED"),
    .DPHASE_SOURCE    ("DISABLED"),
    .OUTDIVIDER_MUXA  ("DIVA"),
    .OUTDIVIDER_MUXB  ("DIVB"),
    .OUTDIVIDER_MUXC  ("DIVC"),
    .OUTDIVIDER_MUXD  ("DIVD"),
    .CLKI_DIV         (5),
    .CLKOP_ENABLE     ("ENABLED"),
    .CLKOP_DIV        (48),
    .CLKOP_CPHASE     (9),
    .CLKOP_FPHASE     (0),
    .CLKOS_ENABLE     ("ENABLED"),
    .CLKOS_DIV        (10),
    .CLKOS_CPHASE     (0),
    .CLKOS_FPHASE     (0),
    .FEEDBK_PATH      ("CLKOP"),
    .CLKFB_DIV        (2)
  ) u_pll (
    .RST          (1'b0),
    .STDBY        (1'b0),
    .CLKI         (clk25_i),
    .CLKOP        (clkfb),
    .CLKOS        (clk48_o),
    .CLKOS2       (),
    .CLKOS3       (),
    .CLKFB        (clkfb),
    .CLKINTFB     (),
    .PHASESEL0    (1'b0),
    .PHASESEL1    (1'b0),
    .PHASEDIR     (1'b1),
    .PHASESTEP    (1'b1),
    .PHASELOADREG (1'b1),
    .PLLWAKESYNC  (1'b0),
    .ENCLKOP      (1'b0),
    .ENCLKOS      (1'b0),
    .ENCLKOS2     (1'b0),
    .ENCLKOS3     (1'b0),
    .LOCK         (locked_o),
    .INTLOCK      ()
  );
endmodule
