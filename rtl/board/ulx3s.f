# Board files of the ULX3S (ECP5) top, read after rtl/sources.f by make synth (mk/synth.mk).
# Vendor primitives (EHXPLLL) come from Yosys' ECP5 cell library; make lint reads these files
# with that library in its strict front end (scripts/lint_slang.py), not in Verilator.
rtl/board/TRELLIS_IO.sv
rtl/board/ms_reset_sync.sv
rtl/board/ms_pll_ecp5.sv
rtl/board/ms_ulx3s.sv
