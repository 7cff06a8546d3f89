#!/usr/bin/env python3
"""Geometry property run (issue #9): >= 10^6 random cases per solver over the whole domain.

Every solver of multisonar.geometry (point, wall, cylinder, classify) and of the firmware
library firmware/geometry (host build, arithmetic variants f64, f32, q; the C classify has no
cylinder answer) gets the *same* random cases, drawn from the whole input domain:

  arrays     N = 2/3/5/8 receivers (cylinder, classify: 3/5/8); half 24-ring adjacent
             receivers (virtual source at the robot origin or collocated with a receiver),
             half random arrays (receiver at / within 1 mm of the source, receivers within
             1e-4 rad of one line through the source); 4% two receivers coincide, 1% all
             receivers at one point (degenerate; counted with the near-collinear arrays);
  range      beyond the farthest receiver: 80% 0.1..8.6 m, 10% tiny 1e-4..0.1 m, 10% huge
             8.6..300 m (log-uniform);
  bearing    75% within +-45 deg of the array axis, 15% grazing 45..90 deg off the axis
             (beyond the +-60 deg field of view), 10% along a receiver baseline +-1 mrad
             (reflector nearly collinear with the receivers);
  truth      30% point, 25% wall, 20% cylinder (radius 1 mm..10 m), 25% *no solution*:
             a path shorter than its receiver's baseline (no reflection path is that short),
             a pair violating the triangle inequality |R_i - R_j| <= |c_i - c_j| (true of the
             point, wall and specular-cylinder models alike) by delta >= 1.05 sqrt(2N) tol
             (so every answer misfits by > tol), or garbage (NaN, Inf, 0, negative);
  noise      55% none, 35% 1 us of path (0.34 mm), 10% 2 cm (no usable truth: only the
             self-consistency checks below apply).

Counted per solver and implementation:
  NaN/Inf      any non-finite output (must be 0);
  flags        valid <=> reason == 0 (inconsistent flags must be 0);
  no solution  invalid with a reason (must be all of them; classify: 'uncertain');
  garbage      a valid answer that does not explain its data: recomputed RMS misfit of the
               answer > tol + slack, gdop > max_gdop or not physical (must be 0);
  beyond bound valid answers on solvable model data (noise <= 1 us) farther from the truth
               than the stated bound (tests/test_geometry.py, tests/test_fw_geometry.py,
               ms_geom.h: f64 1e-9 range, f32 2e-6 m gdop + 2e-6 range, q 2 um + 1e-8 m
               gdop^2 + its 1 um input rounding, cylinder per variant) plus the conditioning
               term 16 u gdop range (u = unit roundoff: 2^-53 f64, 2^-24 f32, 2^-31 q; it
               dominates beyond the stated 8.6 m domain, e.g. f32 at 300 m) plus 6 gdop sigma
               for 1 us noise; all of them must explain the data: another exact solution (the
               mirror image of a two-receiver or collinear array, a second exact cylinder of
               N = 3) or a truth outside the field of view, where the in-view mirror is the
               documented answer; split into 'explains data' (explained) / 'not' (garbage);
  classify     no-solution data must give 'uncertain'; confident edge<->wall swaps on edge
               / wall data (noise <= 1 us) are counted (expected ~ 1 - confidence).

    .venv/bin/python scripts/bench_geometry_property.py [--cases 1000000] [--impl python,f64,f32,q]
        [--solvers point,wall,cylinder,classify] [--seed 1] [--plot FILE.png]
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from multisonar import geometry as g  # noqa: E402

import test_fw_geometry as tfw  # noqa: E402  (ctypes wrapper of the host build)
import test_geometry as tg  # noqa: E402  (array generators)

IMPLS = ("python", "f64", "f32", "q")
SOLVERS = ("point", "wall", "cylinder", "classify")
N_MIX = {"point": {2: 0.3, 3: 0.35, 5: 0.2, 8: 0.15}, "wall": {2: 0.3, 3: 0.35, 5: 0.2, 8: 0.15},
         "cylinder": {3: 0.5, 5: 0.3, 8: 0.2}, "classify": {3: 0.5, 5: 0.3, 8: 0.2}}
TRUTH = ("point", "wall", "cylinder", "no solution")
T_POINT, T_WALL, T_CYL, T_NOSOL = range(4)
SIG = g.DEFAULT_NOISE_SIGMA
BIG_SIG = 0.02
TOL = g.DEFAULT_TOL
CHUNK = 50000
N_SIGMA = 6.0  # noisy bound: 6 gdop sigma (chi-square tail < 1e-7 per case)
K_COND = 16.0  # conditioning term K * U * gdop * range (see _bound)
U_ROUND = {"python": 2.0 ** -53, "f64": 2.0 ** -53, "f32": 2.0 ** -24, "q": 2.0 ** -31}
FOV_EDGE = math.radians(3.0)  # truth this close to the FOV edge: noise may push it out


# --------------------------------------------------------------------------------------
# cases
# --------------------------------------------------------------------------------------


def gen_cases(rng, M, N):
    """Random cases over the whole domain (module docstring). Returns a dict of arrays."""
    ring = rng.random(M) < 0.5
    C = np.zeros((M, N, 2))
    S = np.zeros((M, 2))
    axis = np.zeros(M)
    C[ring], S[ring], axis[ring] = tg._ring_sets(rng, int(ring.sum()), N)
    C[~ring], S[~ring], axis[~ring] = tg._random_sets(rng, int((~ring).sum()), N)
    u = rng.random(M)
    dup = u < 0.04
    C[dup, 1] = C[dup, 0]
    same = (u >= 0.04) & (u < 0.05)
    C[same] = C[same, :1]
    degen = dup | same | tg._collinear_ish(C, S)  # coincident receivers, or all on one line
    base = np.max(np.linalg.norm(C - S[:, None, :], axis=2), axis=1)
    v = rng.random(M)
    off = np.exp(rng.uniform(math.log(0.1), math.log(8.6), M))
    off = np.where(v < 0.1, np.exp(rng.uniform(math.log(1e-4), math.log(0.1), M)), off)
    off = np.where(v >= 0.9, np.exp(rng.uniform(math.log(8.6), math.log(300.0), M)), off)
    r = base + off
    w = rng.random(M)
    br = axis + rng.uniform(-tg.MAX_OFF, tg.MAX_OFF, M)
    graz = w < 0.15
    sgn = np.where(rng.random(M) < 0.5, -1.0, 1.0)
    br = np.where(graz, axis + sgn * rng.uniform(tg.MAX_OFF, 0.5 * math.pi, M), br)
    bl = C[:, -1] - C[:, 0]
    coll = (w >= 0.15) & (w < 0.25) & (np.linalg.norm(bl, axis=1) > 0)
    bdir = np.arctan2(bl[:, 1], bl[:, 0]) + np.pi * (rng.random(M) < 0.5) + rng.normal(0, 1e-3, M)
    br = np.where(coll, bdir, br)
    ub = np.stack([np.cos(br), np.sin(br)], 1)
    out_fov = np.abs(tg._wrap(br - axis)) > g.DEFAULT_FOV - FOV_EDGE

    t = rng.random(M)
    truth = np.where(t < 0.3, T_POINT, np.where(t < 0.55, T_WALL, np.where(t < 0.75, T_CYL, T_NOSOL)))
    x = S + r[:, None] * ub
    R = g.point_path_lengths(x, C, S)
    wl = truth == T_WALL
    R[wl] = g.wall_path_lengths(r[wl], br[wl], C[wl], S[wl])
    a = np.exp(rng.uniform(math.log(1e-3), math.log(10.0), M))
    p = S + (r + a)[:, None] * ub
    cy = np.flatnonzero(truth == T_CYL)
    with np.errstate(all="ignore"):
        L, _, _, ok = g._specular((p[cy] - S[cy])[:, None, :], a[cy][:, None], C[cy] - S[cy][:, None, :], iters=12)
    ok = np.all(ok, axis=1) & np.all(np.isfinite(L), axis=1)
    R[cy[ok]] = L[ok]
    truth[cy[~ok]] = T_POINT  # (never seen: receivers are inside the range disc)

    nz = rng.random(M)
    noise = np.where(nz < 0.55, 0, np.where(nz < 0.9, 1, 2))
    sig = np.where(noise == 0, 0.0, np.where(noise == 1, SIG, BIG_SIG))
    R = R + rng.normal(0.0, 1.0, R.shape) * sig[:, None]

    ns = np.flatnonzero(truth == T_NOSOL)
    noise[ns] = 0
    k = rng.random(ns.size)
    i = rng.integers(0, N, ns.size)
    j = (i + rng.integers(1, N, ns.size)) % N
    cn = np.linalg.norm(C[ns] - S[ns][:, None, :], axis=2)
    short = k < 0.25
    rows = ns[short]
    R[rows, i[short]] = cn[short, i[short]] * rng.random(short.sum()) - 2e-6
    tri = (k >= 0.25) & (k < 0.85)
    rows = ns[tri]
    dij = np.linalg.norm(C[rows, i[tri]] - C[rows, j[tri]], axis=1)
    dmin = 1.05 * math.sqrt(2 * N) * TOL
    delta = np.exp(rng.uniform(math.log(dmin), 0.0, tri.sum()))
    R[rows, j[tri]] = R[rows, i[tri]] + dij + delta
    gar = k >= 0.85
    rows = ns[gar]
    R[rows, i[gar]] = rng.choice(np.array([np.nan, np.inf, -np.inf, 0.0, -1.0]), gar.sum())
    return dict(C=C, S=S, axis=axis, R=R, truth=truth, noise=noise, degen=degen, out_fov=out_fov,
                x=x, r=r, br=br, p=p, a=a)


# --------------------------------------------------------------------------------------
# running one implementation
# --------------------------------------------------------------------------------------


class Impl:
    def __init__(self, name):
        self.name = name
        self.fw = None if name == "python" else tfw.FwGeom(name)

    def inputs(self, cs):
        C, S, R = cs["C"], cs["S"], cs["R"]
        if self.fw is not None:
            C, S, R = self.fw.quantize(C, S, R)
        return C, S, R

    def solve(self, solver, C, R, S, axis):
        """Common dict: valid, reason, raw (every output, for the NaN/Inf check) + fields."""
        if self.fw is None:
            f = {"point": g.solve_point_batch, "wall": g.solve_wall_batch,
                 "cylinder": g.solve_cylinder_batch, "classify": g.classify_batch}[solver]
            b = f(C, R, S, axis=axis)
            if solver == "point":
                d = dict(valid=b.valid, reason=b.reason, position=b.position, range=b.range,
                         bearing=b.bearing, residual=b.residual, gdop=b.gdop)
            elif solver == "wall":
                d = dict(valid=b.valid, reason=b.reason, distance=b.distance, normal_angle=b.normal_angle,
                         foot=b.foot, residual=b.residual, gdop=b.gdop)
            elif solver == "cylinder":
                d = dict(valid=b.valid, reason=b.reason, centre=b.centre, radius=b.radius, range=b.range,
                         bearing=b.bearing, residual=b.residual, gdop=b.gdop)
            else:
                d = dict(kind=b.kind, chi2=b.chi2, reason=np.zeros(len(R), int))
            d["raw"] = np.concatenate([np.asarray(v, np.float64).reshape(len(R), -1) for v in d.values()], 1)
            return d
        fw = self.fw
        if solver == "classify":
            return fw.classify(C, R, S, axis)
        return getattr(fw, solver)(C, R, S, axis)


def _misfit(solver, d, C, S, R):
    """Recomputed RMS path misfit of each answer and whether it is physical."""
    with np.errstate(all="ignore"):
        if solver == "point":
            Rm = g.point_path_lengths(d["position"], C, S)
            phys = d["range"] > 0
        elif solver == "wall":
            Rm = g.wall_path_lengths(d["distance"], d["normal_angle"], C, S)
            phys = d["distance"] > 0
        else:
            L, _, _, ok = g._specular((d["centre"] - S)[:, None, :], d["radius"][:, None],
                                      C - S[:, None, :], iters=30)
            Rm, phys = L, np.all(ok, axis=1) & (d["radius"] >= 0)
        mis = np.sqrt(np.mean((Rm - R) ** 2, axis=1))
    return np.where(np.isfinite(mis), mis, np.inf), phys


def _slack(impl, scale):
    """Misfit slack of the recomputation: rounding of the answer in the variant's format."""
    return {"python": 1e-9, "f64": 1e-9, "f32": 1e-5, "q": 2e-6}[impl] * np.maximum(scale, 1.0) + \
        {"python": 0.0, "f64": 0.0, "f32": 0.0, "q": 2e-6}[impl]


def _bound(solver, impl, gd, scale, noisy, N):
    """Stated error bound against the truth (module docstring)."""
    gd1 = np.maximum(gd, 1.0)
    if solver == "cylinder":
        b = {"python": 1e-9 * scale * gd1, "f64": 1e-9 * scale * gd1,
             "f32": tfw.CYL_ABS["f32"] + tfw.CYL_REL["f32"] * gd1 * scale,
             "q": tfw.CYL_ABS["q"] + tfw.CYL_REL["q"] * gd1 * scale + 1e-6 * gd1 * math.sqrt(N)}[impl]
    else:
        b = {"python": tfw.F64_REL * scale, "f64": tfw.F64_REL * scale,
             "f32": tfw.F32_ABS * gd1 + tfw.F32_REL * scale,
             "q": tfw.Q_ABS + tfw.Q_GDOP * gd1 ** 2 + 1e-6 * gd1 * math.sqrt(N)}[impl]
    # + the conditioning of the problem itself: the inputs and path sums rounded in the
    # variant's arithmetic (unit roundoff U), amplified by gdop (beyond the stated domain's
    # 8.6 m this term dominates the stated bound of f32)
    b = b + K_COND * U_ROUND[impl] * gd1 * scale
    return b + np.where(noisy, N_SIGMA * gd1 * SIG, 0.0)


def evaluate(solver, impl, d, cs, C, S, R):
    """Counters of one chunk (dict of ints)."""
    M, N = R.shape
    truth, noise = cs["truth"], cs["noise"]
    fin = np.all(np.isfinite(d["raw"]), axis=1)
    c = dict(cases=M, naninf=int(np.sum(~fin)))
    nosol = truth == T_NOSOL
    c["nosol"] = int(nosol.sum())
    if solver == "classify":
        kind = d["kind"]
        c["badkind"] = int(np.sum((kind < 0) | (kind > 3)))
        c["nosol_ok"] = int(np.sum(nosol & (kind == 3)))
        c["nosol_bad"] = int(np.sum(nosol & (kind != 3)))
        ew = np.isin(truth, (T_POINT, T_WALL)) & (noise < 2)
        c["ew"] = int(ew.sum())
        c["ew_right"] = int(np.sum(ew & (kind == truth)))
        c["ew_uncertain"] = int(np.sum(ew & (kind == 3)))
        c["ew_swap"] = int(np.sum(ew & (kind == 1 - truth)))
        c["ew_cyl"] = int(np.sum(ew & (kind == 2)))
        return c
    valid, reason = np.asarray(d["valid"], bool), np.asarray(d["reason"])
    c["flags"] = int(np.sum(valid != (reason == 0)) + np.sum(reason >= len(g.REASONS)))
    c["nosol_ok"] = int(np.sum(nosol & ~valid & (reason > 0)))
    c["nosol_bad"] = int(np.sum(nosol & valid))
    c["valid"] = int(valid.sum())
    if solver == "point":
        scale = np.maximum(d["range"], 1e-3)
    elif solver == "wall":
        scale = np.maximum(d["distance"], 1e-3)
    else:
        scale = np.maximum(d["range"] + d["radius"], 1e-3)
    mis, phys = _misfit(solver, d, C, S, R)
    explains = (mis <= TOL * (1 + 1e-6) + _slack(impl, scale)) & phys & (d["gdop"] <= g.DEFAULT_MAX_GDOP * (1 + 1e-6))
    garbage = valid & ~explains
    c["garbage"] = int(garbage.sum())
    tcode = {"point": T_POINT, "wall": T_WALL, "cylinder": T_CYL}[solver]
    sol = (truth == tcode) & (noise < 2)
    c["solvable"] = int(sol.sum())
    c["sol_valid"] = int(np.sum(sol & valid))
    rs = np.bincount(reason[sol & ~valid].astype(int), minlength=len(g.REASONS))
    for k in range(1, len(g.REASONS)):
        c[f"reason{k}"] = int(rs[k])
    if solver == "point":
        err = np.linalg.norm(d["position"] - cs["x"], axis=1)
        tscale = cs["r"]
    elif solver == "wall":
        err = np.maximum(np.abs(d["distance"] - cs["r"]), np.abs(tg._wrap(d["normal_angle"] - cs["br"])) * cs["r"])
        tscale = cs["r"]
    else:
        err = np.maximum(np.linalg.norm(d["centre"] - cs["p"], axis=1), np.abs(d["radius"] - cs["a"]))
        tscale = cs["r"] + cs["a"]
    gd = np.where(valid, d["gdop"], 0.0)
    beyond = sol & valid & ~(err <= _bound(solver, impl, gd, tscale, noise == 1, N))
    c["beyond"] = int(beyond.sum())
    c["beyond_explains"] = int(np.sum(beyond & explains))
    c["beyond_outfov"] = int(np.sum(beyond & explains & cs["out_fov"]))
    c["beyond_degen"] = int(np.sum(beyond & explains & ~cs["out_fov"] & cs["degen"]))
    if solver == "point":
        ang = d["bearing"]
    elif solver == "wall":
        ang = d["normal_angle"]
    else:
        ang = d["bearing"]
    ans_out = np.abs(tg._wrap(ang - cs["axis"])) > g.DEFAULT_FOV
    c["beyond_ansout"] = int(np.sum(beyond & explains & ~cs["out_fov"] & ~cs["degen"] & ans_out))
    c["beyond_other_noisy"] = int(np.sum(beyond & explains & ~cs["out_fov"] & ~cs["degen"] & ~ans_out & (noise == 1)))
    c["beyond_garbage"] = int(np.sum(beyond & ~explains))
    c["sol_nf"] = int(np.sum(sol & (noise == 0)))
    c["sol_nf_valid"] = int(np.sum(sol & (noise == 0) & valid))
    return c


def _add(acc, c):
    for k, v in c.items():
        acc[k] = acc.get(k, 0) + v


def run(cases, impls=IMPLS, solvers=SOLVERS, seed=1, progress=None):
    """{(solver, impl): counters}, {(solver, impl): seconds in the solver}."""
    fws = {i: Impl(i) for i in impls}
    res, secs = {}, {}
    for si, solver in enumerate(solvers):
        rng = np.random.default_rng([seed, si])
        for N, frac in N_MIX[solver].items():
            todo = int(round(cases * frac))
            while todo > 0:
                m = min(CHUNK, todo)
                todo -= m
                cs = gen_cases(rng, m, N)
                for name, im in fws.items():
                    C, S, R = im.inputs(cs)
                    t0 = time.perf_counter()
                    with np.errstate(all="ignore"):
                        d = im.solve(solver, C, R, S, cs["axis"])
                    secs[(solver, name)] = secs.get((solver, name), 0.0) + time.perf_counter() - t0
                    _add(res.setdefault((solver, name), {}), evaluate(solver, name, d, cs, C, S, R))
                if progress:
                    progress(f"{solver} N={N}: {todo} left")
    return res, secs


def table(res, secs):
    lines = ["| solver | impl | cases | NaN/Inf | flag errors | no-solution cases | invalid with reason "
             "| valid on no solution | garbage (valid, misfit > tol) | solvable (model truth, noise <= 1 us) "
             "| valid | beyond bound | of which explains data (truth at/outside FOV edge / degenerate array / "
             "answer outside FOV / other solution noise-free + 1 us) | beyond bound, not explaining data | solves/s |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|"]
    cls = ["| impl | cases | NaN/Inf | kind out of range | no-solution cases | 'uncertain' | confident "
           "on no solution | edge/wall truth (noise <= 1 us) | right | uncertain | edge<->wall swapped "
           "| 'cylinder' | solves/s |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for (solver, impl), c in res.items():
        rate = c["cases"] / max(secs[(solver, impl)], 1e-9)
        if solver == "classify":
            cls.append(f"| {impl} | {c['cases']} | {c['naninf']} | {c['badkind']} | {c['nosol']} | {c['nosol_ok']} "
                       f"| {c['nosol_bad']} | {c['ew']} | {c['ew_right'] / max(c['ew'], 1):.3%} "
                       f"| {c['ew_uncertain'] / max(c['ew'], 1):.3%} "
                       f"| {c['ew_swap']} ({c['ew_swap'] / max(c['ew'], 1):.4%}) "
                       f"| {c['ew_cyl']} | {rate:,.0f} |")
            continue
        other = c["beyond_explains"] - c["beyond_outfov"] - c["beyond_degen"] - c["beyond_ansout"]
        noisy = c["beyond_other_noisy"]
        lines.append(f"| {solver} | {impl} | {c['cases']} | {c['naninf']} | {c['flags']} | {c['nosol']} "
                     f"| {c['nosol_ok']} | {c['nosol_bad']} | {c['garbage']} | {c['solvable']} "
                     f"| {c['sol_valid'] / max(c['solvable'], 1):.2%} | {c['beyond']} "
                     f"| {c['beyond_explains']} ({c['beyond_outfov']} / {c['beyond_degen']} / {c['beyond_ansout']} "
                     f"/ {other - noisy} + {noisy}) "
                     f"| {c['beyond_garbage']} | {rate:,.0f} |")
    reasons = ["| solver | impl | " + " | ".join(g.REASONS[1:]) + " |", "|---|---|" + "---:|" * (len(g.REASONS) - 1)]
    for (solver, impl), c in res.items():
        if solver != "classify":
            cells = " | ".join(str(c[f"reason{k}"]) for k in range(1, len(g.REASONS)))
            reasons.append(f"| {solver} | {impl} | {cells} |")
    return "\n".join(lines), "\n".join(cls), "\n".join(reasons)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", type=int, default=1_000_000, help="cases per solver (default 10^6)")
    ap.add_argument("--impl", default=",".join(IMPLS), help="comma list of python,f64,f32,q")
    ap.add_argument("--solvers", default=",".join(SOLVERS), help="comma list of point,wall,cylinder,classify")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--plot", metavar="FILE", help="write a PNG of the invalid-reason mix on solvable data")
    a = ap.parse_args(argv)
    impls = [s for s in a.impl.split(",") if s]
    solvers = [s for s in a.solvers.split(",") if s]
    for s in impls:
        if s not in IMPLS:
            ap.error(f"unknown implementation {s!r} (choose from {', '.join(IMPLS)})")
    for s in solvers:
        if s not in SOLVERS:
            ap.error(f"unknown solver {s!r} (choose from {', '.join(SOLVERS)})")
    if a.cases < 1000:
        ap.error("--cases must be >= 1000")
    if any(s != "python" for s in impls):
        subprocess.run(["make", "-s", "-C", str(ROOT / "firmware"), "host-libs"], check=True)
    t0 = time.perf_counter()
    res, secs = run(a.cases, impls, solvers, a.seed,
                    progress=lambda s: print(f"  [{time.perf_counter() - t0:6.0f} s] {s}", file=sys.stderr))
    main_t, cls_t, rs_t = table(res, secs)
    print(f"Geometry property run: {a.cases} cases per solver and implementation, seed {a.seed}, "
          f"{time.perf_counter() - t0:.0f} s wall\n")
    print(main_t)
    if "classify" in solvers:
        print("\nclassify (C: no 'cylinder' answer, it says 'uncertain' there):\n")
        print(cls_t)
    print("\nInvalid answers on solvable data (model truth, noise <= 1 us), by reason:\n")
    print(rs_t)
    print("\nMust be 0: NaN/Inf, flag errors, valid on no solution, garbage, beyond bound not explaining data, "
          "classify confident on no solution.")
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        keys = [k for k in res if k[0] != "classify"]
        fig, ax = plt.subplots(figsize=(10, 4.5))
        bottom = np.zeros(len(keys))
        for r in range(1, len(g.REASONS)):
            h = np.array([res[k][f"reason{r}"] / max(res[k]["solvable"], 1) for k in keys])
            if h.any():
                ax.bar(np.arange(len(keys)), h, bottom=bottom, label=g.REASONS[r])
                bottom += h
        ax.set_xticks(np.arange(len(keys)), [f"{s}\n{i}" for s, i in keys], fontsize=7)
        ax.set_ylabel("fraction of solvable cases answered invalid")
        ax.set_title(f"geometry property run, {a.cases} cases per solver: invalid reasons on solvable data")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=110)
        print(f"\nplot: {a.plot}")


if __name__ == "__main__":
    main()
