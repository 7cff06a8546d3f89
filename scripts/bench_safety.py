#!/usr/bin/env python3
"""Safety property under randomised person-crossing scenes (issue #9), on the golden model.

Each trial (``multisonar.safety.run_trial``): a person crosses between the robot and a wall that
the left virtual sensor (tx 6, rx 5-7) tracks; wall distance, lane, radius, speeds, firing order
and K are random per seed. Reported: how often the person is reported within the bound
N + K + 1 pulses after it first hides the wall on one of the sensor's receivers ("detected"),
later ("late") or not at all ("missed"); latency in pulses and ms; tracking samples that were
another pulse's echo (interlacing aliases) or no echo at all (spurious / crosstalk).
The gated miss rule is the RTL's default (RX_FILTER.miss_gate reset value, 10.4 us);
--miss-gate-us 0 measures the rule without it.

--sweep-reinit none,4,8,bound runs the same seeds once per value of the golden model's forced
re-initialisation every M tracking pulses (VirtualSensor(reinit_every=M), the RTL's MODE.reinit_every; "none" = off, "bound" = N + K + 1 of
each trial, which bounds the latency by construction) and prints one row per M: outcomes,
worst latency, and the cost: true tracking samples per second of sonar time (first echoes in
tracking windows, all receivers of the sensor, that are the echo of their own pulse), over the
whole trial and over the plain wall tracking before the onset, relative to "none".

    .venv/bin/python scripts/bench_safety.py --trials 200 [--workers 2] [--spurious 50] [--miss-gate-us 0] [--plot F.png] [--csv F.csv]
    .venv/bin/python scripts/bench_safety.py --trials 60 --workers 1 --sweep-reinit none,4,6,8,12,16,24 [--plot F.png] [--csv F.csv]
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path
from typing import Any, Iterator

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "host"))

from multisonar.constants import TICK_HZ  # noqa: E402
from multisonar.fastfiring import DEFAULT_MISS_GATE  # noqa: E402
from multisonar.safety import TrialResult, as_rows, run_trial, summarise  # noqa: E402


def _run(seeds: range, workers: int, label: str, **kw: Any) -> Iterator[TrialResult]:
    """Trials of ``seeds`` in order; one process when ``workers`` is 1; progress on stderr."""
    t = time.time()
    fn = partial(run_trial, **kw)
    with ProcessPoolExecutor(max_workers=workers) if workers > 1 else _Serial() as ex:
        for i, r in enumerate(ex.map(fn, seeds), 1):
            print(f"\r{label}{i}/{len(seeds)} trials, {time.time() - t:.0f} s", end="", file=sys.stderr, flush=True)
            yield r
    print(file=sys.stderr)


class _Serial:
    def __enter__(self) -> "_Serial":
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def map(self, fn: Any, it: Any) -> Iterator[Any]:
        return map(fn, it)


def _write_csv(path: Path, rows: list[dict]) -> None:
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _reinit_value(tok: str) -> int | str | None:
    tok = tok.strip().lower()
    return None if tok in ("none", "off", "0") else "bound" if tok == "bound" else int(tok)


def sweep_reinit(a: argparse.Namespace, seeds: range, gate: int) -> int:
    values = [_reinit_value(x) for x in a.sweep_reinit.split(",")]
    t0 = time.time()
    runs: list[tuple[Any, list[TrialResult]]] = []
    for m in values:
        runs.append((m, list(_run(seeds, a.workers, f"M={m or 'none'}: ", spurious_rate_hz=a.spurious, miss_gate=gate,
                                  reinit_every=m))))
    base = summarise(runs[0][1]) if values[0] is None else None
    print(f"{len(seeds)} trials (seeds {seeds.start}-{seeds.stop - 1}) per M, spurious rate "
          f"{runs[0][1][0].spurious_rate_hz:g} Hz per channel, miss gate {gate} ticks, {time.time() - t0:.0f} s wall\n")
    print("| re-init every M | person hid the wall | within N+K+1 | late | missed | latency pulses median / max | "
          "latency ms median / max | init pings / trial | true samples/s | rel. | pre-onset samples/s | rel. |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    rows, notes = [], []
    for m, rs in runs:
        s = summarise(rs)
        rel = (f"{s['samples_per_s'] / base['samples_per_s']:.1%}" if base else "-",
               f"{s['pre_onset_samples_per_s'] / base['pre_onset_samples_per_s']:.1%}" if base else "-")
        print(f"| {m or 'none'} | {s['counted']} | {s['detected']} ({s['detected'] / max(s['counted'], 1):.1%}) | {s['late']} | "
              f"{s['missed']} | {s['latency_pulses_median']:.1f} / {s['latency_pulses_max']} | "
              f"{s['latency_ms_median']:.1f} / {s['latency_ms_max']:.1f} | {s['init_pings'] / s['trials']:.1f} | "
              f"{s['samples_per_s']:.0f} | {rel[0]} | {s['pre_onset_samples_per_s']:.0f} | {rel[1]} |")
        rows += [r | {"sweep_reinit": m or "none"} for r in as_rows(rs)]
        bad = [r.seed for r in rs if r.outcome in ("late", "missed")]
        if bad:
            notes.append(f"- M={m or 'none'}: seeds {bad} outside the bound "
                         f"(latency pulses {[r.latency_pulses for r in rs if r.seed in bad]})")
    if notes:
        print("\nTrials outside the bound:\n" + "\n".join(notes))
    if a.csv:
        _write_csv(a.csv, rows)
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        num = [(m, rs) for m, rs in runs if isinstance(m, int)]
        fig, ax = plt.subplots(figsize=(7, 4))
        ax2 = ax.twinx()
        xs = [m for m, _ in num]
        ss = [summarise(rs) for _, rs in num]
        ax.plot(xs, [100 * s["detected"] / max(s["counted"], 1) for s in ss], "o-", label="within N+K+1 (%)")
        if base:
            ax2.plot(xs, [100 * s["pre_onset_samples_per_s"] / base["pre_onset_samples_per_s"] for s in ss], "s--",
                     color="C1", label="pre-onset samples/s (% of none)")
            b = summarise(runs[0][1])
            ax.axhline(100 * b["detected"] / max(b["counted"], 1), color="C0", lw=0.8, ls=":", label="none")
        ax.set_xlabel("forced re-init every M tracking pulses")
        ax.set_ylabel("crossings within N+K+1 (%)")
        ax2.set_ylabel("tracking samples/s (% of none)")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, loc="center right", fontsize=8)
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
        print(f"\nplot: {a.plot}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--spurious", type=float, default=None, help="spurious pulses per channel and second (default: the scene's 2 Hz)")
    ap.add_argument("--miss-gate-us", type=float, default=DEFAULT_MISS_GATE / TICK_HZ * 1e6,
                    help="gated miss rule (RX_FILTER.miss_gate): a tracking window's first echo farther than this "
                         "from the prediction counts as a miss; 0 = off (default: the register's reset value, %(default)g us)")
    ap.add_argument("--reinit-every", type=int, default=None,
                    help="the sensor's reinit_every (MODE.reinit_every): force an init ping after this many tracking pulses")
    ap.add_argument("--sweep-reinit", metavar="M1,M2,...",
                    help="run the seeds once per forced re-init period M (none, integers, bound = N+K+1) and print one row per M")
    ap.add_argument("--plot", type=Path)
    ap.add_argument("--csv", type=Path)
    a = ap.parse_args()
    seeds = range(a.first_seed, a.first_seed + a.trials)
    gate = round(a.miss_gate_us * TICK_HZ / 1e6)
    if not 0 <= gate < 1 << 16:
        ap.error(f"--miss-gate-us {a.miss_gate_us:g} does not fit RX_FILTER.miss_gate (0..65535 ticks)")
    if a.sweep_reinit:
        return sweep_reinit(a, seeds, gate)
    t = time.time()
    results = list(_run(seeds, a.workers, "", spurious_rate_hz=a.spurious, miss_gate=gate, reinit_every=a.reinit_every))
    opts = ", ".join(x for x in (f"miss gate {a.miss_gate_us:g} us ({gate} ticks)" if gate else "miss gate off",
                                 a.reinit_every and f"model option re-init every {a.reinit_every} pulses (not in the RTL)")
                     if x)
    print(f"{a.trials} trials, spurious rate {results[0].spurious_rate_hz:g} Hz per channel, {opts}, {time.time() - t:.0f} s wall\n")
    print("| order | trials | person hid the wall | within N+K+1 pulses | late | missed | latency pulses median / max | latency ms median / max | samples | alias samples | false samples |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for order in (1, 2, 3, None):
        rs = [r for r in results if order is None or r.order == order]
        if not rs:
            continue
        s = summarise(rs)
        print(f"| {order or 'all'} | {s['trials']} | {s['counted']} | {s['detected']} | {s['late']} | {s['missed']} | "
              f"{s['latency_pulses_median']:.1f} / {s['latency_pulses_max']} | {s['latency_ms_median']:.1f} / {s['latency_ms_max']:.1f} | "
              f"{s['samples']} | {s['alias_samples']} ({s['alias_samples'] / max(s['samples'], 1):.2%}) | "
              f"{s['false_samples']} ({s['false_sample_rate']:.3%}) |")
    late = [r for r in results if r.outcome in ("late", "missed")]
    if late:
        print("\nTrials outside the bound (seed: order, K, wall, lane, person speed, latency pulses / bound, alias samples):")
        for r in late:
            print(f"- {r.seed}: N={r.order}, K={r.miss_limit}, wall {r.wall_y:.2f} m, lane {r.person_y:.2f} m, "
                  f"person {r.person_speed:+.2f} m/s, robot {r.robot_speed:.2f} m/s: {r.latency_pulses} / {r.bound_pulses} pulses "
                  f"({r.latency_ms:.0f} ms), {r.alias_samples} alias samples")
    if a.csv:
        _write_csv(a.csv, as_rows(results))
    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(7, 4))
        for order, m in ((1, "o"), (2, "s"), (3, "^")):
            rs = [r for r in results if r.order == order and r.latency_pulses >= 0]
            ax.scatter([r.bound_pulses for r in rs], [r.latency_pulses for r in rs], marker=m, label=f"order {order}", alpha=0.6)
        lim = max([r.latency_pulses for r in results] + [8]) + 1
        ax.plot([0, lim], [0, lim], "k--", lw=0.8, label="bound N+K+1")
        ax.set_xlabel("bound N + K + 1 (pulses)")
        ax.set_ylabel("detection latency (pulses)")
        ax.legend()
        fig.tight_layout()
        fig.savefig(a.plot, dpi=120)
        print(f"\nplot: {a.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
