"""The whole device behind USB: the unchanged host driver against the RTL (SoC + firmware +
sonar core + host link + USB device core), a bus reset in the middle of the frame stream
(clean error, re-open, restart), and one wire-level end-to-end run. Details: tb_usb_link.py."""

import subprocess

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_usb_link():
    hexfile = ROOT / "build/fw/sonar_app.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    run_cocotb("usb_link_tb", "tb_usb_link", parameters={"INIT_FILE": f'"{hexfile}"'},
               extra_sources=[ROOT / "tests/rtl/usb_host_phy_tb.sv", ROOT / "tests/rtl/usb_tl_host_tb.sv",
                              ROOT / "tests/rtl/usb_link_tb.sv"], icarus_ok=False)
