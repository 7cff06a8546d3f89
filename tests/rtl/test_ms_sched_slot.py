"""The scheduler engine's slot unit (ms_sched_slot) against its model (sched_program.SlotUnit)."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_sched_slot():
    run_cocotb("ms_sched_slot_tb", "tb_ms_sched_slot",
               sources=[ROOT / "rtl/core/ms_sched_slot.sv", ROOT / "tests/rtl/ms_sched_slot_tb.sv"])
