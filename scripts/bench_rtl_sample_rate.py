"""Per-sensor sample rate measured in RTL simulation (ms_sched_uc, Verilator) next to the
golden model, on a static reflector in front of one collocated sender/receiver.

    .venv/bin/python scripts/bench_rtl_sample_rate.py [--cases 2:1,2:3,4:1,4:4] [--plot out.png]

Each case is distance_m:order. Prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "rtl"))
os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="2:1,2:3,4:1,4:4", help="distance_m:order, comma separated")
    ap.add_argument("--plot", help="write a bar chart PNG")
    args = ap.parse_args()
    from cocotb_run import run_cocotb
    from test_ms_scheduler import PARAMETERS, SOURCES

    out = ROOT / "build" / "bench" / "rtl_sample_rate.json"
    # the scheduler test's sources and parameters, so the build is shared
    run_cocotb("ms_scheduler_tb", "tb_bench_rate", sources=SOURCES, parameters=PARAMETERS, icarus_ok=False,
               extra_env={"RATE_CASES": args.cases, "RATE_OUT": str(out)})
    rows = json.loads(out.read_text())
    print("| distance (m) | order asked | order used | RTL (Hz) | golden model (Hz) | identical pulse ticks |")
    print("|---:|---:|---|---:|---:|---|")
    for r in rows:
        print(f"| {r['distance_m']:.1f} | {r['order']} | {r['order_used']} | {r['rtl_hz']:.1f} | {r['model_hz']:.1f} | {r['identical_pulses']} |")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.5))
        labels = [f"{r['distance_m']:.0f} m, N={r['order']}" for r in rows]
        x = range(len(rows))
        ax.bar([i - 0.2 for i in x], [r["rtl_hz"] for r in rows], 0.4, label="RTL")
        ax.bar([i + 0.2 for i in x], [r["model_hz"] for r in rows], 0.4, label="golden model")
        ax.set_xticks(list(x), labels)
        ax.set_ylabel("samples/s per sensor")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)


if __name__ == "__main__":
    main()
