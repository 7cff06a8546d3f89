"""The fast-firing scheduler, ms_sched_uc (the main program of multisonar.tools.sched_program on
ms_sched_engine with its units; 8 virtual sensors, 16 window slots per element), closed-loop
against the golden model at the device's decision lead (tests/rtl/tb_ms_scheduler.py); tables through
the load port, as the firmware writes them."""

import pytest

from cocotb_run import GEN, ROOT, run_cocotb
from multisonar.constants import DEVICE_DECISION_LEAD

SOURCES = [GEN / "rtl/ms_ucode_pkg.sv", GEN / "rtl/ms_sched_io_pkg.sv",
           ROOT / "rtl/rx/ms_rx_conditioner.sv", ROOT / "rtl/core/ms_sched_workq.sv",
           ROOT / "rtl/core/ms_sched_engine.sv",
           ROOT / "rtl/core/ms_sched_div.sv", ROOT / "rtl/core/ms_sched_slot.sv",
           ROOT / "rtl/core/ms_sched_closes.sv",
           ROOT / "rtl/core/ms_sched_uc.sv", ROOT / "tests/rtl/ms_scheduler_tb.sv"]
# the product's scheduler (UCODE_FILE: the package's UCODE_HEX, the gen step's image); the
# benches (scripts/bench_*, experiments --rtl) build the same, so one Verilator build serves them all
PARAMETERS = {"NUM_CH": 24, "LEAD": DEVICE_DECISION_LEAD}


@pytest.mark.sim
def test_ms_scheduler():
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, parameters=PARAMETERS, icarus_ok=False)


@pytest.mark.sim
def test_ms_scheduler_overrun():
    """At LEAD 4096 three decisions in the start tick take the engine past P / 2: overrun_o."""
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, variant="lead4096",
               parameters={**PARAMETERS, "LEAD": 4096}, icarus_ok=False, extra_env={"SCHED_LEAD": "4096"},
               testcase=["overrun_reported"])
