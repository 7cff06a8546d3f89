#!/usr/bin/env python3
"""What a longer decision lead P (LEAD) costs, on the golden model (issue #27).

The scheduler decides each pulse P ticks before its t0 and may fall P/2 behind real time
(docs/fast_firing.md section 3.1). A lean serial engine spends more clocks per item than today's
pipelined one, so it needs a larger P. For each P this bench measures what users would lose:

- tracking samples on the demo: first echoes in tracking windows of the demo's five sensors on
  `sim://corridor` (2 s), the mean over --corridor-seeds acoustic-noise seeds (with the spread:
  the five sensors share elements, so one run's count jumps by +-20 % from one P to the next,
  P = 4200 or 5000 against 4096 included), relative to the first P of the list;
- full-ring refresh: the `ring8` room of `multisonar experiment ring` at 2 m and 5.7 m, order 8
  (the engine's heaviest same-tick burst), and when the first full sweep is complete;
- safety: randomised person crossings (`multisonar.safety.run_trial`, seeds from --seed): the
  obstacle reported within N + K + 1 pulses, worst latency, tracking samples relative to the
  first P of the list;
- refusals: a sensor needs its blanking D and its window T_V + T_N longer than P (cfg_error LEAD
  / WINDOW_SHORT); whether the default one-element sensor and the ring8 sensors pass, and the
  narrowest window (= the shortest blanking) P allows, in millimetres of range;
- the engine's budget P/2 against the worst lag measured at the product's P
  (build/bench/sched_lag.json from scripts/bench_sched_lag.py, when present): how many times
  more clocks per item the engine may spend.

    .venv/bin/python scripts/bench_lead.py [--leads 4096,8192,16384,32768] [--trials 40] [--seed 5000]
        [--workers 2] [--json F] [--plot F.png]

Prints a markdown table; writes build/bench/lead.json (or --json).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))

from multisonar.constants import DEVICE_DECISION_LEAD, TICK_HZ, speed_of_sound  # noqa: E402
from multisonar.experiments import ring  # noqa: E402
from multisonar.layout import load_layout  # noqa: E402
from multisonar.safety import run_trial, summarise  # noqa: E402
from multisonar.schedule import Schedule, VirtualSensor  # noqa: E402
from multisonar.scene import load_scene  # noqa: E402

OUT = ROOT / "build" / "bench" / "lead.json"
LAG = ROOT / "build" / "bench" / "sched_lag.json"
RING_S = 0.3  # sonar seconds per ring point: about 60 sweeps at 5.7 m
CORRIDOR_S = 2.0  # sonar seconds of the demo's sensors on the corridor scene


def corridor_run(lead: int, seed: int) -> tuple[int, int]:
    """First echoes in tracking windows and init pings of the demo's sensors on `corridor`, with
    the acoustic model's noise drawn from ``seed``."""
    import numpy as np

    from multisonar.demo import demo_sensors
    from multisonar.fastfiring import FastFiringModel, SceneEchoSource

    scene = load_scene("corridor")
    model = FastFiringModel(Schedule(scene.layout, demo_sensors("demo"), temperature_c=scene.temperature_c),
                            SceneEchoSource(scene, rng=np.random.default_rng(seed)), decision_lead=lead)
    res = model.run(int(CORRIDOR_S * TICK_HZ))
    return (sum(e.first_echo and e.in_window and not e.init_ping for e in res.events),
            sum(p.init for p in res.pulses))


def _map(fn: Any, seeds: range, workers: int) -> list[Any]:
    """fn over seeds, in order, on ``workers`` processes (one: in this process)."""
    if workers > 1:
        with ProcessPoolExecutor(max_workers=workers) as ex:
            return list(ex.map(fn, seeds))
    return [fn(s) for s in seeds]


def corridor_samples(lead: int, seeds: range, workers: int) -> dict[str, Any]:
    """Mean and spread over ``seeds`` of corridor_run."""
    import statistics

    runs = _map(partial(corridor_run, lead), seeds, workers)
    samples = [r[0] for r in runs]
    return {"corridor_tracking_samples": round(statistics.mean(samples), 1),
            "corridor_samples_std": round(statistics.stdev(samples), 1) if len(samples) > 1 else 0.0,
            "corridor_samples_runs": samples,
            "corridor_init_pings": round(statistics.mean(r[1] for r in runs), 1)}


def _mm(ticks: int) -> float:
    """Range depth of `ticks` of round-trip time, mm."""
    return ticks / TICK_HZ * speed_of_sound() / 2 * 1000


def _sensors() -> dict[str, list[Any]]:
    """Resolved sensors whose limits the refusals are checked on (validated at the product P)."""
    layout = load_layout()
    return {"default": Schedule(layout, [VirtualSensor("s", tx=[0], rx=[0])]).validate(),
            "ring8": Schedule(layout, ring.ring_sensors(8)).validate()}


def _worst_lag() -> int | None:
    if not LAG.exists():
        return None
    return max((r["lag_max"] for r in json.loads(LAG.read_text())), default=None)


def measure(lead: int, trials: int, seed: int, workers: int, sensors: dict[str, list[Any]],
            corridor_seeds: int = 8) -> dict[str, Any]:
    row: dict[str, Any] = {"lead_ticks": lead, "lead_us": round(lead / TICK_HZ * 1e6, 1),
                           "engine_budget_ticks": lead // 2}
    for d in (2.0, 5.7):
        m = ring.measure_ring(d, 8, duration_s=RING_S, decision_lead=lead)
        key = f"{d:g}m".replace(".", "p")
        row[f"ring_{key}_hz"] = round(m["full_ring_hz"], 2)
        row[f"ring_{key}_first_sweep_ms"] = round(m["track_start_tick"] / TICK_HZ * 1e3, 2)
    row.update(corridor_samples(lead, range(corridor_seeds), workers))
    s = summarise(_map(partial(run_trial, decision_lead=lead), range(seed, seed + trials), workers))
    row.update(safety_trials=s["trials"], safety_within_bound=s["detected"], safety_late=s["late"],
               safety_missed=s["missed"], safety_worst_pulses=s["latency_pulses_max"],
               safety_worst_ms=round(s["latency_ms_max"], 2), safety_samples=s["samples"])
    for name, rs in sensors.items():
        row[f"{name}_accepted"] = all(r.blank > lead and r.t_v + r.t_n > lead for r in rs)
    row["narrowest_window_mm"] = round(_mm(lead + 1), 1)  # also the shortest blanking D
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--leads", default="4096,8192,16384,32768", help="decision leads P, ticks")
    ap.add_argument("--trials", type=int, default=40, help="person crossings per P")
    ap.add_argument("--seed", type=int, default=5000, help="first trial seed")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--corridor-seeds", type=int, default=8, help="noise seeds of the corridor runs per P")
    ap.add_argument("--json", type=Path, default=OUT)
    ap.add_argument("--plot", type=Path)
    a = ap.parse_args()
    leads = [int(x) for x in a.leads.split(",")]
    if any(x <= 0 for x in leads):
        ap.error(f"--leads {a.leads}: every P must be a positive tick count")
    t0 = time.time()
    sens = _sensors()
    rows = []
    for lead in leads:
        rows.append(measure(lead, a.trials, a.seed, a.workers, sens, a.corridor_seeds))
        print(f"P = {lead}: done, {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    lag = _worst_lag()
    base, cbase = rows[0]["safety_samples"] or 1, rows[0]["corridor_tracking_samples"] or 1
    for r in rows:
        r["safety_samples_rel"] = round(r["safety_samples"] / base, 4)
        r["corridor_samples_rel"] = round(r["corridor_tracking_samples"] / cbase, 4)
        r["corridor_samples_rel_std"] = round(r["corridor_samples_std"] / cbase, 4)
        r["worst_lag_ticks"] = lag
        r["clocks_per_item_headroom"] = round(r["engine_budget_ticks"] / lag, 2) if lag else None
    limits = {name: {"blank_ticks": min(int(r.blank) for r in rs), "window_ticks": min(int(r.t_v + r.t_n) for r in rs)}
              for name, rs in sens.items()}
    doc = {"product_lead_ticks": DEVICE_DECISION_LEAD, "ring_duration_s": RING_S, "trials": a.trials,
           "corridor_seeds": a.corridor_seeds,
           "first_seed": a.seed, "sensor_limits": limits, "rows": rows}
    a.json.parent.mkdir(parents=True, exist_ok=True)
    a.json.write_text(json.dumps(doc, indent=1) + "\n")

    print("| P (ticks) | P (us) | budget P/2 | x worst lag | ring 2 m (Hz) | ring 5.7 m (Hz) | first sweep 5.7 m (ms) "
          "| safety within bound | worst (pulses / ms) | tracking samples: crossings | corridor +- sd (init pings) "
          "| default / ring8 accepted | narrowest window (mm) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---|---|---:|---|---|---:|")
    for r in rows:
        print(f"| {r['lead_ticks']} | {r['lead_us']} | {r['engine_budget_ticks']} | {r['clocks_per_item_headroom'] or '-'} "
              f"| {r['ring_2m_hz']} | {r['ring_5p7m_hz']} | {r['ring_5p7m_first_sweep_ms']} "
              f"| {r['safety_within_bound']}/{r['safety_trials']} | {r['safety_worst_pulses']} / {r['safety_worst_ms']} "
              f"| {r['safety_samples_rel']:.3f} | {r['corridor_samples_rel']:.3f} +- {r['corridor_samples_rel_std']:.3f} "
              f"({r['corridor_init_pings']}) "
              f"| {'yes' if r['default_accepted'] else 'NO'} / "
              f"{'yes' if r['ring8_accepted'] else 'NO'} | {r['narrowest_window_mm']} |")
    print(f"\nsensor limits (ticks): {limits}; worst engine lag at P = {DEVICE_DECISION_LEAD}: "
          f"{lag if lag is not None else 'not measured (run scripts/bench_sched_lag.py)'}")
    print(f"bench_lead: wrote {a.json} ({time.time() - t0:.0f} s)")
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        xs = [r["lead_ticks"] for r in rows]
        ax[0].plot(xs, [r["ring_2m_hz"] for r in rows], "o-", label="ring 2 m")
        ax[0].plot(xs, [r["ring_5p7m_hz"] for r in rows], "s-", label="ring 5.7 m")
        ax[0].set(xscale="log", xlabel="decision lead P (ticks)", ylabel="full-ring refresh (Hz)")
        ax[0].legend()
        ax[1].plot(xs, [r["safety_samples_rel"] for r in rows], "o-", label="person crossings")
        ax[1].plot(xs, [r["corridor_samples_rel"] for r in rows], "s-", label="demo on corridor")
        ax[1].set(xscale="log", xlabel="decision lead P (ticks)", ylabel="tracking samples (rel.)")
        ax[1].legend()
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
        print(f"bench_lead: wrote {a.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
