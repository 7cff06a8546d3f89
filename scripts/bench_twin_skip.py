#!/usr/bin/env python3
"""The twin's exact skip of calm clocks (issue #30): speed with and without it, and proof that
it changes nothing.

The same single-threaded session (multisonar.twin.check.fixed_session: the noisy corridor, START
the compiled-in demo table, read bulk IN every 0.5 ms of device time) runs twice, skip off and
on, from the same seed. Reported per run: wall seconds of the session, clocks per wall second,
sonar seconds per wall second, skips and the share of clocks skipped; and whether the two runs
agree byte for byte (bulk IN, mailbox words, pulses, the model's whole state at the end).
Wall time on a shared 2-core machine varies by +-25 % from run to run: compare the two rows of
one invocation, and the skipped share, which is deterministic.

    python scripts/bench_twin_skip.py [--seconds 0.2] [--seed 5] [--json F] [--plot F]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))

from multisonar.constants import TICK_HZ  # noqa: E402
from multisonar.twin.check import booted_corridor, fixed_session  # noqa: E402
from multisonar.twin.sim import state_differences  # noqa: E402


def session(seconds: float, seed: int, skip: bool) -> tuple[dict, object]:
    sim = booted_corridor(seed)
    try:
        t0_tick = sim.tick
        t = time.perf_counter()
        r = fixed_session(sim, seconds, skip=skip)
        wall = time.perf_counter() - t
    finally:
        sim.close()
    clocks = r.tick - t0_tick
    skips, skipped = r.skip_stats
    row = {"skip": skip, "sonar_s": round(clocks / TICK_HZ, 4), "wall_s": round(wall, 2),
           "clocks_per_wall_s": round(clocks / wall), "sonar_s_per_wall_s": round(clocks / TICK_HZ / wall, 4),
           "skips": skips, "skipped_share": round(skipped / clocks, 4), "pulses": len(r.fires),
           "bulk_in_bytes": len(r.bulk_in), "mailbox_words": len(r.mailbox)}
    return row, r


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=0.2, help="sonar seconds per run (default %(default)s)")
    ap.add_argument("--seed", type=int, default=5, help="the scene's noise seed (default %(default)s)")
    ap.add_argument("--json", type=Path, help="write the figures as JSON")
    ap.add_argument("--plot", type=Path, help="write a bar chart (PNG)")
    args = ap.parse_args()

    rows, runs = [], []
    for skip in (False, True):
        row, r = session(args.seconds, args.seed, skip)
        rows.append(row)
        runs.append(r)
    a, b = runs
    same = {"bulk_in": a.bulk_in == b.bulk_in, "mailbox": a.mailbox == b.mailbox,
            "pulses": [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in a.fires]
            == [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in b.fires],
            "end_tick": a.tick == b.tick,
            "state": state_differences(a.state, b.state, a.boot_state, b.boot_state) == []}
    speedup = rows[1]["sonar_s_per_wall_s"] / rows[0]["sonar_s_per_wall_s"]

    print(f"# Exact skip of calm clocks: corridor (noisy, seed {args.seed}), the demo's table, "
          f"{args.seconds} sonar-s per run\n")
    print("| skip | wall s | clocks / wall s | sonar-s / wall-s | skips | clocks skipped |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| {'on' if r['skip'] else 'off'} | {r['wall_s']} | {r['clocks_per_wall_s']:,} | "
              f"{r['sonar_s_per_wall_s']:.4f} | {r['skips']:,} | {100 * r['skipped_share']:.1f}% |")
    print(f"\nspeed-up {speedup:.2f}x; the runs agree: " + ", ".join(f"{k} {'yes' if v else 'NO'}" for k, v in same.items()))
    out = {"seconds": args.seconds, "seed": args.seed, "runs": rows, "speedup": round(speedup, 3),
           "identical": same, "exact": all(same.values())}
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=1))
        print(f"\nwrote {args.json}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.bar(["skip off", "skip on"], [r["sonar_s_per_wall_s"] for r in rows], color=["0.6", "C0"])
        ax.set_ylabel("sonar-s per wall-s")
        ax.set_title(f"twin, exact skip of calm clocks ({speedup:.2f}x)")
        fig.tight_layout()
        args.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.plot, dpi=120)
        print(f"wrote {args.plot}")
    return 0 if out["exact"] else 1


if __name__ == "__main__":
    sys.exit(main())
