# Board files of the ULX3S (ECP5) top, read after rtl/sources.f by make synth (mk/synth.mk).
# Vendor primitives (EHXPLLL) come from Yosys' ECP5 cell library; not linted by make lint.
rtl/board/TRELLIS_IO.sv
rtl/board/ms_reset_sync.sv
rtl/board/ms_pll_ecp5.sv
rtl/board/ms_ulx3s.sv
