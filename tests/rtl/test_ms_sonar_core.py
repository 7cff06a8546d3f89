"""The whole sonar core (registers, receivers, scheduler, transmitters, event FIFO) against
the golden model, configured and read through its register bus."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_sonar_core():
    # a 32-word event FIFO so that the FIFO-full test fills it in a few pulses; the other
    # tests drain it every few milliseconds, as the firmware does
    run_cocotb("ms_sonar_core_tb", "tb_ms_sonar_core", icarus_ok=False, parameters={"EVT_DEPTH_W": 5},
               extra_sources=[ROOT / "tests/rtl/ms_sonar_core_tb.sv"])
