#!/usr/bin/env python3
"""False fixes under spurious pulses and crosstalk (issue #9), on the golden model.

Each trial (``multisonar.safety.run_false_fix_trial``) is the scene and sensor of the safety
trial of the same seed (the left sensor, tx 6 / rx 5-7, tracking a wall at 1.3-2.5 m; with the
person crossing unless --no-person; order and K random), with the scene's spurious pulse rate
and direct crosstalk level replaced. Every pulse with a first in-window echo on all three
receivers goes through the host geometry; a **fix** is what the firmware reports as one: an
edge (valid point fit) or wall (valid wall fit) record. A **false fix** is a fix whose reported
point (edge position, wall foot), placed in the world with the robot pose at the reflection
instant, lies farther than --tol-mm from every true reflector surface (wall, person) then.
Records the firmware classes "uncertain" still carry the point fit's position (quality 0): they
are counted apart ("uncertain points"), with how many of them are that far off.
A **false sample** is a first in-window echo (init or tracking window) that matches no true
echo path of its own pulse within 12.5 us; "alias" ones are another pulse's echo
(interlacing), the others spurious pulses or crosstalk. First echoes the gated miss rule
rejected (flagged gated, event bit 45) are no geometry input and counted apart ("gated", in
brackets those that are false or alias).

    .venv/bin/python scripts/bench_false_fix.py [--trials 20] [--rates 2,20,100,500] [--crosstalk 0.1,0.3,1.0] [--workers 1] [--plot F.png] [--csv F.csv] [--json F.json]
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict
from functools import partial
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from multisonar.safety import FALSE_FIX_TOL_M, FalseFixResult, run_false_fix_trial, summarise_false_fixes  # noqa: E402


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x.strip()]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=20, help="seeds per condition (default %(default)s)")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--rates", type=_floats, default=[2.0, 20.0, 100.0, 500.0], help="spurious pulses per channel and second")
    ap.add_argument("--crosstalk", type=_floats, default=[0.1, 0.3, 1.0], help="direct crosstalk level (scene model.crosstalk_level)")
    ap.add_argument("--no-person", action="store_true", help="the tracked wall alone (no person crossing)")
    ap.add_argument("--tol-mm", type=float, default=FALSE_FIX_TOL_M * 1e3, help="false-fix distance, mm (default %(default)g)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--plot", type=Path)
    ap.add_argument("--csv", type=Path)
    ap.add_argument("--json", type=Path, help="the table as JSON: one summary per condition")
    a = ap.parse_args()
    seeds = range(a.first_seed, a.first_seed + a.trials)
    conds = [(r, x) for x in a.crosstalk for r in a.rates]
    t = time.time()
    results: dict[tuple[float, float], list[FalseFixResult]] = {}
    ex = ProcessPoolExecutor(max_workers=a.workers) if a.workers > 1 else None
    for ci, (rate, xt) in enumerate(conds, 1):
        fn = partial(run_false_fix_trial, spurious_rate_hz=rate, crosstalk_level=xt, person=not a.no_person,
                     tol_m=a.tol_mm / 1e3)
        rs = results.setdefault((rate, xt), [])
        for i, r in enumerate(ex.map(fn, seeds) if ex else map(fn, seeds), 1):
            rs.append(r)
            print(f"\rcondition {ci}/{len(conds)} (spurious {rate:g}/s, crosstalk {xt:g}): {i}/{len(seeds)} trials, "
                  f"{time.time() - t:.0f} s", end="", file=sys.stderr, flush=True)
    if ex:
        ex.shutdown()
    print(file=sys.stderr)
    print(f"{a.trials} trials per condition (seeds {seeds.start}-{seeds.stop - 1}, {'wall only' if a.no_person else 'wall + person crossing'}, "
          f"1.6 s each), false fix > {a.tol_mm:g} mm from every true surface, {time.time() - t:.0f} s wall\n")
    print("| spurious /s/ch | crosstalk | samples | false samples | false-sample rate | alias samples | gated (false + alias) | fixes | fixes/s | "
          "false fixes (spurious / alias / true echoes) | false-fix rate | false fixes/s | max fix error mm | "
          "uncertain points (false) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for (rate, xt), rs in results.items():
        s = summarise_false_fixes(rs)
        other = s["false_fixes"] - s["false_fixes_spurious"] - s["false_fixes_alias"]
        print(f"| {rate:g} | {xt:g} | {s['samples']} | {s['false_samples']} | {s['false_sample_rate']:.2%} | {s['alias_samples']} | "
              f"{s['gated']} ({s['gated_false'] + s['gated_alias']}) | {s['fixes']} | {s['fixes_per_s']:.1f} | {s['false_fixes']} ({s['false_fixes_spurious']} / {s['false_fixes_alias']} / {other}) | "
              f"{s['false_fix_rate']:.2%} | {s['false_fixes_per_s']:.3f} | {s['max_fix_error_m'] * 1e3:.1f} | "
              f"{s['uncertain_points']} ({s['false_uncertain_points']}) |")
    for out in (a.json, a.csv, a.plot):  # the output files' folders, e.g. build/bench/ on a fresh clone
        if out:
            out.parent.mkdir(parents=True, exist_ok=True)
    if a.json:
        a.json.write_text(json.dumps({
            "trials_per_condition": a.trials, "first_seed": a.first_seed, "person": not a.no_person,
            "tol_mm": a.tol_mm, "wall_s": round(time.time() - t, 1),
            "conditions": [{"spurious_rate_hz": rate, "crosstalk_level": xt} | summarise_false_fixes(rs)
                           for (rate, xt), rs in results.items()]}, indent=1, default=float) + "\n")
    if a.csv:
        rows = [asdict(r) for rs in results.values() for r in rs]
        with a.csv.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
        for i, xt in enumerate(a.crosstalk):
            ss = [summarise_false_fixes(results[(r, xt)]) for r in a.rates]
            ax1.plot(a.rates, [100 * s["false_sample_rate"] for s in ss], "o-", color=f"C{i}", label=f"crosstalk {xt:g}")
            ax2.plot(a.rates, [s["false_fixes_per_s"] for s in ss], "o-", color=f"C{i}", label=f"false fixes/s, crosstalk {xt:g}")
            ax2.plot(a.rates, [s["fixes_per_s"] for s in ss], "x:", color=f"C{i}", label=f"all fixes/s, crosstalk {xt:g}")
        for ax in (ax1, ax2):
            ax.set_xscale("log")
            ax.set_xlabel("spurious pulses per channel and second")
            ax.legend(fontsize=7)
        ax1.set_ylabel("false samples (% of first echoes)")
        ax2.set_ylabel("per second of sonar time")
        ax2.set_yscale("symlog", linthresh=0.1)
        ax2.set_ylim(bottom=0)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
        print(f"\nplot: {a.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
