# Board files of the iCE40-HX8K top, read after rtl/sources.f by make synth TARGET=ice40 (mk/synth.mk).
# Vendor primitives (SB_PLL40_PAD) come from Yosys' iCE40 cell library; not linted by make lint.
rtl/board/ms_reset_sync.sv
rtl/board/ms_pll_ice40.sv
rtl/board/ms_ice40hx8k.sv
