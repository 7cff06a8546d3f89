"""The firmware geometry library's host builds (``make -C firmware host-libs``:
build/fw/host/libmsgeom_{f64,f32,q}.so, the same C as on the soft-core) for the arithmetic
variants of the trade-off report, and the measured soft-core cost of a fix per variant.

The ctypes interface is the double-precision batch shim (firmware/geometry/ms_geom_host.c),
as in tests/test_fw_geometry.py. The Q variant's interface takes micrometres: inputs are
rounded to 1 um before the call, as the firmware receives them.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
LIBDIR = ROOT / "build" / "fw" / "host"
VARIANTS = ("f64", "f32", "q")
_P = ctypes.POINTER(ctypes.c_double)

#: Cycles of one fix (point fit + wall fit + edge/wall decision, 3 receivers) on the PicoRV32
#: SoC at 48 MHz, median over the typical cases, measured in RTL simulation by
#: scripts/bench_fw_cycles.py (table in firmware/README.md, "Cycles on the soft-core").
FIX_CYCLES = {"f64": 2_467_777, "f32": 1_672_217, "q": 23_444}
SOC_HZ = 48_000_000


def ensure_built() -> bool:
    """Build the host libraries if missing (needs gcc and make); False if they cannot be had."""
    if all((LIBDIR / f"libmsgeom_{v}.so").exists() for v in VARIANTS):
        return True
    if shutil.which("gcc") is None or shutil.which("make") is None or not (ROOT / "firmware").is_dir():
        return False
    r = subprocess.run(["make", "-s", "-C", str(ROOT / "firmware"), "host-libs"], capture_output=True, text=True)
    return r.returncode == 0 and all((LIBDIR / f"libmsgeom_{v}.so").exists() for v in VARIANTS)


class FwWall:
    """Wall solver of one arithmetic variant (``msh_solve_wall_batch``)."""

    def __init__(self, variant: str) -> None:
        if variant not in VARIANTS:
            raise ValueError(f"unknown arithmetic variant {variant!r}; one of {VARIANTS}")
        path = LIBDIR / f"libmsgeom_{variant}.so"
        if not path.exists():
            raise FileNotFoundError(f"{path} is missing: run 'make -C firmware host-libs'")
        self.variant = variant
        self.lib = ctypes.CDLL(str(path))
        fn = self.lib.msh_solve_wall_batch
        fn.argtypes = [ctypes.c_int, ctypes.c_int, _P, _P, _P, _P, ctypes.c_double, ctypes.c_double, ctypes.c_double, _P]
        fn.restype = None

    def solve(self, C: np.ndarray, R: np.ndarray, S: np.ndarray, axis: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(valid, distance from the source, normal angle) per row; C (M,N,2), R (M,N), S (M,2)."""
        from .. import geometry as g

        if self.variant == "q":
            C, R, S = (np.round(np.asarray(a, np.float64) * 1e6) / 1e6 for a in (C, R, S))
        R = np.ascontiguousarray(R, np.float64)
        M, N = R.shape
        C = np.ascontiguousarray(np.broadcast_to(C, (M, N, 2)), np.float64)
        S = np.ascontiguousarray(np.broadcast_to(S, (M, 2)), np.float64)
        ax = None if axis is None else np.ascontiguousarray(np.broadcast_to(axis, (M,)), np.float64)
        out = np.zeros((M, 8))
        self.lib.msh_solve_wall_batch(M, N, C.ctypes.data_as(_P), R.ctypes.data_as(_P), S.ctypes.data_as(_P),
                                      None if ax is None else ax.ctypes.data_as(_P), float("inf"), float("inf"),
                                      g.DEFAULT_FOV, out.ctypes.data_as(_P))
        return out[:, 0] > 0, out[:, 2], out[:, 3]
