"""Transmit phaser (per-element delay + burst generator); runs on Verilator and Icarus (SIM=icarus)."""

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_tx_phaser():
    run_cocotb("ms_tx_phaser", "tb_ms_tx_phaser",
               sources=[ROOT / "rtl/tx/ms_tx_channel.sv", ROOT / "rtl/tx/ms_tx_phaser.sv"],
               parameters={"NUM_CH": 24})
