#!/usr/bin/env python3
"""Command fuzzing on the RTL at scale (issue #9): N random and mutated command packets through
the device's command path (tests/rtl/cmd_fuzz_tb.sv: ms_system = SoC running
firmware/app/sonar + sonar core + host link; the cocotb test ``cmd_fuzz`` of
tests/rtl/tb_cmd_fuzz.py, which checks every reply against the protocol model, the table and
the streaming afterwards, and fails on any mismatch or hang). Prints the figures: packets, per
status code, per packet kind, replies, hangs, latency, wall time, packets/s. With --watchdog
the firmware-hang test runs too and its figures are printed.

    .venv/bin/python scripts/bench_cmd_fuzz.py [--packets 100000] [--seed 9] [--watchdog] [--plot FILE.png]

Wall time: ~45 packets/s on the 2-core reference machine under load (10^5 packets ~ 40 min).
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
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT / "tests" / "rtl"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--packets", type=int, default=100_000, help="command packets to fuzz (>= 10^5 for the issue)")
    ap.add_argument("--seed", type=int, default=9)
    ap.add_argument("--watchdog", action="store_true", help="also run the firmware-hang / watchdog test")
    ap.add_argument("--plot", type=Path, help="write a PNG of the replies per status code")
    a = ap.parse_args(argv)
    from cocotb_run import run_cocotb

    hexfile = ROOT / "build/fw/sonar_app.hex"
    subprocess.run(["make", "-s", str(hexfile.relative_to(ROOT))], cwd=ROOT, check=True)
    out_dir = ROOT / "build" / "sim" / "cmd_fuzz_out"
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as td:
        js = Path(td) / "fuzz.json"
        env = {"CMD_FUZZ_N": str(a.packets), "CMD_FUZZ_SEED": str(a.seed), "CMD_FUZZ_JSON": str(js),
               "CMD_FUZZ_DIR": str(out_dir)}
        if not a.watchdog:
            env["COCOTB_TEST_FILTER"] = r"\.cmd_fuzz$"
        run_cocotb("cmd_fuzz_tb", "tb_cmd_fuzz",
                   parameters={"INIT_FILE": f'"{hexfile}"', "CAP_FILE": f'"{out_dir / "cap.txt"}"',
                               "CMD_FILE": f'"{out_dir / "cmd.txt"}"'},
                   extra_sources=[ROOT / "tests/rtl/cmd_fuzz_tb.sv"], icarus_ok=False, extra_env=env)
        r = json.loads(js.read_text())
        wdt = json.loads(js.with_suffix(".wdt.json").read_text()) if a.watchdog else None

    print("| figure | value |")
    print("|---|---:|")
    print(f"| packets (seed {r['seed']}) | {r['packets']} |")
    print(f"| replies (exactly one each, in order, checked) | {r['replies']} |")
    print(f"| hangs (no reply within 2 M clocks) | {r['hangs']} |")
    print(f"| bytes sent | {r['bytes']} |")
    print(f"| frames received meanwhile (CRC checked) | {r['frames_during_fuzz']} |")
    print(f"| reply latency, mean / max (clocks) | {r['mean_latency_clk']:.0f} / {r['max_latency_clk']} |")
    print(f"| stale READ_REGS values (firmware cache bug) | {r['stale_reads']} |")
    print(f"| table registers changed by accepted WRITE_REGS (hardware = model) | {r['table_regs_changed']} |")
    print(f"| frames after the fuzzing (START, consecutive seq) | {r['frames_after']} |")
    print(f"| device time (fuzzing) | {r['sim_s'] * 1e3:.1f} ms |")
    print(f"| wall time (test / fuzzing) | {r['wall_s']:.1f} s / {r['fuzz_wall_s']:.1f} s |")
    print(f"| packets/s (wall) | {r['packets_per_s']:.1f} |")
    print()
    print("| status | replies |")
    print("|---|---:|")
    for k, v in sorted(r["statuses"].items(), key=lambda kv: -kv[1]):
        print(f"| {k} | {v} |")
    print()
    print("| packet kind | sent |")
    print("|---|---:|")
    for k, v in sorted(r["kinds"].items()):
        if v:
            print(f"| {k} | {v} |")
    if wdt:
        print()
        print("| watchdog figure | value |")
        print("|---|---:|")
        for k, v in wdt.items():
            print(f"| {k} | {v} |")
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        items = sorted(r["statuses"].items(), key=lambda kv: -kv[1])
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.bar([k for k, _ in items], [v for _, v in items])
        ax.set_ylabel("replies")
        ax.set_title(f"RTL command fuzzing: {r['packets']} packets, {r['hangs']} hangs")
        ax.tick_params(axis="x", rotation=45)
        fig.tight_layout()
        a.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(a.plot, dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main())
