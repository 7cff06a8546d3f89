"""ms_system (SoC + sonar core) runs firmware that reaches the sonar registers."""

import subprocess

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_ms_system_smoke():
    hexfile = ROOT / "build/fw/system_smoke.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    run_cocotb("ms_system", "tb_ms_system",
               parameters={"INIT_FILE": f'"{hexfile}"', "STRETCH_W": 4}, icarus_ok=False)
