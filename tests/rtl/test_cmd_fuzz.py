"""Command fuzzing of the device and the firmware watchdog, on the RTL (ms_system running
firmware/app/sonar; top tests/rtl/cmd_fuzz_tb.sv). Details: tb_cmd_fuzz.py.

CMD_FUZZ_N sets the number of fuzzed command packets (default 10000, the CI size issue #9 asks for;
~3 min on 2 cores);
scripts/bench_cmd_fuzz.py runs >= 10^5 and prints the figures."""

import os
import subprocess

import pytest

from cocotb_run import ROOT, run_cocotb


def run(extra_env: dict[str, str] | None = None) -> None:
    hexfile = ROOT / "build/fw/sonar_app.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    env = {"CMD_FUZZ_N": os.environ.get("CMD_FUZZ_N", "10000")}
    env.update(extra_env or {})
    out = ROOT / "build" / "sim" / "cmd_fuzz_out"
    out.mkdir(parents=True, exist_ok=True)
    env["CMD_FUZZ_DIR"] = str(out)
    run_cocotb("cmd_fuzz_tb", "tb_cmd_fuzz",
               parameters={"INIT_FILE": f'"{hexfile}"', "CAP_FILE": f'"{out / "cap.txt"}"',
                           "CMD_FILE": f'"{out / "cmd.txt"}"'},
               extra_sources=[ROOT / "tests/rtl/cmd_fuzz_tb.sv"], icarus_ok=False, extra_env=env)


@pytest.mark.sim
def test_cmd_fuzz():
    run()
