#!/usr/bin/env python3
"""The miss hold's cost and gain on the noisy corridor (issue #28), on the golden model.

The demo's five sensors on the corridor scene (spurious pulses, crosstalk, fading echoes) for
--seconds of sonar time per scene seed, with RX_FILTER.miss_hold on and off
(docs/fast_firing.md section 4.4): per sensor the pulses, init pings and tracking samples, and the
wall fixes of the host geometry with the false ones among them (farther than 50 mm from the true
wall). The safety side (person crossings) is `multisonar experiment safety`.

    .venv/bin/python scripts/bench_miss_hold.py [--seeds 1-6] [--seconds 1.0] [--json F.json] [--plot F.png]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from multisonar.demo import run_golden  # noqa: E402
from multisonar.scene import load_scene  # noqa: E402

FALSE_WALL_M = 0.05


def _seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def run(seeds: list[int], seconds: float, hold: bool) -> dict:
    out: dict = {"miss_hold": hold, "pulses": {}, "init_pings": {}, "samples": {}, "wall_fixes": 0,
                 "false_wall_fixes": 0}
    for seed in seeds:
        r = run_golden(load_scene("corridor", seed=seed), seconds, progress=False, miss_hold=hold)
        for key in ("pulses", "init_pings", "samples"):
            for name, v in getattr(r, key).items():
                out[key][name] = out[key].get(name, 0) + int(v)
        walls = [f for f in r.fixes if f.kind == "wall"]
        out["wall_fixes"] += len(walls)
        out["false_wall_fixes"] += sum(f.error > FALSE_WALL_M for f in walls)
    for key in ("pulses", "init_pings", "samples"):
        out[key]["all"] = sum(out[key].values())
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=_seeds, default=_seeds("1-6"), help="scene seeds, A-B (default 1-6)")
    ap.add_argument("--seconds", type=float, default=1.0, help="sonar seconds per seed (default %(default)s)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--plot", type=Path, help="tracking samples per sensor, hold on / off")
    a = ap.parse_args()
    t = time.time()
    on, off = run(a.seeds, a.seconds, True), run(a.seeds, a.seconds, False)
    names = list(on["samples"])
    print(f"corridor, seeds {a.seeds[0]}-{a.seeds[-1]} x {a.seconds:g} s, golden model ({time.time() - t:.0f} s)")
    print("| sensor | pulses off / on | init pings off / on | samples off / on | samples on / off |")
    print("|---|---:|---:|---:|---:|")
    for n in names:
        print(f"| {n} | {off['pulses'][n]} / {on['pulses'][n]} | {off['init_pings'][n]} / {on['init_pings'][n]} "
              f"| {off['samples'][n]} / {on['samples'][n]} | {on['samples'][n] / max(off['samples'][n], 1):.3f} |")
    print(f"wall fixes off / on: {off['wall_fixes']} / {on['wall_fixes']}; false (> {FALSE_WALL_M * 1e3:.0f} mm) "
          f"{off['false_wall_fixes']} / {on['false_wall_fixes']}")
    doc = {"scene": "corridor", "seeds": a.seeds, "seconds": a.seconds, "off": off, "on": on,
           "sample_ratio": on["samples"]["all"] / max(off["samples"]["all"], 1)}
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(doc, indent=1))
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 3.5))
        xs = range(len(names) - 1)
        ax.bar([x - 0.2 for x in xs], [off["samples"][n] for n in names[:-1]], 0.4, label="miss hold off")
        ax.bar([x + 0.2 for x in xs], [on["samples"][n] for n in names[:-1]], 0.4, label="miss hold on")
        ax.set_xticks(list(xs), names[:-1])
        ax.set_ylabel("tracking samples")
        ax.set_title("corridor: tracking samples per sensor")
        ax.legend()
        a.plot.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(a.plot, dpi=120, bbox_inches="tight")
    return 0


if __name__ == "__main__":
    sys.exit(main())
