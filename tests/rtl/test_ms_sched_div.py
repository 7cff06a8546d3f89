"""The scheduler engine's divider unit (ms_sched_div) against its model (sched_program.DivUnit)."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_sched_div():
    run_cocotb("ms_sched_div", "tb_ms_sched_div", sources=[ROOT / "rtl/core/ms_sched_div.sv"])
