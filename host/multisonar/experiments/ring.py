"""Full-ring refresh (issue #27): 8 virtual sensors over all 24 elements in a static room.

The ring: the ``ring8`` sensor set of the maximum-load demo (:data:`multisonar.demo.RING8_SENSORS`):
sensor k transmits on element 3k+1 and listens on 3k, 3k+1, 3k+2, so the 24 receivers (24
directions, 15 deg apart) are each one sensor's, and each transmitter's crosstalk neighbours
are its own receivers: no two sensors share an element. The room: a circular wall centred
on the robot, ``distance_m`` in front of every element (radius = ring radius + distance), as
:class:`multisonar.fastfiring.SyntheticEchoSource` echoes: every receiver hears every firing
at its own geometric path (the transmitter's element to the wall's specular point to the
receiver: the on-axis receiver at 2 d, its two neighbours 15 deg off at a few mm more), with
the firing element's ring-down (1.25 ms, inside the 1.5 ms dead zone), no noise. The sensors
start together and stay in lockstep, so another sensor's echo of the same wall lands with the
sensor's own.

Backend: the tick-exact golden model (:class:`multisonar.fastfiring.FastFiringModel`) with the
device's decision lead P (:data:`multisonar.constants.DEVICE_DECISION_LEAD`), i.e. the RTL's
behaviour, for ``DURATION_S`` of sonar time per (distance, order); orders 1..``MAX_ORDER`` of
this build (:data:`multisonar.schedule.MAX_ORDER`, read when the experiment runs). Every
sensor's max range is ``MAX_RANGE_M`` (6 m, so 5.7 m is inside it: T_E + T_N <= MAX_TOF).

Metrics, all from the event-FIFO word stream (pulse records and first echoes in a window; the
same function reads the model's ``RunResult.words`` and the RTL's event log), over the tracking
phase: from the first tracking pulse of the last sensor to settle (pulses issued from then on)
to 1 ms before the end of the run. A *sample* of direction r is a first echo in a window of
receiver r, at tick t0 + ToF.

* ``full_ring_hz`` (the headline): complete ring sweeps per second. A sweep ends at the tick
  by which every one of the 24 directions has a sample newer than the previous sweep's end;
  the rate is 1 / mean interval between sweep ends. It is the rate at which complete sets of
  all 24 directions are measured, never more than the slowest direction's rate.
* ``dir_min_hz`` / ``dir_mean_hz``: per-direction sample rate (1 / mean interval between a
  direction's samples), the slowest and the mean over the 24 directions.
* ``worst_gap_ms``: the longest interval between two samples of one direction (any direction
  is at most this old: the guaranteed refresh is 1 / worst gap).
* ``pulse_hz``: per-sensor pulse rate (mean over the 8 sensors; ``pulse_min_hz`` the slowest).
* ``analytic_hz``: 1 / T_s from the contract's integer formula (docs/fast_firing.md
  section 4.3) for the sensors' echo ToFs, at the highest feasible order n <= the order asked.

Goal (issue #27): full-ring refresh >= 100 Hz at 2 m and >= 60 Hz at 5.7 m; anchor: Browne &
Kleeman's FPGA sonar ring, 60 Hz for the full 360 degrees at 5.7 m with two pulses in flight.
With ``rtl=True`` the two goal distances at the highest order also run on the RTL scheduler
(ms_sched_uc in Verilator through cocotb, tests/rtl/tb_bench_ring.py, the machinery of
scripts/bench_rtl_sample_rate.py): its event words are compared with the golden model's word
for word, its figures computed from its own words by the same function, and its engine's
headroom reported (largest lag behind real time; overrun_o when it exceeds LEAD / 2).
"""

from __future__ import annotations

import math
import sys
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import DEVICE_DECISION_LEAD, TICK_HZ, speed_of_sound
from .common import ExperimentError, ExperimentResult, md_table, run_scheduler_bench
from .executor import run_sweep

DISTANCES = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 5.7]
DISTANCES_QUICK = [2.0, 5.7]
#: issue #27's goal: full-ring refresh (Hz) at a distance (m)
GOALS_HZ = {2.0: 100.0, 5.7: 60.0}
#: Browne & Kleeman's FPGA sonar ring (the issue's anchor): full 360 deg at 60 Hz at 5.7 m, 2 pulses in flight
ANCHOR = {"who": "Browne & Kleeman, FPGA sonar ring", "distance_m": 5.7, "full_ring_hz": 60.0, "pulses_in_flight": 2}
MAX_RANGE_M = 6.0
DURATION_S = 0.4
DURATION_QUICK_S = 0.25
RINGDOWN_TICKS = 60_000  # 1.25 ms of ring-down on each firing element (inside T_dead = 1.5 ms)
#: samples and pulses in the last CUT_TICKS of a run are not counted (the RTL writes a word a
#: few ticks after the model's logical tick; both are cut at the same place)
CUT_TICKS = TICK_HZ // 1000
N_DIRECTIONS = 24
#: the two arrangements of 8 sensors over the 24 elements that the checks compare
ARRANGEMENTS = {
    "ring8": "tx 3k+1 alone, rx 3k..3k+2 (the demo's ring8 set; the transmitter's crosstalk neighbours are "
             "its own receivers)",
    "ring8-phased": "tx 3k..3k+2 phased (virtual source at the robot origin), rx 3k..3k+2",
}


def orders() -> list[int]:
    """Orders swept: 1..MAX_ORDER of this build (read now, so a larger MAX_ORDER is picked up)."""
    from .. import schedule

    return list(range(1, schedule.MAX_ORDER + 1))


def ring_sensors(order: int, arrangement: str = "ring8", max_range_m: float = MAX_RANGE_M) -> list[Any]:
    """The 8 virtual sensors of an arrangement (:data:`ARRANGEMENTS`), all at ``order``."""
    from ..demo import RING8_SENSORS
    from ..schedule import VirtualSensor

    if arrangement == "ring8":
        return [VirtualSensor(name, tx=tx, rx=rx, order=order, max_range_m=max_range_m)
                for name, tx, rx in RING8_SENSORS]
    if arrangement == "ring8-phased":
        return [VirtualSensor(f"ring{k}", tx=[3 * k, 3 * k + 1, 3 * k + 2], rx=[3 * k, 3 * k + 1, 3 * k + 2],
                              order=order, max_range_m=max_range_m, source=(0.0, 0.0)) for k in range(8)]
    raise ValueError(f"unknown arrangement {arrangement!r}; known: {', '.join(ARRANGEMENTS)}")


def room_ranges(layout: Any, sensors: list[Any], distance_m: float) -> dict[int, float]:
    """One-way range (m, from the virtual source, as SyntheticEchoSource takes it) of each
    receiver's echo from a circular wall centred on the robot, ``distance_m`` in front of the
    elements: half the shortest path transmitter -> wall -> receiver. A single transmitter
    reflects specularly at the point of the wall that minimises the path (searched on the arc
    between the two elements); a group phased from the robot origin sends a circular wave that
    the concentric wall returns along the radius."""
    pos = np.asarray(layout.positions, float)
    radius = float(np.mean(np.linalg.norm(pos, axis=1))) + float(distance_m)
    out: dict[int, float] = {}
    for s in sensors:
        tx = [int(e) for e in s.tx]
        for r in (int(e) for e in s.rx):
            pr = pos[r]
            if len(tx) == 1:
                pt = pos[tx[0]]
                a0, a1 = math.atan2(pt[1], pt[0]), math.atan2(pr[1], pr[0])
                da = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
                phi = a0 + np.linspace(0.0, da, 4001)
                q = radius * np.stack([np.cos(phi), np.sin(phi)], axis=1)
                path = float(np.min(np.linalg.norm(q - pt, axis=1) + np.linalg.norm(q - pr, axis=1)))
            else:
                src = np.asarray(s.source, float)
                if np.linalg.norm(src) > 1e-9:
                    raise ValueError("room_ranges: a phased group's virtual source must be the robot origin")
                path = radius + (radius - float(np.linalg.norm(pr))) - float(np.min(np.linalg.norm(pos[tx], axis=1)))
            out[r] = path / 2.0
    return out


def ring_source(distance_m: float, arrangement: str = "ring8", temperature_c: float = 20.0) -> Any:
    """The room's echoes for the arrangement's receivers (a fresh source: RTL and model each take one)."""
    from ..fastfiring import SyntheticEchoSource
    from ..layout import load_layout

    ranges = room_ranges(load_layout(), ring_sensors(1, arrangement), distance_m)
    return SyntheticEchoSource(ranges, temperature_c=temperature_c, ringdown_ticks=RINGDOWN_TICKS)


def ring_metrics(words: list[int], start_tick: int, duration_ticks: int, n_sensors: int = 8,
                 n_directions: int = N_DIRECTIONS) -> dict[str, Any]:
    """The refresh figures (module docstring) from an event-FIFO word stream of a run that
    started at ``start_tick`` and lasted ``duration_ticks``."""
    from ..fastfiring import PulseStart, ToFEvent, unpack_word

    end = start_tick + duration_ticks - CUT_TICKS
    last_t0 = start_tick
    t0_of: dict[tuple[int, int], tuple[int, bool]] = {}
    pulses: dict[int, list[tuple[int, bool]]] = {s: [] for s in range(n_sensors)}
    raw: list[tuple[int, int, int]] = []  # (sample tick, rx, pulse t0)
    for w in words:
        rec = unpack_word(int(w))
        if isinstance(rec, PulseStart):
            t0 = last_t0 + (((rec.t0 - last_t0) + (1 << 31)) & 0xFFFFFFFF) - (1 << 31)  # unwrap the 32-bit t0
            last_t0 = t0
            t0_of[(rec.sensor, rec.pulse_id & 0xFF)] = (t0, rec.init_ping)
            pulses.setdefault(rec.sensor, []).append((t0, rec.init_ping))
        elif isinstance(rec, ToFEvent) and rec.sample:
            hit = t0_of.get((rec.sensor, rec.seq))
            if hit is not None:
                raw.append((hit[0] + rec.tof, rec.rx, hit[0]))
    firsts = [next((t for t, init in p if not init), None) for p in pulses.values()]
    nan = float("nan")
    out: dict[str, Any] = {"full_ring_hz": nan, "dir_min_hz": nan, "dir_mean_hz": nan, "worst_gap_ms": nan,
                           "pulse_hz": nan, "pulse_min_hz": nan, "directions": 0, "sweeps": 0, "samples": 0,
                           "init_after_start": 0, "track_start_tick": -1}
    if any(f is None for f in firsts):
        return out
    t_a = max(f for f in firsts if f is not None)
    out["track_start_tick"] = int(t_a - start_tick)
    out["init_after_start"] = int(sum(init for p in pulses.values() for t, init in p if t_a <= t < end))
    per_dir: dict[int, list[int]] = {}
    for tick, rx, t0 in raw:
        if t0 >= t_a and tick < end:
            per_dir.setdefault(rx, []).append(tick)
    out["samples"] = int(sum(len(v) for v in per_dir.values()))
    rates, gaps = [], []
    for rx in range(n_directions):
        ticks = sorted(per_dir.get(rx, []))
        if len(ticks) >= 2:
            d = np.diff(ticks)
            rates.append(TICK_HZ / float(np.mean(d)))
            gaps.append(int(d.max()))
        else:
            rates.append(0.0)
    out["directions"] = int(sum(len(per_dir.get(rx, [])) >= 2 for rx in range(n_directions)))
    out["dir_min_hz"] = float(min(rates))
    out["dir_mean_hz"] = float(np.mean(rates))
    if out["directions"] == n_directions:
        out["worst_gap_ms"] = max(gaps) / TICK_HZ * 1e3
    # complete ring sweeps: samples of one tick count together
    by_tick: dict[int, set[int]] = {}
    for rx, ticks in per_dir.items():
        for t in ticks:
            by_tick.setdefault(t, set()).add(rx)
    seen: set[int] = set()
    ends: list[int] = []
    for t in sorted(by_tick):
        seen |= by_tick[t]
        if len(seen) >= n_directions:
            ends.append(t)
            seen = set()
    out["sweeps"] = len(ends)
    if len(ends) >= 2:
        out["full_ring_hz"] = (len(ends) - 1) * TICK_HZ / float(ends[-1] - ends[0])
    prates = []
    for p in pulses.values():
        t0s = [t for t, init in p if t_a <= t < end and not init]
        prates.append((len(t0s) - 1) * TICK_HZ / float(t0s[-1] - t0s[0]) if len(t0s) >= 2 else 0.0)
    out["pulse_hz"] = float(np.mean(prates))
    out["pulse_min_hz"] = float(min(prates))
    return out


def analytic(distance_m: float, order: int, arrangement: str = "ring8", temperature_c: float = 20.0) -> dict[str, Any]:
    """1 / T_s of the contract's integer formula for the sensors' echo ToFs (every sensor of the
    ring sees the same ones): the slowest sensor's period at its highest feasible order."""
    from ..layout import load_layout
    from ..schedule import Schedule, effective_order, pulse_period

    layout = load_layout()
    sensors = ring_sensors(order, arrangement)
    src = ring_source(distance_m, arrangement, temperature_c)
    periods, ns = [], []
    for cfg in Schedule(layout, sensors, temperature_c=temperature_c).validate():
        lo, hi = cfg.te_limits()
        te = [min(max(src.tof_ticks(src.ranges[int(r)][0], 0), lo), hi) for r in cfg.rx]
        n = effective_order(cfg.order, min(te), max(te), cfg.t_v, cfg.t_n, cfg.blank)
        periods.append(pulse_period(n, min(te), max(te), cfg.t_v, cfg.t_n, cfg.blank))
        ns.append(n)
    return {"analytic_hz": TICK_HZ / max(periods), "order_analytic": int(min(ns))}


def measure_ring(distance_m: float, order: int, arrangement: str = "ring8", duration_s: float = DURATION_S,
                 temperature_c: float = 20.0, decision_lead: int = DEVICE_DECISION_LEAD) -> dict[str, Any]:
    """One (distance, order) point on the golden model (with the device's decision lead, unless
    another is given)."""
    from ..fastfiring import FastFiringModel
    from ..layout import load_layout
    from ..schedule import Schedule

    sensors = ring_sensors(order, arrangement)
    model = FastFiringModel(Schedule(load_layout(), sensors, temperature_c=temperature_c),
                            ring_source(distance_m, arrangement, temperature_c), decision_lead=decision_lead)
    dur = int(round(duration_s * TICK_HZ))
    res = model.run(dur)
    m = ring_metrics(res.words, 0, dur, n_sensors=len(sensors))
    t_a = m["track_start_tick"]
    used = sorted({p.order for p in res.pulses if not p.init and t_a >= 0 and p.t0 >= t_a})
    m["order_used"] = int(max(used)) if used else -1
    m["orders_used"] = used
    m["pulses"] = len(res.pulses)
    m["words"] = len(res.words)
    return m


def run(executor: Executor, *, quick: bool = False, rtl: bool = False, temperature_c: float = 20.0,
        progress: bool = True) -> ExperimentResult:
    from ..layout import load_layout
    from ..schedule import MAX_ORDER, interlace_limit_s

    layout = load_layout()
    c = speed_of_sound(temperature_c)
    t_dead = layout.transducer.ring_down_s
    sensors0 = ring_sensors(1)
    t_v, t_n = float(sensors0[0].t_v), float(sensors0[0].t_n)
    limit = 1.0 / interlace_limit_s(t_dead_s=t_dead, t_v_s=t_v, t_n_s=t_n)
    ords = orders()
    dists = DISTANCES_QUICK if quick else DISTANCES
    duration = DURATION_QUICK_S if quick else DURATION_S
    tasks = [{"distance_m": d, "order": n, "duration_s": duration, "temperature_c": temperature_c}
             for d in dists for n in ords]
    # the arrangement check: the other 8-sensor arrangement at the goal distances, highest order
    alt = [{"distance_m": d, "order": MAX_ORDER, "arrangement": "ring8-phased", "duration_s": duration,
            "temperature_c": temperature_c} for d in GOALS_HZ]
    meas = run_sweep(executor, measure_ring, tasks + alt, label="ring", progress=progress)
    rows: list[dict[str, Any]] = []
    for task, m in zip(tasks, meas):
        d, n = task["distance_m"], task["order"]
        ana = analytic(d, n, temperature_c=temperature_c)
        goal = GOALS_HZ.get(d, float("nan"))
        rows.append({"distance_m": d, "t_e_ms": 2 * d / c * 1e3, "order": n, "order_used": m["order_used"],
                     "full_ring_hz": m["full_ring_hz"], "dir_min_hz": m["dir_min_hz"], "dir_mean_hz": m["dir_mean_hz"],
                     "worst_gap_ms": m["worst_gap_ms"], "pulse_hz": m["pulse_hz"], "pulse_min_hz": m["pulse_min_hz"],
                     "analytic_hz": ana["analytic_hz"], "order_analytic": ana["order_analytic"],
                     "directions": m["directions"], "sweeps": m["sweeps"], "init_after_start": m["init_after_start"],
                     "interlace_limit_hz": limit, "goal_hz": goal,
                     "goal_met": (bool(m["full_ring_hz"] >= goal) if math.isfinite(goal) else None),
                     "anchor_hz": ANCHOR["full_ring_hz"] if d == ANCHOR["distance_m"] else float("nan"),
                     "rtl_full_ring_hz": float("nan"), "rtl_identical": None, "rtl_overrun": None})
    arrangements = []
    for task, m in zip(alt, meas[len(tasks):]):
        base = next(r for r in rows if r["distance_m"] == task["distance_m"] and r["order"] == task["order"]) \
            if task["distance_m"] in dists else None
        arrangements.append({"distance_m": task["distance_m"], "order": task["order"],
                             "ring8_hz": base["full_ring_hz"] if base else float("nan"),
                             "phased_hz": m["full_ring_hz"], "phased_order_used": m["order_used"],
                             "phased_directions": m["directions"]})

    rtl_rows: list[dict[str, Any]] = []
    rtl_note = "RTL: not run (add --rtl; needs Verilator)."
    if rtl:
        cases = [(d, MAX_ORDER) for d in GOALS_HZ]
        if progress:
            print(f"  ring: RTL scheduler, {len(cases)} cases (a Verilator build the first time)", file=sys.stderr)
        rtl_rows = rtl_ring(cases, duration, temperature_c)
        for rr in rtl_rows:
            rr.update({f"rtl_{k}": v for k, v in ring_metrics(rr["rtl_words"], rr["e0"], rr["duration_ticks"]).items()})
            for r in rows:
                if r["distance_m"] == rr["distance_m"] and r["order"] == rr["order"]:
                    r["rtl_full_ring_hz"] = rr["rtl_full_ring_hz"]
                    same = all(_same(rr[f"rtl_{k}"], r[k]) for k in ("full_ring_hz", "dir_min_hz", "dir_mean_hz",
                                                                      "worst_gap_ms", "pulse_hz"))
                    r["rtl_identical"] = bool(rr["identical"] and same)
                    r["rtl_overrun"] = bool(rr["overrun"])
                    rr["figures_equal"] = same
        rtl_note = ("RTL: ms_sched_uc in Verilator (cocotb, tests/rtl/tb_bench_ring.py; the same 8 sensors, "
                    "the same echoes driven on its 24 inputs), compared with the golden model started at the same "
                    "tick: " + "; ".join(
                        f"{r['distance_m']:g} m / order {r['order']}: {r['n_words']} FIFO words "
                        f"{'identical' if r['identical'] else 'DIFFERENT (' + r['mismatch'] + ')'}, "
                        f"figures from the RTL's words {'equal' if r.get('figures_equal') else 'NOT equal'} "
                        f"(full ring {r['rtl_full_ring_hz']:.2f} Hz), engine lag max {r['lag_max']} ticks"
                        + (f" > LEAD/2 = {DEVICE_DECISION_LEAD // 2}: **overrun** (overrun_o set: the engine broke "
                           "its timing contract, although no trigger came late here)" if r["overrun"] else
                           f" <= LEAD/2 = {DEVICE_DECISION_LEAD // 2}, no overrun") for r in rtl_rows) + ".")

    # headline: the goal distances
    goals = []
    for d, g in GOALS_HZ.items():
        at = [r for r in rows if r["distance_m"] == d]
        if not at:
            continue
        top = next(r for r in at if r["order"] == MAX_ORDER)  # the fastest (falls back where infeasible)
        meets = [r["order"] for r in at if r["goal_met"]]
        rr = next((x for x in rtl_rows if x["distance_m"] == d), None)
        goals.append({"distance_m": d, "goal_hz": g, "order": MAX_ORDER,
                      "order_used": top["order_used"], "full_ring_hz": top["full_ring_hz"],
                      "dir_min_hz": top["dir_min_hz"], "dir_mean_hz": top["dir_mean_hz"],
                      "worst_gap_ms": top["worst_gap_ms"], "pulse_hz": top["pulse_hz"],
                      "directions": top["directions"], "lowest_order_meeting_goal": min(meets) if meets else None,
                      "anchor_hz": ANCHOR["full_ring_hz"] if d == ANCHOR["distance_m"] else None,
                      "goal_met": bool(top["goal_met"]),
                      "rtl_full_ring_hz": rr["rtl_full_ring_hz"] if rr else None,
                      "rtl_identical": (bool(rr["identical"] and rr.get("figures_equal")) if rr else None),
                      "rtl_overrun": (bool(rr["overrun"]) if rr else None),
                      "rtl_lag_max_ticks": (int(rr["lag_max"]) if rr else None)})
    goal_met = bool(goals) and all(g["goal_met"] for g in goals)

    def cell_hz(v: Any) -> str:
        return "-" if v is None or not math.isfinite(float(v)) else f"{float(v):.1f}"

    head_rows = [{"d": g["distance_m"], "goal": f">= {g['goal_hz']:.0f}", "anchor": cell_hz(g["anchor_hz"]),
                  "order": f"{g['order']} [{g['order_used']}]", "ring": g["full_ring_hz"],
                  "dir": f"{g['dir_min_hz']:.1f} / {g['dir_mean_hz']:.1f}", "gap": g["worst_gap_ms"],
                  "pulse": g["pulse_hz"], "low": "-" if g["lowest_order_meeting_goal"] is None
                  else str(g["lowest_order_meeting_goal"]),
                  "met": "yes" if g["goal_met"] else "**no**",
                  "rtl": ("-" if g["rtl_identical"] is None else
                          f"{g['rtl_full_ring_hz']:.1f} ({'= model' if g['rtl_identical'] else 'DIFFERS'}"
                          f"{'; engine overrun' if g['rtl_overrun'] else ''})")}
                 for g in goals]
    head_cols = [("d", "distance (m)"), ("goal", "goal (Hz)"), ("anchor", "B&K anchor (Hz)"),
                 ("order", "order [used]"), ("ring", "full-ring refresh (Hz)"),
                 ("dir", "per-direction min / mean (Hz)"), ("gap", "worst gap (ms)"),
                 ("pulse", "per-sensor pulse rate (Hz)"), ("low", "lowest order meeting goal"), ("met", "goal met"),
                 ("rtl", f"RTL, order {MAX_ORDER} (Hz)")]
    wide = []
    for d in dists:
        line: dict[str, Any] = {"d": d, "te": 2 * d / c * 1e3}
        for r in rows:
            if r["distance_m"] == d:
                cell = f"{cell_hz(r['full_ring_hz'])} [{r['order_used']}]"
                if math.isfinite(r["rtl_full_ring_hz"]):
                    cell += f" / RTL {r['rtl_full_ring_hz']:.1f}"
                line[f"o{r['order']}"] = cell
                line[f"a{r['order']}"] = r["analytic_hz"]
        wide.append(line)
    wide_cols = [("d", "d (m)"), ("te", "T_E (ms)")] + [(f"o{n}", f"order {n} [used]") for n in ords]
    detail_cols = [("distance_m", "d (m)"), ("order", "order"), ("order_used", "used"),
                   ("full_ring_hz", "full ring (Hz)"), ("dir_min_hz", "dir min (Hz)"),
                   ("dir_mean_hz", "dir mean (Hz)"), ("worst_gap_ms", "worst gap (ms)"),
                   ("pulse_hz", "pulse rate (Hz)"), ("analytic_hz", "1/T_s (Hz)"), ("directions", "directions"),
                   ("init_after_start", "init pings")]
    arr_rows = [{"d": a["distance_m"], "n": a["order"], "a": a["ring8_hz"], "b": a["phased_hz"],
                 "bu": a["phased_order_used"], "bd": a["phased_directions"]} for a in arrangements]
    max_dev = max((abs(r["full_ring_hz"] / r["analytic_hz"] - 1) for r in rows if math.isfinite(r["full_ring_hz"])),
                  default=float("nan"))
    ok_dirs = all(r["directions"] == N_DIRECTIONS for r in rows)
    verdict = ("**Goal met** at both distances" if goal_met else
               "**Goal NOT met**: " + "; ".join(
                   f"{g['distance_m']:g} m: {g['full_ring_hz']:.1f} Hz < {g['goal_hz']:.0f} Hz"
                   for g in goals if not g["goal_met"]))
    md = "\n".join([
        f"# Full-ring refresh: 8 virtual sensors, all 24 directions, static room (orders 1..{MAX_ORDER})", "",
        "Golden model (tick-exact scheduler, decision lead P = "
        f"{DEVICE_DECISION_LEAD} ticks as the device), the `ring8` sensors: sensor k transmits on element 3k+1 "
        "and listens on 3k..3k+2, so every one of the 24 directions (15 deg apart) is one receiver's; a circular "
        "wall at distance d in front of every element (synthetic echoes at each receiver's geometric path, "
        f"ring-down, no noise); max range {MAX_RANGE_M:g} m, T_dead = {t_dead * 1e3:.2f} ms, "
        f"T_V = T_N = {t_v * 1e3:.1f} ms, {temperature_c:g} degC (c = {c:.1f} m/s); {duration:g} s of sonar time "
        "per point, measured over the tracking phase.", "",
        "Full-ring refresh = complete sweeps of all 24 directions per second (a sweep ends when every direction has "
        "a sample newer than the previous sweep's end; 1 / mean interval between sweep ends). Per direction: "
        "1 / mean interval between its samples (min and mean over the 24). Worst gap: the longest interval "
        "between two samples of one direction. Goal (issue #27): "
        + ", ".join(f">= {g:g} Hz at {d:g} m" for d, g in GOALS_HZ.items())
        + f"; anchor: Browne & Kleeman's FPGA ring, {ANCHOR['full_ring_hz']:g} Hz for the full 360 deg at "
        f"{ANCHOR['distance_m']:g} m with {ANCHOR['pulses_in_flight']} pulses in flight.", "",
        md_table(head_cols, head_rows, {"ring": ".1f", "gap": ".2f", "pulse": ".1f"}), "",
        verdict + f" with MAX_ORDER = {MAX_ORDER}.", "",
        "Sweep: full-ring refresh (Hz) [order used]:", "",
        md_table(wide_cols, wide, {"d": ".2f", "te": ".2f"}), "",
        f"Every point: {'all 24 directions measured' if ok_dirs else 'NOT all 24 directions measured'}; "
        f"largest |full ring / (1/T_s) - 1| = {max_dev:.2%} (1/T_s from the contract's integer formula); "
        f"interlace limit {limit:.0f} Hz. The sensors run in lockstep (no element shared, the same echoes), so "
        "full ring = per-direction rate = per-sensor pulse rate.", "",
        "All points:", "",
        md_table(detail_cols, rows, {"distance_m": ".2f", "full_ring_hz": ".2f", "dir_min_hz": ".2f",
                                     "dir_mean_hz": ".2f", "worst_gap_ms": ".2f", "pulse_hz": ".2f",
                                     "analytic_hz": ".2f"}), "",
        f"Arrangement check (order {MAX_ORDER}): " + ARRANGEMENTS["ring8"] + " against "
        + ARRANGEMENTS["ring8-phased"] + ":", "",
        md_table([("d", "d (m)"), ("n", "order"), ("a", "ring8 (Hz)"), ("b", "ring8-phased (Hz)"),
                  ("bu", "phased: used"), ("bd", "phased: directions")], arr_rows,
                 {"d": ".2f", "a": ".1f", "b": ".1f"}), "",
        rtl_note, ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        from ..schedule import analytic_period_s as ap

        dd = np.linspace(min(dists), max(dists), 200)
        fig, ax = plt.subplots(figsize=(9, 4.8))
        for n in ords:
            ax.plot(dd, [1 / ap(x, n, t_dead_s=t_dead, t_v_s=t_v, t_n_s=t_n, c=c) for x in dd], lw=1,
                    label=f"order {n} (Eq. (2))")
            col = ax.lines[-1].get_color()
            sel = [r for r in rows if r["order"] == n]
            ax.plot([r["distance_m"] for r in sel], [r["full_ring_hz"] for r in sel], "o", ms=4, color=col)
            rt = [r for r in sel if math.isfinite(r["rtl_full_ring_hz"])]
            if rt:
                ax.plot([r["distance_m"] for r in rt], [r["rtl_full_ring_hz"] for r in rt], "x", ms=10, mew=2,
                        color=col)
        ax.axhline(limit, ls="--", color="k", lw=0.8, label="interlace limit")
        for d, g in GOALS_HZ.items():
            ax.hlines(g, d - 0.2, d + 0.2, color="tab:red", lw=3,
                      label="goal (issue #27)" if d == min(GOALS_HZ) else None)
        ax.plot([ANCHOR["distance_m"]], [ANCHOR["full_ring_hz"]], marker="*", ms=13, color="k", ls="none",
                label="Browne & Kleeman (2 in flight)", zorder=5)
        ax.set_xlabel("distance to the wall in every direction (m)")
        ax.set_ylabel("full-ring refresh (Hz, all 24 directions)")
        ax.set_title("8 virtual sensors, 24 directions: full-ring refresh (dots: model, x: RTL)")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)

    columns = ["distance_m", "t_e_ms", "order", "order_used", "full_ring_hz", "dir_min_hz", "dir_mean_hz",
               "worst_gap_ms", "pulse_hz", "pulse_min_hz", "analytic_hz", "order_analytic", "directions", "sweeps",
               "init_after_start", "interlace_limit_hz", "goal_hz", "goal_met", "anchor_hz", "rtl_full_ring_hz",
               "rtl_identical", "rtl_overrun"]
    data = {"experiment": "ring", "max_order": MAX_ORDER, "orders": ords, "arrangement": "ring8",
            "arrangement_text": ARRANGEMENTS["ring8"], "max_range_m": MAX_RANGE_M, "duration_s": duration,
            "decision_lead_ticks": DEVICE_DECISION_LEAD, "temperature_c": temperature_c,
            "interlace_limit_hz": limit, "metric": "full_ring_hz: complete sweeps of all 24 directions per second",
            "anchor": ANCHOR, "goals": goals, "goal_met": goal_met, "rows": rows, "arrangements": arrangements,
            "rtl": [{k: v for k, v in r.items() if k != "rtl_words"} for r in rtl_rows]}
    summary = {"goal_met": goal_met, "goals": goals, "max_order": MAX_ORDER, "interlace_limit_hz": limit,
               "max_rel_diff": max_dev, "all_directions": ok_dirs}
    return ExperimentResult("ring", "full-ring refresh", columns, rows, md, plot, summary=summary, json_data=data)


def _same(a: Any, b: Any) -> bool:
    fa, fb = float(a), float(b)
    return (math.isnan(fa) and math.isnan(fb)) or fa == fb


def rtl_ring(cases: list[tuple[float, int]], duration_s: float, temperature_c: float = 20.0) -> list[dict[str, Any]]:
    """Run the ring on the RTL scheduler (tests/rtl/tb_bench_ring.py; needs Verilator and the
    repository's tests/rtl): per case its event words, start tick, word-for-word comparison."""
    if temperature_c != 20.0:
        raise ExperimentError("--rtl runs the ring at 20 degC (the RTL bench's schedule)")
    return run_scheduler_bench("tb_bench_ring", "ring_rtl.json", "RING_OUT",
                               {"RING_CASES": ",".join(f"{d:g}:{n}" for d, n in cases),
                                "RING_DURATION_S": repr(float(duration_s))})
