"""Fixed geometry cases for the soft-core benchmark (firmware/app/bench_geom.c), their float64
reference from :mod:`multisonar.geometry`, and the decoder of the firmware's mailbox stream.

    python -m multisonar.tools.geom_cases --header build/fw/bench_cases.h

One module owns the whole protocol, so the C header, the Python reference and the decoder
cannot drift apart. Cases (deterministic, seeded), all made with the forward models
``point_path_lengths`` / ``wall_path_lengths`` of the golden model:

* ``typical`` (16): three adjacent receivers of the 24-element ring, the source either the
  middle element (1 transmitter / 3 receivers) or the ring centre (the phased virtual
  source); an edge (8) or a wall (8) 1..4 m beyond the ring, up to +-20 deg off the sensor
  axis; 1 us of path noise (sigma 0.343 mm). These are what the firmware solves per pulse.
* ``extreme`` (11): 0.15 m and 8 m, 40-45 deg off axis, two receivers (classify rejects
  N = 2), five and eight receivers, a 5 cm outlier (inconsistent data), a path shorter than
  the baseline, and two pillars (cylinders of radius 0.15 m and 0.5 m, made with
  ``cylinder_path_lengths``) on which the benchmark also times the cylinder solver (``cyl``:
  it costs millions of cycles, so only there).

Inputs are rounded to 1 um (the Q variant's interface; every variant and Python get exactly
the same numbers). Options are the library defaults (axis: receivers' mean outward
direction, tol 1 mm, max gdop 1e4, fov 60 deg); classify uses sigma = 343 um.

Mailbox stream (32-bit words, in order):
  header  MAGIC | arith (1 f64, 2 f32, 3 q), number of cases, timer overhead (cycles of
          back-to-back counter reads), instruction overhead (the same in retired
          instructions); both already subtracted from every count below
  per case, four calls in this order, each ``cycles, instructions`` then ``status, fields...``:
    prepare   (ms_prepare: the per-sensor set-up; no status, no fields)
    point     status valid | reason << 8;  x, y, range, bearing, residual, gdop
    wall      status valid | reason << 8;  distance, normal_angle, foot_x, foot_y, residual, gdop
    classify  (ms_fix: both fits + the decision) status kind | accepted << 4 | reason << 8 |
              point.reason << 16 | wall.reason << 24;  chi2 edge, chi2 wall
    cylinder  (ms_solve_cylinder, only on cases with ``cyl``; else all zero) status
              valid | reason << 8 | ran << 16;  cx, cy, radius, range, bearing, residual
  trailer DONE
Each field is the variant's own interface value, losslessly: f64 two words (the IEEE
double, low word first), f32 one word (IEEE float bits), q one int32 word (lengths um,
angles 2^32 per turn, numbers Q16.16).
"""

from __future__ import annotations

import argparse
import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import geometry as g
from ..layout import load_layout

MAGIC = 0x6E0B0000
DONE = 0x00000D0E
ARITH = {1: "f64", 2: "f32", 3: "q"}
N_POINT_FIELDS, N_WALL_FIELDS, N_CLASS_FIELDS, N_CYL_FIELDS = 6, 6, 2, 6
SIGMA_UM = round(g.DEFAULT_NOISE_SIGMA * 1e6)  # 343 um
SIGMA = SIGMA_UM * 1e-6
MAX_N = 8
GROUPS = ("typical", "extreme")


@dataclass(frozen=True)
class Case:
    name: str
    group: str  # "typical" | "extreme"
    kind: str  # the true reflector: "edge" | "wall" | "none"
    receivers: np.ndarray  # (N, 2) metres, multiples of 1 um
    path: np.ndarray  # (N,) metres, multiples of 1 um
    source: np.ndarray  # (2,) metres, multiples of 1 um
    cyl: bool = False  # the benchmark also runs the cylinder solver on this case

    @property
    def n(self) -> int:
        return len(self.path)


def _um(a) -> np.ndarray:
    return np.round(np.asarray(a, np.float64) * 1e6) / 1e6


def cases(seed: int = 5) -> list[Case]:
    """The fixed case list (same every call)."""
    lay = load_layout()
    P, AX = lay.positions, lay.axes
    rng = np.random.default_rng(seed)
    out: list[Case] = []

    def add(name, group, kind, C, R, S, cyl=False):
        out.append(Case(name, group, kind, _um(C), _um(R), _um(S), cyl))

    def rx(k0, n=3):
        idx = (k0 + np.arange(n) - (n - 1) // 2) % lay.n
        return P[idx], AX[k0]

    # typical: 8 edges and 8 walls at 1..4 m, interleaved so that any prefix is a mix (the
    # SoC test runs only the first few): edge, wall, edge, wall, ... with the source the
    # middle element for pairs 0, 2, 4, 6 and the ring centre for pairs 1, 3, 5, 7
    for i in range(16):
        kind = "edge" if i % 2 == 0 else "wall"
        j = i // 2
        k0 = int(rng.integers(0, lay.n))
        C, ax = rx(k0)
        S = P[k0] if j % 2 == 0 else np.zeros(2)
        r = 1.0 + 3.0 * j / 7.0 + rng.uniform(-0.1, 0.1)
        br = ax + math.radians(rng.uniform(-20.0, 20.0))
        u = np.array([math.cos(br), math.sin(br)])
        if kind == "edge":
            R = g.point_path_lengths((0.35 + r) * u, C, S)
        else:  # the wall 0.35 + r from the ring centre is that minus S.u from the source
            R = g.wall_path_lengths(0.35 + r - float(np.dot(S, u)), br, C, S)
        R = R + rng.normal(0.0, g.DEFAULT_NOISE_SIGMA, R.shape)
        add(f"{kind} {r:.2f} m src={'elem' if j % 2 == 0 else 'centre'}", "typical", kind, C, R, S)

    def edge(k0, n, dist, off_deg, src_elem=True, noise=True):
        C, ax = rx(k0, n)
        S = P[k0] if src_elem else np.zeros(2)
        br = ax + math.radians(off_deg)
        R = g.point_path_lengths((0.35 + dist) * np.array([math.cos(br), math.sin(br)]), C, S)
        if noise:
            R = R + rng.normal(0.0, g.DEFAULT_NOISE_SIGMA, R.shape)
        return C, R, S

    def wall(k0, n, dist, off_deg, src_elem=True, noise=True):
        C, ax = rx(k0, n)
        S = P[k0] if src_elem else np.zeros(2)
        br = ax + math.radians(off_deg)
        d = 0.35 + dist - float(np.dot(S, [math.cos(br), math.sin(br)]))
        R = g.wall_path_lengths(d, br, C, S)
        if noise:
            R = R + rng.normal(0.0, g.DEFAULT_NOISE_SIGMA, R.shape)
        return C, R, S

    add("edge 0.15 m", "extreme", "edge", *edge(3, 3, 0.15, 10.0))
    add("edge 8 m, 40 deg off axis", "extreme", "edge", *edge(7, 3, 8.0, -40.0, src_elem=False))
    add("wall 8 m", "extreme", "wall", *wall(11, 3, 8.0, 5.0))
    add("wall 0.2 m, 45 deg", "extreme", "wall", *wall(15, 3, 0.2, 45.0, src_elem=False))
    add("edge N=2", "extreme", "edge", *edge(19, 2, 2.0, 8.0, noise=False))
    add("edge N=8", "extreme", "edge", *edge(22, 8, 2.5, -12.0, src_elem=False))
    add("wall N=5", "extreme", "wall", *wall(1, 5, 1.5, 15.0))
    C, R, S = edge(9, 4, 2.0, 5.0)
    R[1] += 0.05
    add("edge N=4, 5 cm outlier", "extreme", "none", C, R, S)
    C, R, S = edge(13, 3, 1.0, 0.0)
    R[2] = 0.5 * float(np.linalg.norm(C[2] - S))
    add("path shorter than baseline", "extreme", "none", C, R, S)

    def pillar(k0, dist, radius, off_deg, src_elem=True):
        C, ax = rx(k0, 3)
        S = P[k0] if src_elem else np.zeros(2)
        br = ax + math.radians(off_deg)
        cen = (0.35 + dist + radius) * np.array([math.cos(br), math.sin(br)])
        R = g.cylinder_path_lengths(cen, radius, C, S) + rng.normal(0.0, g.DEFAULT_NOISE_SIGMA, 3)
        return C, R, S

    add("cylinder r=0.15 m at 2 m", "extreme", "cylinder", *pillar(5, 2.0, 0.15, 6.0), cyl=True)
    add("cylinder r=0.5 m at 1 m", "extreme", "cylinder", *pillar(17, 1.0, 0.5, -10.0, src_elem=False), cyl=True)
    return out


# --------------------------------------------------------------------------------------
# C header
# --------------------------------------------------------------------------------------


def c_header(cs: list[Case]) -> str:
    def i32(v):
        return str(int(round(v * 1e6)))

    rows = []
    for c in cs:
        rxs = ", ".join(f"{{{i32(x)}, {i32(y)}}}" for x, y in c.receivers)
        paths = ", ".join(i32(r) for r in c.path)
        rows.append(f"    /* {c.name} */\n    {{{c.n}, {GROUPS.index(c.group)}, {int(c.cyl)}, {{{i32(c.source[0])}, "
                    f"{i32(c.source[1])}}}, {{{rxs}}}, {{{paths}}}}},")
    return (
        "/* Generated by multisonar.tools.geom_cases (python -m multisonar.tools.geom_cases). Do not edit.\n"
        " * Geometry cases for firmware/app/bench_geom.c; lengths in micrometres (robot frame). */\n"
        "#ifndef BENCH_CASES_H\n#define BENCH_CASES_H\n\n#include <stdint.h>\n\n"
        f"#define BENCH_MAGIC 0x{MAGIC:08X}u\n#define BENCH_DONE 0x{DONE:08X}u\n"
        f"#define BENCH_NCASES {len(cs)}\n#define BENCH_MAX_N {MAX_N}\n#define BENCH_SIGMA_UM {SIGMA_UM}\n\n"
        "typedef struct {\n    uint8_t n, group, cyl; /* group 0 typical, 1 extreme; cyl: time the cylinder solver */\n"
        "    int32_t src[2];\n    int32_t rx[BENCH_MAX_N][2];\n    int32_t path[BENCH_MAX_N];\n} bench_case_t;\n\n"
        "static const bench_case_t bench_cases[BENCH_NCASES] = {\n" + "\n".join(rows) + "\n};\n\n#endif\n")


def write_header(path: Path) -> None:
    text = c_header(cases())
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_text() != text:  # stable mtime for make
        path.write_text(text)


# --------------------------------------------------------------------------------------
# Python float64 reference and the decoder
# --------------------------------------------------------------------------------------


def reference(cs: list[Case] | None = None) -> list[dict]:
    """multisonar.geometry on every case (library defaults; classify with sigma = 343 um)."""
    out = []
    for c in cs or cases():
        p = g.solve_point(c.receivers, c.path, c.source)
        w = g.solve_wall(c.receivers, c.path, c.source)
        r = dict(point=dict(valid=p.valid, reason=g.REASONS.index(p.reason), x=p.position[0], y=p.position[1],
                            range=p.range, bearing=p.bearing, residual=p.residual, gdop=p.gdop),
                 wall=dict(valid=w.valid, reason=g.REASONS.index(w.reason), distance=w.distance,
                           normal_angle=w.normal_angle, foot_x=w.foot[0], foot_y=w.foot[1],
                           residual=w.residual, gdop=w.gdop))
        cy = g.solve_cylinder(c.receivers, c.path, c.source) if c.n >= 3 else None
        r["cylinder"] = dict(valid=False, reason=g.BADIN, cx=0.0, cy=0.0, radius=0.0, range=0.0, bearing=0.0,
                             residual=0.0) if cy is None else \
            dict(valid=cy.valid, reason=g.REASONS.index(cy.reason), cx=cy.centre[0], cy=cy.centre[1],
                 radius=cy.radius, range=cy.range, bearing=cy.bearing, residual=cy.residual, gdop=cy.gdop)
        if c.n >= 3:
            k = g.classify_batch(c.receivers, c.path, c.source, noise_sigma=SIGMA)
            kind = int(k.kind[0])
            r["classify"] = dict(kind=3 if kind == 2 else kind, chi2_edge=float(k.chi2[0, 0]),
                                 chi2_wall=float(k.chi2[0, 1]))
        else:
            r["classify"] = dict(kind=3, chi2_edge=0.0, chi2_wall=0.0)
        out.append(r)
    return out


def words_per_field(variant: str) -> int:
    return 2 if variant == "f64" else 1


HEADER_WORDS = 4


def expected_words(variant: str, ncases: int) -> int:
    per_case = 2 + 4 * 3 + (N_POINT_FIELDS + N_WALL_FIELDS + N_CLASS_FIELDS + N_CYL_FIELDS) * words_per_field(variant)
    return HEADER_WORDS + ncases * per_case + 1


def _s32(w: int) -> int:
    return w - (1 << 32) if w & 0x80000000 else w


def words_for_cases(variant: str, k: int) -> int:
    """Words of the header and the first k cases (a run may stop there)."""
    return expected_words(variant, k) - 1


def decode(words: list[int], complete: bool = True) -> dict:
    """Mailbox words -> {variant, overhead, cases: [{point, wall, classify}]} in metres,
    radians and plain numbers (cycles per call under ``cycles``). complete=False accepts a
    stream cut after any whole case (the cases present are decoded)."""
    if len(words) < HEADER_WORDS or words[0] & 0xFFFF0000 != MAGIC:
        raise ValueError(f"not a bench_geom stream (first word {words[:1]})")
    variant = ARITH[words[0] & 0xFF]
    ncases, overhead, ins_overhead = words[1], words[2], words[3]
    if complete:
        if len(words) != expected_words(variant, ncases) or words[-1] != DONE:
            raise ValueError(f"{variant}: {len(words)} words, expected {expected_words(variant, ncases)} "
                             "ending in DONE")
    else:
        per_case = words_for_cases(variant, 1) - HEADER_WORDS
        ncases = min(ncases, (len(words) - HEADER_WORDS) // per_case)
    pos = HEADER_WORDS

    def take():
        nonlocal pos
        pos += 1
        return words[pos - 1]

    def field(what):
        if variant == "f64":
            lo, hi = take(), take()
            return struct.unpack("<d", struct.pack("<II", lo, hi))[0]
        w = take()
        if variant == "f32":
            return struct.unpack("<f", struct.pack("<I", w))[0]
        v = _s32(w)
        return {"len": v * 1e-6, "ang": v * (math.pi / 2 ** 31), "num": v / 65536.0}[what]

    out = []
    for _ in range(ncases):
        prep = dict(cycles=take(), instructions=take())
        cyc, ins, st = take(), take(), take()
        pt = dict(cycles=cyc, instructions=ins, valid=bool(st & 1), reason=(st >> 8) & 0xFF)
        for name, what in zip(("x", "y", "range", "bearing", "residual", "gdop"),
                              ("len", "len", "len", "ang", "len", "num")):
            pt[name] = field(what)
        cyc, ins, st = take(), take(), take()
        wl = dict(cycles=cyc, instructions=ins, valid=bool(st & 1), reason=(st >> 8) & 0xFF)
        for name, what in zip(("distance", "normal_angle", "foot_x", "foot_y", "residual", "gdop"),
                              ("len", "ang", "len", "len", "len", "num")):
            wl[name] = field(what)
        cyc, ins, st = take(), take(), take()
        cl = dict(cycles=cyc, instructions=ins, kind=st & 0xF, accepted=(st >> 4) & 0xF, reason=(st >> 8) & 0xFF,
                  point_reason=(st >> 16) & 0xFF, wall_reason=(st >> 24) & 0xFF,
                  chi2_edge=field("num"), chi2_wall=field("num"))
        cyc, ins, st = take(), take(), take()
        cy = dict(cycles=cyc, instructions=ins, valid=bool(st & 1), reason=(st >> 8) & 0xFF, ran=bool(st & 0x10000))
        for name, what in zip(("cx", "cy", "radius", "range", "bearing", "residual"),
                              ("len", "len", "len", "len", "ang", "len")):
            cy[name] = field(what)
        out.append(dict(prepare=prep, point=pt, wall=wl, classify=cl, cylinder=cy))
    return dict(variant=variant, overhead=overhead, ins_overhead=ins_overhead, cases=out)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def errors(dec: dict, ref: list[dict], cs: list[Case] | None = None) -> list[dict]:
    """Per case: range / bearing error of point and wall (NaN where either side is invalid),
    flag and kind agreement, Python gdop (for the bounds)."""
    cs = cs or cases()
    out = []
    for c, d, r in zip(cs, dec["cases"], ref):
        e = dict(name=c.name, group=c.group)
        for solver, rng_k, ang_k in (("point", "range", "bearing"), ("wall", "distance", "normal_angle")):
            dc, rp = d[solver], r[solver]
            both = dc["valid"] and rp["valid"]
            e[f"{solver}_same_flag"] = dc["valid"] == rp["valid"]
            e[f"{solver}_same_reason"] = dc["reason"] == rp["reason"]
            e[f"{solver}_valid"] = both
            e[f"{solver}_range_m"] = abs(dc[rng_k] - rp[rng_k]) if both else math.nan
            e[f"{solver}_bearing_rad"] = abs(_wrap(dc[ang_k] - rp[ang_k])) if both else math.nan
            e[f"{solver}_scale_m"] = rp[rng_k]
            e[f"{solver}_gdop"] = rp["gdop"]
        e["same_kind"] = d["classify"]["kind"] == r["classify"]["kind"]
        dc, rc = d.get("cylinder"), r["cylinder"]
        e["cylinder_ran"] = bool(dc and dc["ran"])
        if e["cylinder_ran"]:
            both = dc["valid"] and rc["valid"]
            e["cylinder_same_flag"] = dc["valid"] == rc["valid"]
            e["cylinder_same_reason"] = dc["reason"] == rc["reason"]
            e["cylinder_valid"] = both
            e["cylinder_centre_m"] = math.hypot(dc["cx"] - rc["cx"], dc["cy"] - rc["cy"]) if both else math.nan
            e["cylinder_radius_m"] = abs(dc["radius"] - rc["radius"]) if both else math.nan
            e["cylinder_bearing_rad"] = abs(_wrap(dc["bearing"] - rc["bearing"])) if both else math.nan
            e["cylinder_gdop"] = rc.get("gdop", 0.0)
            e["cylinder_scale_m"] = rc["range"] + rc["radius"]
        out.append(e)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--header", type=Path, required=True, help="C header to write (e.g. build/fw/bench_cases.h)")
    a = ap.parse_args(argv)
    write_header(a.header)


if __name__ == "__main__":
    main()
