"""Occluder safety under randomised person crossings (issue #28): ``multisonar experiment safety``.

Each trial is :func:`multisonar.safety.run_trial` on the wide generator
(:func:`multisonar.safety.wide_trial_params`: wall 1.45-4 m, person lane beyond the sensor's
minimum range, radius and speed, robot 0-2 m/s, order 1-8 as far as the wall allows, K 1-3,
spurious pulses 1-50 /s per channel), on the golden model (tick-identical to the RTL scheduler)
with the acoustic model in the loop. A trial passes when the person is reported within
N + K + 1 pulses of hiding the tracked wall. Each seed runs twice: with the device's defaults (the
firing rules under test) and with the gate-only default of the issue's time (gated miss rule
2400 ticks, no miss hold), whose tracking samples are the reference of ``sample_fraction``. Fixes are made from
every pulse with first echoes (not gated) on the sensor's three receivers, as the firmware does;
a fix farther than 50 mm from every true surface is false (``false_fix_rate`` = false fixes /
fixes).
"""

from __future__ import annotations

from concurrent.futures import Executor
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from .common import ExperimentResult, md_table
from .executor import run_sweep

#: the gate-only default when issue #28 was filed (RX_FILTER.miss_gate, ticks; no miss hold):
#: the reference of sample_fraction
BASELINE_MISS_GATE = 2400
QUICK_TRIALS, DEFAULT_TRIALS = 12, 1000


def trial_task(seed: int) -> tuple[Any, Any]:
    """Crossing ``seed`` of the wide generator: (with the defaults, with the gate-only default)."""
    from ..safety import run_trial, wide_trial_params

    p = wide_trial_params(seed)
    return run_trial(seed, params=p), run_trial(seed, params=p, miss_gate=BASELINE_MISS_GATE, miss_hold=False)


def _summary(pairs: list[tuple[Any, Any]]) -> dict[str, Any]:
    """The issue's figures of ``pairs`` (trial_task results), from :func:`multisonar.safety.summarise`."""
    from ..safety import summarise

    s, b = summarise(r for r, _ in pairs), summarise(base for _, base in pairs)
    sonar_s = sum(r.duration_s for r, _ in pairs)
    excess = [r.latency_pulses - r.bound_pulses for r, _ in pairs if r.outcome != "no_onset" and r.latency_pulses >= 0]
    return {
        "trials": s["trials"], "counted": s["counted"], "no_onset": s["no_onset"], "within_bound": s["detected"],
        "late": s["late"], "missed": s["missed"], "worst_pulses": s["latency_pulses_max"],
        "worst_excess_pulses": max(excess, default=0), "worst_ms": s["latency_ms_max"],
        "median_ms": s["latency_ms_median"], "samples": s["samples"], "baseline_samples": b["samples"],
        "sample_fraction": s["samples"] / b["samples"] if b["samples"] else float("nan"),
        "gated": s["gated"], "alias_samples": s["alias_samples"], "false_samples": s["false_samples"],
        "fixes": s["fixes"], "false_fixes": s["false_fixes"],
        "false_fix_rate": s["false_fixes"] / s["fixes"] if s["fixes"] else 0.0,
        "false_fixes_per_s": s["false_fixes"] / sonar_s if sonar_s else float("nan"), "sonar_s": sonar_s,
        "baseline_within_bound": b["detected"], "baseline_late": b["late"] + b["missed"],
    }


def run(executor: Executor, *, quick: bool = False, progress: bool = True, trials: int | None = None,
        seed: int | None = None) -> ExperimentResult:
    n = trials if trials is not None else QUICK_TRIALS if quick else DEFAULT_TRIALS
    first = 0 if seed is None else int(seed)
    if n < 1:
        raise ValueError(f"--trials must be >= 1, got {n}")
    from ..safety import wide_trial_params

    pairs = run_sweep(executor, trial_task, [{"seed": s} for s in range(first, first + n)], label="safety",
                      progress=progress)
    rows = [asdict(r) | {"ok": r.ok, "requested_order": wide_trial_params(r.seed)["order"],
                         "baseline_samples": base.samples, "baseline_outcome": base.outcome,
                         "baseline_latency_pulses": base.latency_pulses} for r, base in pairs]
    summ = _summary(pairs)
    by_order = [{"order": order} | _summary([(r, b) for r, b in pairs if r.order == order])
                for order in sorted({r.order for r, _ in pairs})]
    cols = [("order", "order"), ("trials", "trials"), ("counted", "person hid the wall"),
            ("within_bound", "within N+K+1"), ("late", "late"), ("missed", "missed"),
            ("worst_pulses", "worst pulses"), ("worst_ms", "worst ms"), ("sample_fraction", "samples vs gate-only"),
            ("fixes", "fixes"), ("false_fixes", "false fixes")]
    fmt = {"worst_ms": ".1f", "sample_fraction": ".3f"}
    late = [r for r in rows if r["outcome"] in ("late", "missed")]
    md = [f"# Occluder safety: {n} randomised person crossings (seeds {first}-{first + n - 1})", "",
          "Golden model with the acoustic model in the loop; wide generator "
          "(`multisonar.safety.wide_trial_params`). A crossing passes when the person is reported within "
          "N + K + 1 pulses of hiding the tracked wall on one of the sensor's receivers.", "",
          md_table(cols, by_order + [{"order": "all"} | summ], fmt), "",
          f"- within the bound: **{summ['within_bound']} of {summ['counted']}** crossings where the person hid "
          f"the wall ({summ['no_onset']} trials without an onset are not counted); late {summ['late']}, "
          f"missed {summ['missed']}; worst {summ['worst_pulses']} pulses / {summ['worst_ms']:.1f} ms",
          f"- tracking samples: {summ['samples']} = **{summ['sample_fraction']:.1%}** of the gate-only default "
          f"(gated miss rule {BASELINE_MISS_GATE} ticks, no miss hold) on the same trials ({summ['baseline_samples']}); "
          f"that default: {summ['baseline_within_bound']} within the bound, {summ['baseline_late']} late or missed",
          f"- first echoes flagged gated (no sample, no geometry): {summ['gated']}; accepted alias samples "
          f"{summ['alias_samples']}, false samples {summ['false_samples']}",
          f"- fixes: {summ['fixes']}, false (> 50 mm from every true surface) {summ['false_fixes']} = "
          f"**{summ['false_fix_rate']:.3%}**, {summ['false_fixes_per_s']:.3f} per second of sonar time"]
    if late:
        md += ["", "Crossings outside the bound (seed: order, K, wall, lane, person / robot speed, spurious rate, "
               "latency / bound):"]
        md += [f"- {r['seed']}: N={r['order']}, K={r['miss_limit']}, wall {r['wall_y']:.2f} m, "
               f"lane {r['person_y']:.2f} m, {r['person_speed']:+.2f} / {r['robot_speed']:.2f} m/s, "
               f"{r['spurious_rate_hz']:.1f} /s: "
               f"{r['latency_pulses']} / {r['bound_pulses']} pulses ({r['latency_ms']:.1f} ms)" for r in late]
    columns = list(rows[0])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4.5))
        for order in sorted({r["order"] for r in rows}):
            rs = [r for r in rows if r["order"] == order and r["latency_pulses"] >= 0]
            jitter = np.linspace(-0.25, 0.25, len(rs)) if rs else []
            ax.scatter([r["bound_pulses"] + j for r, j in zip(rs, jitter)], [r["latency_pulses"] for r in rs],
                       s=10, alpha=0.6, label=f"order {order}")
        lim = max([r["latency_pulses"] for r in rows] + [r["bound_pulses"] for r in rows] + [4]) + 1
        ax.plot([0, lim], [0, lim], "k--", lw=0.8, label="bound N+K+1")
        ax.set_xlabel("bound N + K + 1 (pulses)")
        ax.set_ylabel("detection latency (pulses)")
        ax.set_title(f"{summ['within_bound']}/{summ['counted']} within the bound; "
                     f"samples {summ['sample_fraction']:.1%} of gate-only")
        ax.legend(fontsize=7, ncol=2)
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)

    json_data = summ | {"first_seed": first, "by_order": by_order, "baseline_miss_gate": BASELINE_MISS_GATE,
                        "late_seeds": [r["seed"] for r in late]}
    return ExperimentResult("safety", "occluder safety", columns, rows, "\n".join(md) + "\n", plot,
                            summary=summ, json_data=json_data)


__all__ = ["run", "trial_task", "BASELINE_MISS_GATE"]
