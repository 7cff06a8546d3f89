"""Worst-case cycles of the per-pulse geometry over random inputs, on the SoC (issue #26).

firmware/app/bench_fix_random.c generates random virtual sensors and random pulses on the core
(consistent points and walls with noise, garbage and extreme path triples), times every
ms_prepare and ms_fix_fast with the SoC cycle timer and reports once at the end: per outcome
(edge / wall / uncertain / declined; prepare: fast path or not) count, min, max, sum and a
histogram, the outcome per input class, the inputs of the worst call of each outcome, and the
impossible answers it found (count + the first one). This module holds the machinery
(build_image, run_random, decode_report, summary, replay_on_host) that
scripts/bench_fw_random.py runs at full size (>= 1e5 fixes: the table for firmware/README.md)
and a small run as a test (SMALL_CALLS fixes on SMALL_SENSORS sensors: ~1.5 min of simulation on
VexRiscv, plus ~0.5 min for the first Verilator build of the "random" variant).

The SoC is ms_soc with the CPU test_ms_soc_geometry.py uses (its tops; VexRiscv: the pinned
standard core with the 16 KiB instruction cache), in Verilator through cocotb
(tests/rtl/tb_ms_soc_random.py), in a build of its own (variant "random": the image path is a
build parameter, so it never touches the geometry tests' build); a lock file keeps two runs
from swapping the image under each other.
"""

from __future__ import annotations

import fcntl
import functools
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cocotb_run import ROOT, run_cocotb, selected_simulator

import test_ms_soc_geometry as tsg

OUTCOMES = ("edge", "wall", "uncertain", "declined")
RETURN_OF = {"edge": 0, "wall": 1, "uncertain": 3, "declined": -1}  # ms_fix_fast's return (MS_FIX_DECLINED -1)
PREP_OUTCOMES = ("fast", "not fast")                   # ms_prepare's return 1 / 0
CLASSES = ("point", "wall", "garbage", "extreme")      # the generator's input classes
BAD_WHAT = {0: "", 1: "return value", 2: "kind != return", 3: "reason", 4: "accepted bits",
            5: "fit valid / reason", 6: "chi2 / thresholds", 7: "fit values", 8: "prepare return"}
RPT_MAGIC, RPT_DONE = 0x52460002, 0x52464E44
DEFAULT_CALLS, DEFAULT_SENSORS, DEFAULT_SEED = 100_000, 1000, 1  # build/fw/bench_fix_random.hex

SMALL_CALLS, SMALL_SENSORS, SMALL_SEED = 2000, 20, 7
# The fast path is bounded by construction (ms_geom_q_fast.c fq_polish: a closed-form start and at most
# three Gauss-Newton passes per fit, nothing else loops on the data). Measured on VexRiscv
# (scripts/bench_fw_random.py): ~6.8 k cycles with one pass per fit, ~1.2 k per further pass;
# the worst of 1e5 random fixes 12,055 (three passes in both fits); with the instruction cache
# emptied before every call (--icache-cold, 1e4 fixes) 15,699. 20,000 is 1.27x that coldest
# worst case and still catches a fall into the general path (>= 1e6 cycles) or a longer loop.
FIX_MAX_CYCLES = 20_000
# ms_prepare (once per sensor, not per pulse): ~30 k cycles (firmware/README.md); 2x
PREPARE_MAX_CYCLES = 65_536


def image_name(calls: int, sensors: int, seed: int, cold: bool = False) -> str:
    """The make target (mk/bench_random.mk) of the image with these parameters."""
    if (calls, sensors, seed, cold) == (DEFAULT_CALLS, DEFAULT_SENSORS, DEFAULT_SEED, False):
        return "bench_fix_random"
    return f"bench_fix_random-{calls}-{sensors}-{seed}{'-cold' if cold else ''}"


def build_image(calls: int, sensors: int, seed: int, cpu: str, cold: bool = False) -> Path:
    """make build/fw/<image_name>.hex; checks, as test_ms_soc_geometry's firmware_hex, that the
    image reaches the registers through their uncached alias (needed on VexRiscv)."""
    if cold and cpu != "vexriscv":
        raise ValueError("cold (FENCE.I before every call) needs VexRiscv's instruction cache")
    return tsg.firmware_hex(image_name(calls, sensors, seed, cold), cpu)


def run_random(calls: int = SMALL_CALLS, sensors: int = SMALL_SENSORS, seed: int = SMALL_SEED,
               cpu: str = tsg.DEFAULT_CPU, cold: bool = False, out: Path | None = None) -> dict:
    """Build the image, run it on the SoC with ``cpu`` and return the decoded report plus
    sim_cycles, sim_wall_s (simulation alone), wall_s (build + run), progress; the raw record
    (words, progress) lands in ``out``."""
    if cpu not in tsg.CPUS:
        raise ValueError(f"unknown CPU {cpu!r}; ms_soc has {tsg.CPUS}")
    wall0 = time.perf_counter()
    hexfile = build_image(calls, sensors, seed, cpu, cold)
    top = tsg.TOPS[cpu]
    build_dir = ROOT / "build" / "sim" / f"{top}-random-{selected_simulator()}"
    build_dir.mkdir(parents=True, exist_ok=True)
    out = out or build_dir / f"{hexfile.stem}.json"
    out.unlink(missing_ok=True)
    tb_sources = [ROOT / "tests/rtl/ms_soc_geometry_tb.sv"]
    if top != "ms_soc_geometry_tb":
        tb_sources.append(ROOT / f"tests/rtl/{top}.sv")
    image = build_dir / "firmware.hex"  # this build's fixed INIT_FILE
    with open(build_dir / "run.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        shutil.copyfile(hexfile, image)
        run_cocotb(top, "tb_ms_soc_random", extra_sources=tb_sources, variant="random",
                   parameters={"INIT_FILE": f'"{image}"'}, icarus_ok=False,
                   extra_env={"RANDOM_OUT": str(out)})
    raw = json.loads(out.read_text())
    dec = decode_report(raw["words"])
    dec.update(cpu=cpu, image=hexfile.stem, sim_cycles=raw["sim_cycles"], sim_wall_s=raw["sim_wall_s"],
               progress=raw["progress"], wall_s=time.perf_counter() - wall0)
    return dec


def decode_report(words: list[int]) -> dict:
    """The report of bench_fix_random.c, in its order:
    header (21): MAGIC, length, seed, calls, sensors, timer overhead, cold, coarse factor,
        fix bin width, fine bins, coarse bins, the same three for prepare, outcomes, classes,
        record words, impossible answers, what the first one violated, sigma (um), path length
        limit (um);
    per fix outcome: count, min, max, sum (lo, hi), histogram (fine bins of the bin width,
        coarse bins coarse-factor times wider, 1 overflow bin);
    outcome counts per input class (classes x outcomes), max cycles per class, max cycles of
        the first fix after a prepare and of the others;
    per prepare outcome (fast, not fast): the same statistics;
    per fix outcome the worst call's record, then the slowest prepare (cycles, return, sensor,
        fix index, sensor), the first impossible answer's record; DONE.
    A record: cycles, return, class, fix index, generator state (lo, hi), sensor (rx elements
    | source at the centre << 24, source x, y, rx x, y x 3), paths x 3 (um, int32)."""
    it = iter(words)

    def take(n: int = 1) -> list[int]:
        return [next(it) for _ in range(n)]

    def s32(w: int) -> int:
        return w - (1 << 32) if w & 0x80000000 else w

    def stat(nbins: int) -> dict:
        cnt, mn, mx, lo, hi = take(5)
        return dict(count=cnt, min=mn if cnt else None, max=mx if cnt else None, sum=lo | hi << 32,
                    hist=np.array(take(nbins + 1), np.int64))

    def sensor() -> dict:
        el, *xy = take(9)
        xy = [s32(v) for v in xy]
        return dict(elems=[el & 0xFF, el >> 8 & 0xFF, el >> 16 & 0xFF], src_at_centre=bool(el >> 24 & 1),
                    src_um=xy[0:2], rx_um=[xy[2:4], xy[4:6], xy[6:8]])

    def record() -> dict:
        cyc, ret, cls, call, st_lo, st_hi = take(6)
        s = sensor()
        return dict(cycles=cyc, ret=s32(ret), cls=CLASSES[cls] if cls < len(CLASSES) else cls, call=call,
                    state=st_lo | st_hi << 32, **s, path_um=[s32(v) for v in take(3)])

    if len(words) < 2 or words[0] != RPT_MAGIC or words[1] != len(words):
        raise ValueError(f"not a complete bench_fix_random report ({len(words)} words)")
    keys = ("magic", "length", "seed", "calls", "sensors", "timer_overhead", "cold", "coarse", "fix_bin",
            "fix_nfine", "fix_ncoarse", "prep_bin", "prep_nfine", "prep_ncoarse", "noutcomes", "nclasses",
            "rec_words", "n_bad", "bad_what", "sigma_um", "len_limit_um")
    dec = dict(zip(keys, take(len(keys))))
    assert dec["noutcomes"] == len(OUTCOMES) and dec["nclasses"] == len(CLASSES) and dec["rec_words"] == 18
    for p in ("fix", "prep"):  # bin edges, the overflow bin's open end left out
        fine, coarse = dec[f"{p}_nfine"], dec[f"{p}_ncoarse"]
        w = dec[f"{p}_bin"]
        dec[f"{p}_edges"] = np.concatenate([np.arange(fine + 1) * w, fine * w + np.arange(1, coarse + 1) * w * dec["coarse"]])
        dec[f"{p}_nbins"] = fine + coarse
    dec["fix"] = {o: stat(dec["fix_nbins"]) for o in OUTCOMES}
    dec["class_outcomes"] = {c: dict(zip(OUTCOMES, take(len(OUTCOMES)))) for c in CLASSES}
    dec["class_max"] = dict(zip(CLASSES, take(len(CLASSES))))
    dec["max_after_prepare"], dec["max_steady"] = take(2)
    dec["prepare"] = {o: stat(dec["prep_nbins"]) for o in PREP_OUTCOMES}
    dec["worst"] = {o: record() for o in OUTCOMES}
    cyc, ret, idx, call = take(4)
    dec["worst_prepare"] = dict(cycles=cyc, ret=s32(ret), sensor_index=idx, call=call, **sensor())
    first_bad = record()
    dec["first_bad"] = first_bad if dec["n_bad"] else None
    dec["bad_what"] = BAD_WHAT.get(dec["bad_what"], dec["bad_what"])
    if take(1) != [RPT_DONE]:
        raise ValueError("report does not end with DONE (the firmware counted a different length)")
    return dec


def _hist_quantile(hist: np.ndarray, edges: np.ndarray, q: float, lo: int, hi: int):
    """Cycles at quantile q from a histogram (bin centre, clipped to [lo, hi]); None when it
    falls in the overflow bin."""
    c = np.cumsum(hist)
    if c[-1] == 0:
        return None
    b = int(np.searchsorted(c, q * c[-1]))
    if b >= len(hist) - 1:
        return None
    return int(min(max((edges[b] + edges[b + 1]) // 2, lo), hi))


def summary(dec: dict) -> list[dict]:
    """Table rows: ms_fix_fast per outcome and all, ms_prepare per outcome and all: calls,
    median / p99 (histogram bins: +- half a bin), mean, min, max; for the fix the calls over
    the real-time budget (test_ms_soc_geometry.CYCLE_BUDGET, 7,500 cycles per pulse)."""
    rows = []
    for path, outs, edges in (("ms_fix_fast", OUTCOMES, dec["fix_edges"]), ("ms_prepare", PREP_OUTCOMES, dec["prep_edges"])):
        st = dec["fix" if path == "ms_fix_fast" else "prepare"]
        groups = [(o, [st[o]]) for o in outs] + [("all", [st[o] for o in outs])]
        for name, sts in groups:
            sts = [s for s in sts if s["count"]]
            n = sum(s["count"] for s in sts)
            if not n:
                rows.append(dict(path=path, outcome=name, calls=0))
                continue
            hist = sum(s["hist"] for s in sts)
            lo, hi = min(s["min"] for s in sts), max(s["max"] for s in sts)
            rows.append(dict(path=path, outcome=name, calls=n, min=lo, max=hi,
                             mean=sum(s["sum"] for s in sts) / n,
                             median=_hist_quantile(hist, edges, 0.5, lo, hi),
                             p99=_hist_quantile(hist, edges, 0.99, lo, hi),
                             p999=_hist_quantile(hist, edges, 0.999, lo, hi),
                             hist_range=int(edges[-1]),
                             # calls over the per-pulse budget (bins whose centre is above it: +- half a bin)
                             over_budget=int(hist[:-1][(edges[:-1] + edges[1:]) / 2 > tsg.CYCLE_BUDGET].sum() + hist[-1])
                             if path == "ms_fix_fast" else None))
    return rows


@functools.cache
def _host_q():
    """The Q variant's host build (firmware/Makefile host-libs), through test_fw_geometry's wrapper."""
    sys.path.insert(0, str(ROOT / "tests"))
    import test_fw_geometry as tfw

    subprocess.run(["make", "-s", "-C", str(ROOT / "firmware"), "host-libs"], check=True)
    return tfw.FwGeom("q")


def replay_on_host(rec: dict) -> dict:
    """Replay one record's inputs through the host build of the same C (ms_classify = ms_prepare
    + ms_fix; the sensor's options are the defaults there too): the kind, and whether the fast
    path answered (host builds count it). On the SoC a fix the fast path answered must give
    that kind; a declined one must take the general path."""
    f = _host_q()
    C = np.array(rec["rx_um"], float)[None] * 1e-6
    R = np.array(rec["path_um"], float)[None] * 1e-6
    S = np.array(rec["src_um"], float)[None] * 1e-6
    f.stats()
    kind = int(f.classify(C, R, S, sigma=343e-6)["kind"][0])
    fast, general = f.stats()
    return dict(kind=kind, fast=fast == 1 and general == 0)


def replay_agrees(rec: dict) -> bool:
    r = replay_on_host(rec)
    return (not r["fast"]) if rec["ret"] == RETURN_OF["declined"] else (r["fast"] and r["kind"] == rec["ret"])


@pytest.mark.sim
def test_random_fixes_bounded_on_soc():
    """SMALL_CALLS random fixes on the SoC (default CPU): every answer possible, every call
    counted once, each outcome seen, the worst fix and prepare within their bounds, and the
    worst inputs replay to the same answer on the host build."""
    dec = run_random(SMALL_CALLS, SMALL_SENSORS, SMALL_SEED)
    assert (dec["calls"], dec["sensors"], dec["seed"]) == (SMALL_CALLS, SMALL_SENSORS, SMALL_SEED)
    assert dec["n_bad"] == 0, f"impossible answer ({dec['bad_what']}): {dec['first_bad']}"
    fix, prep = dec["fix"], dec["prepare"]
    assert sum(s["count"] for s in fix.values()) == SMALL_CALLS
    assert sum(sum(c.values()) for c in dec["class_outcomes"].values()) == SMALL_CALLS
    assert sum(s["count"] for s in prep.values()) == SMALL_SENSORS
    for s in list(fix.values()) + list(prep.values()):
        assert int(s["hist"].sum()) == s["count"]
        assert s["count"] == 0 or 0 < s["min"] <= s["max"]
    # the generator reaches every outcome, and consistent points / walls mostly give a kind
    assert all(fix[o]["count"] > 0 for o in OUTCOMES), {o: fix[o]["count"] for o in OUTCOMES}
    co = dec["class_outcomes"]
    assert co["point"]["edge"] > co["point"]["wall"] and co["wall"]["wall"] > co["wall"]["edge"], co
    worst = max(s["max"] for s in fix.values() if s["count"])
    print(f"{SMALL_CALLS} random fixes on {dec['cpu']}: worst {worst} cycles "
          f"({max(OUTCOMES, key=lambda o: fix[o]['max'] or 0)}), prepare worst {dec['worst_prepare']['cycles']}; "
          f"{dec['sim_cycles']} cycles in {dec['sim_wall_s']:.0f} s")
    assert worst < FIX_MAX_CYCLES, dec["worst"]
    assert prep["not fast"]["count"] == 0, "ms_prepare declined the fast path for a ring sensor"
    assert dec["worst_prepare"]["cycles"] < PREPARE_MAX_CYCLES, dec["worst_prepare"]
    for o in OUTCOMES:
        w = dec["worst"][o]
        assert w["cycles"] == fix[o]["max"] and w["ret"] == RETURN_OF[o]
        assert replay_agrees(w), (o, w, replay_on_host(w))
