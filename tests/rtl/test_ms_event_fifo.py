"""Event FIFO: ordering, level, overflow counting and flagging; Verilator and Icarus."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_event_fifo():
    run_cocotb("ms_event_fifo", "tb_ms_event_fifo",
               sources=[ROOT / "rtl/common/ms_ram_dp.sv", ROOT / "rtl/event/ms_event_fifo.sv"])
