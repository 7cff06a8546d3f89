"""The soft-core SoC (PicoRV32 RV32IM) runs firmware built by make; watchdog recovery."""

import subprocess

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_soc_firmware_selftest():
    hexfile = ROOT / "build/fw/soc_selftest.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    run_cocotb("ms_soc_tb", "tb_ms_soc", sources=None, extra_sources=[ROOT / "tests/rtl/ms_soc_tb.sv"],
               parameters={"INIT_FILE": f'"{hexfile}"'}, icarus_ok=False)
