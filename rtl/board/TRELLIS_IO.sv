// TRELLIS_IO: black-box declaration of the ECP5 I/O cell that nextpnr-ecp5 places on a pad
// (DIR "INPUT" / "OUTPUT" / "BIDIR"; T high = output off). Yosys' ECP5 library declares it
// only as a simulation model (common_sim.vh) and the friendlier BB only as a techmap rule,
// so neither can be read as a black box by the slang frontend; this file, read by
// rtl/board/ulx3s.f only, makes the board top elaborate and leaves the cell to nextpnr.
(* blackbox *)
module TRELLIS_IO #(
  parameter DIR = "INPUT"
) (
  inout  B,
  input  I,
  input  T,
  output O
);
endmodule
