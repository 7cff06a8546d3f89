"""The scheduler's microcoded engine core (ms_sched_engine) against its instruction-set model
(multisonar.tools.sched_ucode.Machine), clock for clock: directed, random and scan programs."""

import pytest

from cocotb_run import GEN, ROOT, run_cocotb

SOURCES = [GEN / "rtl/ms_ucode_pkg.sv", ROOT / "rtl/core/ms_sched_engine.sv",
           ROOT / "tests/rtl/ms_sched_engine_tb.sv"]


@pytest.mark.sim
def test_ms_sched_engine():
    run_cocotb("ms_sched_engine_tb", "tb_ms_sched_engine", sources=SOURCES, icarus_ok=False)
