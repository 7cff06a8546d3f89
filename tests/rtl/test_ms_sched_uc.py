"""The scheduler on the microcoded engine (ms_sched_uc: the main program of
multisonar.tools.sched_program on ms_sched_engine with its units) on ms_scheduler's
scoreboard: the same wrapper and tests (tb_ms_scheduler.py), the golden model at the engine's
decision lead."""

import os

import pytest

from cocotb_run import GEN, ROOT, run_cocotb

LEAD = 32768   # the lead the program needs (scripts/bench_sched_mainloop.py)
SOURCES = [GEN / "rtl/ms_ucode_pkg.sv", GEN / "rtl/ms_sched_io_pkg.sv", ROOT / "rtl/common/ms_ram_dp.sv",
           ROOT / "rtl/rx/ms_rx_conditioner.sv", ROOT / "rtl/core/ms_sched_workq.sv",
           ROOT / "rtl/core/ms_sched_cfg.sv", ROOT / "rtl/core/ms_sched_engine.sv",
           ROOT / "rtl/core/ms_sched_div.sv", ROOT / "rtl/core/ms_sched_slot.sv",
           ROOT / "rtl/core/ms_sched_closes.sv",
           ROOT / "rtl/core/ms_sched_uc.sv", ROOT / "tests/rtl/ms_scheduler_tb.sv"]
PARAMETERS = {"NUM_CH": 24, "LEAD": LEAD}   # UCODE_FILE: the package's UCODE_HEX, the gen step's image
# a subset for CI's time (every test of tb_ms_scheduler passes; SCHED_UC_ALL=1 runs them, ~11 min):
# boundaries and ranges, full window slots, the tick counter's wrap, an apply while running
TESTS = ["static_ranges_phased_order2", "window_slots_full", "init_only_and_wrap",
         "reconfigure_while_pulses_in_flight"]


@pytest.mark.sim
def test_ms_sched_uc():
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, variant="uc", parameters=PARAMETERS,
               defines={"SCHED_UC": 1}, icarus_ok=False, extra_env={"SCHED_LEAD": str(LEAD)},
               testcase=None if os.environ.get("SCHED_UC_ALL") else TESTS)


@pytest.mark.sim
def test_ms_sched_uc_overrun():
    """At LEAD 4096 three decisions in the start tick take the engine past P / 2: overrun_o."""
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, variant="uc-lead4096",
               parameters={**PARAMETERS, "LEAD": 4096}, defines={"SCHED_UC": 1}, icarus_ok=False,
               extra_env={"SCHED_LEAD": "4096", "SCHED_OVERRUN_LEAD": "4096"}, testcase=["overrun_reported"])
