"""The scheduler's close detector (ms_sched_closes) against its contract."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_sched_closes():
    run_cocotb("ms_sched_closes", "tb_ms_sched_closes", sources=[ROOT / "rtl/core/ms_sched_closes.sv"])
