"""USB PHY blocks (ms_usb_tx, ms_usb_rx, ms_usb_pkt_rx) in a loop: CRC16, NRZI, bit stuffing."""

import pytest

from cocotb_run import ROOT, run_cocotb

SOURCES = [ROOT / "rtl/usb" / f for f in ("ms_usb_pkg.sv", "ms_usb_rx.sv", "ms_usb_tx.sv", "ms_usb_pkt_rx.sv")]


@pytest.mark.sim
def test_usb_phy_loop():
    run_cocotb("usb_phy_loop_tb", "tb_usb_phy", sources=SOURCES + [ROOT / "tests/rtl/usb_phy_loop_tb.sv"])
