#!/usr/bin/env python3
"""Benchmark of multisonar.geometry: accuracy, validity, noise against the Cramer-Rao bound, speed.

Domain (every solver): 24-ring, 3 adjacent receivers (element k-1, k, k+1, k random), virtual
source at the robot origin, reflector 0.1 .. 8.6 m beyond the ring (log-uniform), bearing
within +-45 deg of the middle element's axis; cylinders radius 0.01 .. 1 m (log-uniform).

Noise-free: invalid fraction (with reasons), max / median error relative to the range.
Noisy (sigma_path = c * 1 us, i.i.d. per receiver): RMS error of the valid answers against
the Cramer-Rao bound sqrt(mean(CRB variance)) from the Jacobian at the truth, per range bin.
Solves per second: noise-free batch, one core.

    .venv/bin/python scripts/bench_geometry.py [--cases 1000000] [--cyl-cases 1000000] [--plot out.png]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from multisonar import geometry as g
from multisonar.constants import speed_of_sound
from multisonar.layout import load_layout

SIGMA = speed_of_sound() * 1e-6
BINS = [(0.1, 1.0), (1.0, 3.0), (3.0, 8.6)]


def _domain(rng, M, n=3):
    lay = load_layout()
    k = rng.integers(0, 24, M)
    idx = (k[:, None] + np.arange(n)[None] - n // 2) % 24
    C = lay.positions[idx]
    axis = lay.axes[k]
    dist = np.exp(rng.uniform(math.log(0.1), math.log(8.6), M))  # beyond the ring
    br = axis + rng.uniform(-math.radians(45), math.radians(45), M)
    return C, axis, dist, br


def _cov(J):
    A = np.einsum("mni,mnj->mij", J, J)
    with np.errstate(all="ignore"):
        cov = np.linalg.inv(A)
    return cov


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def _rms(x):
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def run_point(rng, M):
    C, axis, dist, br = _domain(rng, M)
    rho = 0.35 + dist
    x = rho[:, None] * np.stack([np.cos(br), np.sin(br)], 1)
    R = g.point_path_lengths(x, C)
    t = time.perf_counter()
    b = g.solve_point_batch(C, R, tol=1e-9)
    dt = time.perf_counter() - t
    err = np.linalg.norm(b.position - x, axis=1) / rho
    # CRB at the truth
    u0 = x / rho[:, None]
    d1 = x[:, None] - C
    J = u0[:, None] + d1 / np.linalg.norm(d1, axis=2, keepdims=True)
    cov = _cov(J) * SIGMA ** 2
    ur = u0
    ub = np.stack([-u0[:, 1], u0[:, 0]], 1) / rho[:, None]
    var = {"pos": cov[:, 0, 0] + cov[:, 1, 1],
           "range": np.einsum("mi,mij,mj->m", ur, cov, ur),
           "bearing": np.einsum("mi,mij,mj->m", ub, cov, ub)}
    bn = g.solve_point_batch(C, R + rng.normal(0, SIGMA, R.shape))
    e = {"pos": np.linalg.norm(bn.position - x, axis=1), "range": bn.range - rho,
         "bearing": _wrap(bn.bearing - br)}
    return "point", b, err, dt, dist, var, bn.valid, e


def run_wall(rng, M):
    C, axis, dist, br = _domain(rng, M)
    d = 0.35 + dist
    R = g.wall_path_lengths(d, br, C)
    t = time.perf_counter()
    b = g.solve_wall_batch(C, R, tol=1e-9)
    dt = time.perf_counter() - t
    err = np.maximum(np.abs(b.distance - d) / d, np.abs(_wrap(b.normal_angle - br)))
    n = np.stack([np.cos(br), np.sin(br)], 1)
    m = 2 * d[:, None] * n
    U = m[:, None] - C
    U = U / np.linalg.norm(U, axis=2, keepdims=True)
    cov = 0.25 * _cov(U) * SIGMA ** 2  # foot of the perpendicular = m / 2
    ub = np.stack([-n[:, 1], n[:, 0]], 1) / d[:, None]
    var = {"pos": cov[:, 0, 0] + cov[:, 1, 1],
           "range": np.einsum("mi,mij,mj->m", n, cov, n),
           "bearing": np.einsum("mi,mij,mj->m", ub, cov, ub)}
    bn = g.solve_wall_batch(C, R + rng.normal(0, SIGMA, R.shape))
    foot = d[:, None] * n
    e = {"pos": np.linalg.norm(bn.foot - foot, axis=1), "range": bn.distance - d,
         "bearing": _wrap(bn.normal_angle - br)}
    return "wall", b, err, dt, dist, var, bn.valid, e


def run_cylinder(rng, M):
    C, axis, dist, br = _domain(rng, M)
    a = np.exp(rng.uniform(math.log(0.01), math.log(1.0), M))
    r0 = 0.35 + dist
    p = (r0 + a)[:, None] * np.stack([np.cos(br), np.sin(br)], 1)
    R = g.cylinder_path_lengths(p, a, C)
    t = time.perf_counter()
    b = g.solve_cylinder_batch(C, R, tol=1e-9)
    dt = time.perf_counter() - t
    err = np.maximum(np.linalg.norm(b.centre - p, axis=1), np.abs(b.radius - a)) / (r0 + a)
    th = np.stack([br, r0, a], 1)
    with np.errstate(all="ignore"):
        _, J, _ = g._cyl_model(th, C, R)
        cov = _cov(J) * SIGMA ** 2
    var = {"radius": cov[:, 2, 2], "range": cov[:, 1, 1], "bearing": cov[:, 0, 0]}
    bn = g.solve_cylinder_batch(C, R + rng.normal(0, SIGMA, R.shape))
    e = {"radius": bn.radius - a, "range": bn.range - r0, "bearing": _wrap(bn.bearing - br)}
    return "cylinder", b, err, dt, dist, var, bn.valid, e


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=1_000_000, help="cases for point and wall")
    ap.add_argument("--cyl-cases", type=int, default=1_000_000, help="cases for the cylinder (slower, iterative)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--plot", help="write a PNG of error vs CRB per range bin")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    results = [run_point(rng, args.cases), run_wall(rng, args.cases), run_cylinder(rng, args.cyl_cases)]

    print(f"sigma_path = c * 1 us = {SIGMA * 1e3:.3f} mm; 3 adjacent ring receivers, source at the origin\n")
    print("| solver | cases | invalid (noise-free) | reasons | max rel err | median rel err | solves/s |")
    print("|---|---:|---:|---|---:|---:|---:|")
    for name, b, err, dt, dist, var, vn, e in results:
        v = b.valid
        rs = ", ".join(f"{g.REASONS[k]}: {c}" for k, c in enumerate(np.bincount(b.reason, minlength=10)) if k and c)
        print(f"| {name} | {len(v)} | {1 - v.mean():.3%} | {rs or '-'} | {err[v].max():.2e} | "
              f"{np.median(err[v]):.2e} | {len(v) / dt:,.0f} |")
    print()
    print("Noisy (1 us): RMS error of valid answers vs Cramer-Rao bound (RMS of per-case CRB std)")
    print("| solver | range bin beyond ring (m) | valid | quantity | RMS error | CRB | ratio |")
    print("|---|---|---:|---|---:|---:|---:|")
    rows = []
    for name, b, err, dt, dist, var, vn, e in results:
        for lo, hi in BINS:
            sel = vn & (dist >= lo) & (dist < hi)
            allb = (dist >= lo) & (dist < hi)
            for q in e:
                # robust against the rare ghost/ill-conditioned valid answer: RMS over the central 99.9%
                ee = e[q][sel]
                vv = var[q][sel]
                keep = np.abs(ee) <= np.quantile(np.abs(ee), 0.999) if ee.size else ee.astype(bool)
                re, cr = _rms(ee[keep]), float(np.sqrt(np.mean(vv[keep]))) if keep.any() else float("nan")
                unit, f = ("deg", 180 / math.pi) if q == "bearing" else ("mm", 1e3)
                rows.append((name, lo, hi, q, re * f, cr * f))
                print(f"| {name} | {lo:g}-{hi:g} | {sel.sum() / max(allb.sum(), 1):.1%} | {q} ({unit}) | "
                      f"{re * f:.4g} | {cr * f:.4g} | {re / cr if cr > 0 else float('nan'):.2f} |")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(9, 5))
        labels = [f"{r[0]}\n{r[3]}\n{r[1]:g}-{r[2]:g}" for r in rows]
        xs = np.arange(len(rows))
        ax.bar(xs - 0.2, [r[4] for r in rows], 0.4, label="RMS error")
        ax.bar(xs + 0.2, [r[5] for r in rows], 0.4, label="CRB")
        ax.set_yscale("log")
        ax.set_xticks(xs, labels, fontsize=5)
        ax.set_ylabel("mm or deg")
        ax.set_title("geometry under 1 us timing noise: error vs Cramer-Rao bound")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=120)
        print(f"\nplot written to {args.plot}")


if __name__ == "__main__":
    main()
