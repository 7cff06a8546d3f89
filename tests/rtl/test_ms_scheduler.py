"""Fast-firing scheduler, several virtual sensors, scoreboarded against the golden model."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_scheduler():
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler",
               sources=[ROOT / "rtl/common/ms_ram_dp.sv", ROOT / "rtl/rx/ms_rx_conditioner.sv",
                        ROOT / "rtl/core/ms_sched_workq.sv", ROOT / "rtl/core/ms_scheduler.sv",
                        ROOT / "tests/rtl/ms_scheduler_tb.sv"],
               parameters={"NUM_CH": 24, "LEAD": 4096}, icarus_ok=False)
