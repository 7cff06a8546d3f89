"""The scheduler's work queue (ms_sched_workq) alone: ordering, full, overflow and reset
against a model of its contract, at the scheduler's size (80-bit words, 32 deep) and small."""

import pytest

from cocotb_run import ROOT, run_cocotb

SOURCES = [ROOT / "rtl/core/ms_sched_workq.sv"]


@pytest.mark.sim
@pytest.mark.parametrize("width,depth", [(80, 32), (8, 4)], ids=["scheduler", "small"])
def test_ms_sched_workq(width, depth):
    run_cocotb("ms_sched_workq", "tb_ms_sched_workq", sources=SOURCES, variant=f"w{width}-d{depth}",
               parameters={"WIDTH": width, "DEPTH": depth}, extra_env={"WQ_DEPTH": str(depth)})
