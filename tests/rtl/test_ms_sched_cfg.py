"""The scheduler's configuration check and load (ms_sched_cfg) against the simulated device's
decoder of the same registers: 200 random tables, every refusal code, every record, blank
interval and share bit."""

import pytest

from cocotb_run import ROOT, run_cocotb
from multisonar.constants import DEVICE_DECISION_LEAD

SOURCES = [ROOT / "rtl/core/ms_sched_cfg.sv", ROOT / "tests/rtl/ms_sched_cfg_tb.sv"]


@pytest.mark.sim
def test_ms_sched_cfg():
    run_cocotb("ms_sched_cfg_tb", "tb_ms_sched_cfg", sources=SOURCES,
               parameters={"NUM_VS": 8, "LEAD": DEVICE_DECISION_LEAD}, icarus_ok=False)

