#!/usr/bin/env python3
"""Benchmark of the acoustic model (multisonar.acoustics): firings per second.

Prints markdown tables:
 1. every shipped scene: one firing of 1 element and of a 3-element virtual source
    (all 24 receivers), t0 cycled over the scene's duration;
 2. cost against the number of reflectors of each kind (walls with and without
    second-order reflections, points, cylinders, people), static and moving robot.

    .venv/bin/python scripts/bench_acoustics.py [--quick] [--plot out.png] [--json out.json]

Timing: best of several batches of ``--firings`` firings each (wall clock, one core).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from multisonar.acoustics import AcousticModel, Firing  # noqa: E402
from multisonar.scene import available_scenes, load_scene, parse_scene  # noqa: E402


def rate(model: AcousticModel, firings: list[Firing], repeats: int) -> float:
    """Firings per second (best batch)."""
    best = math.inf
    model.fire(firings[0])  # warm-up
    for _ in range(repeats):
        model._components.clear()  # the model keeps recent firings' geometry: time it, not the cache
        t = time.perf_counter()
        for f in firings:
            model.fire(f)
        best = min(best, time.perf_counter() - t)
    return len(firings) / best


def firings_for(scene, n: int, elements: list[int]) -> list[Firing]:
    ts = np.linspace(0.0, scene.duration_s, n, endpoint=False)
    rot = len(scene.layout.positions)
    out = []
    for i, t in enumerate(ts):
        el = [(e + 3 * i) % rot for e in elements]  # rotate around the ring
        if len(el) == 1:
            out.append(Firing.single(float(t), el[0]))
        else:
            out.append(Firing.phased(float(t), el, scene.layout, scene.speed_of_sound))
    return out


def synthetic(kind: str, n: int, moving: bool, second_order: bool = True):
    """A scene with n reflectors of one kind around the robot, 1..4 m away."""
    rng = np.random.default_rng(n)
    doc: dict = {"name": f"{kind}{n}", "model": {"second_order": second_order}}
    if moving:
        doc["trajectory"] = [{"t": 0, "x": 0, "y": 0, "heading_deg": 0}, {"t": 1, "x": 2.0, "y": 0, "heading_deg": 30}]
        doc["footprint_margin"] = 0.0
    ang = rng.uniform(0, 2 * np.pi, n)
    dist = rng.uniform(1.2, 4.0, n)
    cx, cy = dist * np.cos(ang), dist * np.sin(ang)
    if moving:  # keep clear of the robot's path along the x axis
        cy = np.where(cy < 0, -1.0, 1.0) * np.maximum(np.abs(cy), 1.0)
    if kind.startswith("wall"):
        # tangential segments 1 m long
        doc["walls"] = [{"a": [float(x - 0.5 * math.sin(a)), float(y + 0.5 * math.cos(a))],
                         "b": [float(x + 0.5 * math.sin(a)), float(y - 0.5 * math.cos(a))]}
                        for x, y, a in zip(cx, cy, ang)]
    elif kind == "points":
        doc["points"] = [{"at": [float(x), float(y)]} for x, y in zip(cx, cy)]
    elif kind == "cylinders":
        doc["cylinders"] = [{"center": [float(x), float(y)], "radius": 0.1} for x, y in zip(cx, cy)]
    elif kind == "people":
        doc["people"] = [{"radius": 0.2, "path": [{"t": 0, "x": float(x), "y": float(y)},
                                                  {"t": 1, "x": float(x + 0.5), "y": float(y)}]}
                         for x, y in zip(cx, cy)]
    return parse_scene(doc, source=f"<bench {kind}{n}>")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--firings", type=int, default=60, help="firings per timed batch")
    ap.add_argument("--repeats", type=int, default=3, help="batches (best is reported)")
    ap.add_argument("--quick", action="store_true", help="fewer sizes and firings")
    ap.add_argument("--plot", type=Path, help="write a cost-vs-reflectors plot (PNG)")
    ap.add_argument("--json", type=Path, help="write both tables as JSON")
    args = ap.parse_args(argv)
    out: dict = {"scenes": [], "reflectors": []}
    nf = 20 if args.quick else args.firings
    reps = 2 if args.quick else args.repeats

    print("## Acoustic model: firings per second per shipped scene (24 receivers, one core)\n")
    print("| scene | reflectors | robot | 1 element [firings/s] | 3-element virtual source [firings/s] | pulses/firing (3 el.) |")
    print("|---|---:|---|---:|---:|---:|")
    for name in available_scenes():
        sc = load_scene(name)
        m = AcousticModel(sc)
        f1 = firings_for(sc, nf, [0])
        f3 = firings_for(sc, nf, [23, 0, 1])
        r1, r3 = rate(m, f1, reps), rate(m, f3, reps)
        npulse = np.mean([m.fire(f).size for f in f3])
        print(f"| {name} | {sc.n_reflectors} | {'static' if sc.is_static else 'moving'} | {r1:,.0f} | {r3:,.0f} | {npulse:.1f} |")
        out["scenes"].append({"scene": name, "reflectors": sc.n_reflectors, "moving": not sc.is_static,
                              "firings_per_s_1_element": r1, "firings_per_s_3_elements": r3,
                              "ms_per_firing_1_element": 1e3 / r1, "ms_per_firing_3_elements": 1e3 / r3,
                              "pulses_per_firing_3_elements": float(npulse)})

    sizes = [0, 1, 4, 16] if args.quick else [0, 1, 2, 4, 8, 16, 32, 64]
    kinds = ["walls", "walls (no 2nd order)", "points", "cylinders", "people"]
    print("\n## Cost against number of reflectors: microseconds per firing (3-element virtual source, 24 receivers)\n")
    print("| reflectors | " + " | ".join(f"{k}, robot static | {k}, robot moving" for k in kinds) + " |")
    print("|---:|" + "---:|" * (2 * len(kinds)))
    results: dict[tuple[str, bool], list[float]] = {}
    for n in sizes:
        row = []
        for k in kinds:
            for moving in (False, True):
                sc = synthetic(k.split()[0], n, moving, second_order="no 2nd" not in k)
                m = AcousticModel(sc)
                fs = firings_for(sc, max(nf // 2, 5), [23, 0, 1])
                us = 1e6 / rate(m, fs, reps)
                results.setdefault((k, moving), []).append(us)
                out["reflectors"].append({"kind": k, "moving": moving, "reflectors": n, "us_per_firing": us})
                row.append(f"{us:,.0f}")
        print(f"| {n} | " + " | ".join(row) + " |")

    if args.json:
        import json

        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(out, indent=2) + "\n")
        print(f"\nwrote {args.json}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for (k, moving), ys in results.items():
            ax.plot([max(s, 0.5) for s in sizes], ys, marker="o", linestyle="-" if moving else "--",
                    label=f"{k}, robot {'moving' if moving else 'static'}")
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("reflectors in the scene (0 plotted at 0.5)")
        ax.set_ylabel("µs per firing (3-element source, 24 rx)")
        ax.set_title("multisonar.acoustics: cost vs reflectors")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"\nplot written to {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
