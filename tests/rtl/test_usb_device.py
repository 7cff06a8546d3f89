"""USB 2.0 full-speed device core (rtl/usb/): bit-level tests through a wire-level host model."""

import pytest

from cocotb_run import GEN, ROOT, run_cocotb

USB_RTL = [GEN / "rtl/ms_usb_desc_pkg.sv"] + [ROOT / "rtl/usb" / f for f in (
    "ms_usb_pkg.sv", "ms_usb_rx.sv", "ms_usb_tx.sv", "ms_usb_tx_tl.sv", "ms_usb_pkt_rx.sv", "ms_usb_desc_rom.sv",
    "ms_usb_ep0.sv", "ms_usb_ep_out.sv", "ms_usb_ep_in.sv", "ms_usb_xact.sv", "ms_usb_device.sv")]
TB = [ROOT / "tests/rtl/usb_host_phy_tb.sv", ROOT / "tests/rtl/usb_tl_host_tb.sv", ROOT / "tests/rtl/usb_device_tb.sv"]


@pytest.mark.sim
def test_usb_device():
    run_cocotb("usb_device_tb", "tb_usb_device", sources=USB_RTL + TB)


@pytest.mark.sim
def test_usb_device_board_serial():
    """A board's SERIAL parameter replaces the serial string of the generated ROM image; every
    other byte stays the image's (test_enumeration compares the whole set)."""
    serial = 0x1A2B3C4D
    run_cocotb("usb_device_tb", "tb_usb_device", sources=USB_RTL + TB, parameters={"SERIAL": serial},
               variant="serial", testcase=["test_enumeration"], extra_env={"MS_USB_SERIAL": str(serial)})
