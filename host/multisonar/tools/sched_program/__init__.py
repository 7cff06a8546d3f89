"""Microcode kernels of the scheduler for the engine core (docs/sched_engine.md), split by job:
``layout`` (data memory and I/O map), ``units`` (models of the fixed units the kernels drive),
``decision`` (SCHED, CAND, ORDER, CONF, ISSUE, IEL), ``events`` (EDGE, HIT, CLOSE, HEAD, SAFE)
and ``clocks`` (their clocks on representative loads). Each kernel is checked against the
golden model (multisonar.fastfiring) in tests/test_sched_program.py and timed by
scripts/bench_sched_engine.py: the figures that say which of the scheduler's loops the engine
can run within the decision lead.
"""

from __future__ import annotations

from .layout import (BA, BB, BU, CAND, DIV_LATENCY, DIV_N, DIV_Q, DIV_STAT, DIV_X, EVT_HI, EVT_LO,
                     F_ANY_TRK, F_EPOCH, F_IN_INIT, F_TRACKING, HC, HD_EL, HD_T, HS, MISS_MAX,
                     NUM_RX, R_MASK24, R_SIGN24, R_STRIDE, SENS, SENS_STRIDE, SU_CONF, SU_EDGE,
                     SU_FLAGS, SU_GO, SU_HEAD, SU_LATENCY, SU_MINC, SU_SENSOR, SU_TA, SU_TB, SU_TWA,
                     SU_TWB, SU_VALID, SU_X,
                     S_DUE, S_FLAGS, S_K, S_MODE, S_OPEN, S_QUIET, S_REINIT, S_SEQ, S_SHARE, S_TRK,
                     TRIG_EL, TRIG_T, TRK, TU, WSLOTS, WV, W_ADDR, W_META, W_T0, W_WE,
                     pack_rx, prologue)  # noqa: F401
from .units import (DivUnit, EngineWithUnits, Outputs, Slot, SlotUnit, run_kernel)  # noqa: F401
from .decision import (SCHED_GO, SCHED_HOLD, SCHED_NOT_YET, SCHED_QUIET, cand_kernel, conf_kernel,
                       iel_kernel, issue_kernel, order_kernel, sched_kernel)  # noqa: F401
from .events import (close_kernel, edge_kernel, head_kernel, hit_kernel, safe_kernel)  # noqa: F401
from .clocks import (cand_clocks, close_clocks, conf_clocks, hit_clocks, iel_clocks, order_clocks,
                     scan_clocks)  # noqa: F401
