"""Receive-channel synchroniser and glitch filter; runs on Verilator and Icarus (SIM=icarus)."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_rx_conditioner():
    run_cocotb("ms_rx_conditioner", "tb_ms_rx_conditioner", sources=[ROOT / "rtl/rx/ms_rx_conditioner.sv"])
