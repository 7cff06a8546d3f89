"""The whole system on a scene: ms_system (SoC + sonar core) runs the sonar firmware
(firmware/app/sonar) against echoes from a wall and a point reflector; its frames,
read off the host FIFO, are checked against the golden models (multisonar.fastfiring for the
ToF records, multisonar.geometry for the geometry records). Details: tb_system_scene.py."""

import subprocess

import pytest

from cocotb_run import ROOT, run_cocotb


@pytest.mark.sim
def test_system_scene():
    hexfile = ROOT / "build/fw/sonar_app.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    run_cocotb("system_scene_tb", "tb_system_scene", parameters={"INIT_FILE": f'"{hexfile}"'},
               extra_sources=[ROOT / "tests/rtl/system_scene_tb.sv"], icarus_ok=False)
