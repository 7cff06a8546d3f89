"""Fast-firing scheduler, several virtual sensors, scoreboarded against the golden model: the
full scheduler (8 sensors, 16 window slots per element) and the LFE5U-25F's reduced one (4
sensors, 8 slots; mk/synth.mk) on the tests of up to four sensors."""

import pytest

from cocotb_run import ROOT, run_cocotb
from multisonar.constants import DEVICE_DECISION_LEAD

SOURCES = [ROOT / "rtl/common/ms_ram_dp.sv", ROOT / "rtl/rx/ms_rx_conditioner.sv", ROOT / "rtl/core/ms_sched_workq.sv",
           ROOT / "rtl/core/ms_sched_cfg.sv", ROOT / "rtl/core/ms_scheduler.sv", ROOT / "tests/rtl/ms_scheduler_tb.sv"]
# the full scheduler; the benches (scripts/bench_*, experiments --rtl) build the same, so one
# Verilator build serves them all
PARAMETERS = {"NUM_CH": 24, "LEAD": DEVICE_DECISION_LEAD}


@pytest.mark.sim
def test_ms_scheduler():
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, parameters=PARAMETERS, icarus_ok=False)


@pytest.mark.sim
def test_ms_scheduler_reduced():
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, variant="vs4-ws8",
               parameters={**PARAMETERS, "SCHED_VS": 4, "WSLOTS": 8}, icarus_ok=False,
               extra_env={"SCHED_VS": "4", "SCHED_WSLOTS": "8"},
               testcase=["step_occlusion_kmiss", "four_sensors_shared_elements", "window_slots_full",
                         "corridor_scene_three_sensors", "apply_refusals_leave_the_schedule_running"])


@pytest.mark.sim
def test_ms_scheduler_overrun():
    """A build whose lead (512 ticks) the engine cannot keep: the overrun must be reported."""
    run_cocotb("ms_scheduler_tb", "tb_ms_scheduler", sources=SOURCES, variant="lead512",
               parameters={**PARAMETERS, "LEAD": 512}, icarus_ok=False, extra_env={"SCHED_LEAD": "512"},
               testcase=["overrun_reported"])
