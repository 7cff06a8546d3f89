"""Paper Fig. 9: wall-orientation error against the true wall orientation, 45 .. 135 deg,
2 and 3 receivers, with and without re-aiming.

Setup (stated): the ring's adjacent pair, elements 0 (axis 0 deg) and 1 (axis 15 deg),
baseline 91.4 mm (the paper's 91 mm). Element 0 transmits (virtual source = element 0) and
receives; element 1 receives ("2 receivers"); "3 receivers" adds element 23 (axis -15 deg).
The wall is ``distance`` from the transmitter; its orientation is the angle between the wall
line and the pair's baseline as in Fig. 8: 90 deg = the wall faces the pair (normal along the
pair's mean axis, 7.5 deg), 45 / 135 deg = the wall turned by 45 deg either way. Timing noise
sigma = 1 us per receiver (path sigma = c * 1 us), ``cases`` noisy trials per orientation.

Echo visibility: a receiver hears the wall if the acoustic model (:mod:`multisonar.acoustics`,
beam pattern, spreading and absorption, comparator threshold) gives it a first-order echo from
the wall; fewer than 2 receivers hearing = a miss.

Re-aiming (paper section V.A: "encountering walls outside of the high confidence interval leads
to repositioning of the virtual orientation"): if the first estimate's orientation relative to
the pair is outside 75..115 deg, the virtual sensor is moved to the adjacent pair (k, k+1)
whose mean axis is nearest to the estimated wall normal (3 receivers: k-1, k, k+1; transmitter
k) and the wall is measured again; the error is that of the final estimate. If the fixed sensor
hears nothing, the neighbouring pairs are tried first (nearest first) for the first estimate.
"""

from __future__ import annotations

import math
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import speed_of_sound
from .common import ExperimentResult, md_table, wrap_angle
from .executor import run_sweep

CONFIGS = {"2 rx": (0, (0, 1)), "3 rx": (0, (23, 0, 1))}  # name -> (tx, receivers) of the fixed pair
HIGH_CONFIDENCE = (75.0, 115.0)


def _heard(layout: Any, tx: int, rx: tuple[int, ...], distance: float, normal: float) -> list[int]:
    """Receivers that hear the wall, decided by the acoustic model (``AcousticModel.truth`` on
    the wall_1m scene with this wall line: first-order echo inside both beams, amplitude above
    the comparator threshold)."""
    from ..acoustics import AcousticModel, Firing, PulseKind
    from ..scene import load_scene

    P = layout.positions
    n = np.array([math.cos(normal), math.sin(normal)])
    q = P[tx] + distance * n  # foot of the perpendicular from the transmitter
    bearing = math.degrees(math.atan2(q[1], q[0]))
    scene = load_scene("wall_1m", distance=float(np.hypot(*q)), bearing_deg=bearing,
                       orientation_deg=math.degrees(normal) + 90.0 - bearing, length=6.0)
    tr = AcousticModel(scene, rng=np.random.default_rng(0)).truth(Firing.single(0.0, int(tx)))
    ok = (tr["kind"] == PulseKind.ECHO) & (tr["amplitude"] >= scene.noise.threshold)
    got = set(int(r) for r in tr["rx"][ok])
    return [r for r in rx if r in got]


def _measure(layout: Any, tx: int, rx: list[int], distance: float, normal: float, sigma: float,
             rng: np.random.Generator, cases: int) -> tuple[np.ndarray, np.ndarray]:
    """(valid, estimated normal angle) per trial for a wall at ``distance`` from element tx."""
    from .. import geometry as g

    if len(rx) < 2:
        return np.zeros(cases, bool), np.zeros(cases)
    C = layout.positions[rx]
    R = g.wall_path_lengths(distance, normal, C, layout.positions[tx])
    Rn = R[None, :] + rng.normal(0.0, sigma, (cases, len(rx)))
    axis = float(np.angle(np.exp(1j * layout.axes[rx]).mean()))
    b = g.solve_wall_batch(C, Rn, layout.positions[tx], axis=axis)
    return b.valid, b.normal_angle


def orientation_point(orientation_deg: float, cases: int, distance_m: float, sigma_us: float, seed: int
                      ) -> list[dict[str, Any]]:
    """All configurations at one orientation: rows for (2 rx, 3 rx) x (fixed, re-aimed)."""
    from ..layout import load_layout

    layout = load_layout()
    P, A = layout.positions, layout.axes
    n_el = layout.n
    sigma = speed_of_sound() * sigma_us * 1e-6
    mid = float(np.angle(np.exp(1j * A[[0, 1]]).mean()))
    na = mid + math.radians(orientation_deg - 90.0)
    nvec = np.array([math.cos(na), math.sin(na)])
    wall_c = float(nvec @ P[0]) + distance_m  # wall line: n . x = wall_c
    rows = []
    for ci, (name, (tx, rx)) in enumerate(CONFIGS.items()):
        rng = np.random.default_rng([seed, int(round(orientation_deg * 100)), ci])
        heard = _heard(layout, tx, rx, distance_m, na)
        valid, est = _measure(layout, tx, heard, distance_m, na, sigma, rng, cases)
        for reaim in (False, True):
            final_valid, final_est = valid.copy(), est.copy()
            n_reaimed = 0
            used = {len(heard)}
            if reaim:
                if len(heard) < 2:  # the fixed sensor hears nothing: scan the neighbouring pairs
                    for off in (1, -1, 2, -2, 3, -3):
                        k = off % n_el
                        rx1 = (k, (k + 1) % n_el) if len(rx) == 2 else ((k - 1) % n_el, k, (k + 1) % n_el)
                        d1 = wall_c - float(nvec @ P[k])
                        h1 = _heard(layout, k, rx1, d1, na)
                        if len(h1) >= 2:
                            final_valid, final_est = _measure(layout, k, h1, d1, na, sigma, rng, cases)
                            used.add(len(h1))
                            break
                est_r, valid_r = final_est, final_valid
                rel = np.degrees(wrap_angle(est_r - mid)) + 90.0
                need = valid_r & ((rel < HIGH_CONFIDENCE[0]) | (rel > HIGH_CONFIDENCE[1]))
                # pair (k, k+1) whose mean axis is nearest to the estimated normal
                pair_axes = A + 0.5 * wrap_angle(np.roll(A, -1) - A)
                k_of = np.argmin(np.abs(wrap_angle(est_r[:, None] - pair_axes[None, :])), axis=1)
                for k in np.unique(k_of[need]):
                    sel = need & (k_of == k)
                    k = int(k)
                    rx2 = (k, (k + 1) % n_el) if len(rx) == 2 else ((k - 1) % n_el, k, (k + 1) % n_el)
                    d2 = wall_c - float(nvec @ P[k])
                    h2 = _heard(layout, k, rx2, d2, na)
                    used.add(len(h2))
                    v2, e2 = _measure(layout, k, h2, d2, na, sigma, rng, int(sel.sum()))
                    final_valid[sel], final_est[sel] = v2, e2
                    n_reaimed += int(sel.sum())
            err = np.degrees(wrap_angle(final_est[final_valid] - na))
            rows.append({"orientation_deg": orientation_deg, "config": name, "reaim": reaim,
                         "receivers_heard": "/".join(str(u) for u in sorted(used)),
                         "n": cases, "valid_frac": float(final_valid.mean()), "reaimed_frac": n_reaimed / cases,
                         "mean_deg": float(err.mean()) if err.size else float("nan"),
                         "std_deg": float(err.std()) if err.size else float("nan"),
                         "max_abs_deg": float(np.abs(err).max()) if err.size else float("nan"),
                         "rms_deg": float(np.sqrt(np.mean(err ** 2))) if err.size else float("nan")})
    return rows


def run(executor: Executor, *, quick: bool = False, cases: int | None = None, step_deg: float | None = None,
        distance_m: float = 1.0, sigma_us: float = 1.0, seed: int = 9, progress: bool = True) -> ExperimentResult:
    cases = cases or (300 if quick else 2000)
    step = step_deg or (15.0 if quick else 5.0)
    orient = [float(o) for o in np.arange(45.0, 135.0 + 1e-9, step)]
    tasks = [{"orientation_deg": o, "cases": cases, "distance_m": distance_m, "sigma_us": sigma_us, "seed": seed}
             for o in orient]
    rows = [r for part in run_sweep(executor, orientation_point, tasks, label="fig9", progress=progress) for r in part]

    def key(cfg: str, reaim: bool) -> str:
        return f"{cfg}, {'re-aimed' if reaim else 'fixed'}"

    keys = [key(c, a) for c in CONFIGS for a in (False, True)]
    wide = []
    for o in orient:
        line: dict[str, Any] = {"o": o}
        for r in rows:
            if r["orientation_deg"] == o:
                k = key(r["config"], r["reaim"])
                line[k] = (f"{r['mean_deg']:+.3f} / {r['std_deg']:.3f} / {r['max_abs_deg']:.3f}, "
                           f"{1 - r['valid_frac']:.0%} miss" if np.isfinite(r["mean_deg"]) else
                           f"-, {1 - r['valid_frac']:.0%} miss")
        wide.append(line)
    summ_rows = []
    summary: dict[str, Any] = {}
    for c in CONFIGS:
        for a in (False, True):
            sel = [r for r in rows if r["config"] == c and r["reaim"] == a]
            core = [r for r in sel if HIGH_CONFIDENCE[0] <= r["orientation_deg"] <= HIGH_CONFIDENCE[1]]
            out = [r for r in sel if not HIGH_CONFIDENCE[0] <= r["orientation_deg"] <= HIGH_CONFIDENCE[1]]

            def agg(rs: list[dict[str, Any]], f: str, fn: Any) -> float:
                v = [r[f] for r in rs if np.isfinite(r[f])]
                return float(fn(v)) if v else float("nan")

            s = {"what": key(c, a),
                 "core_max": agg(core, "max_abs_deg", max), "core_std": agg(core, "std_deg", np.mean),
                 "out_rms": agg(out, "rms_deg", lambda v: float(np.sqrt(np.mean(np.square(v))))),
                 "all_rms": agg(sel, "rms_deg", lambda v: float(np.sqrt(np.mean(np.square(v))))),
                 "all_max": agg(sel, "max_abs_deg", max),
                 "miss": 1 - float(np.mean([r["valid_frac"] for r in sel]))}
            summ_rows.append(s)
            summary[s["what"]] = s
    md = "\n".join([
        "# Fig. 9: wall-orientation error vs wall orientation", "",
        f"Wall at {distance_m} m from element 0 (the transmitter), 91.4 mm baseline (elements 0, 1; 3 receivers adds 23), "
        f"{sigma_us} us timing noise per receiver, {cases} trials per orientation, echo visibility from the acoustic model "
        f"(beam half angle {math.degrees(_half()):.0f} deg, comparator threshold). Cells: mean / std / max abs error (deg), share of misses "
        "(fewer than two receivers hear the wall, or the fit is flagged invalid). Re-aimed: estimates outside "
        f"{HIGH_CONFIDENCE[0]:.0f}..{HIGH_CONFIDENCE[1]:.0f} deg move the virtual sensor to the pair facing the wall "
        "and measure again.", "",
        md_table([("o", "orientation (deg)")] + [(k, k) for k in keys], wide, {"o": ".0f"}), "",
        "Summary (deg; paper: max abs error ~0.5 deg in 75..115 deg, std 0.25 deg, severe outliers outside):", "",
        md_table([("what", "configuration"), ("core_max", "75..115: max abs"), ("core_std", "75..115: mean std"),
                  ("out_rms", "outside: rms"), ("all_rms", "45..135: rms"), ("all_max", "45..135: max abs"),
                  ("miss", "miss rate")], summ_rows,
                 {"core_max": ".3f", "core_std": ".3f", "out_rms": ".3f", "all_rms": ".3f", "all_max": ".3f", "miss": ".1%"}),
        ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        fig, axs = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
        for ax, a in zip(axs, (False, True)):
            for c in CONFIGS:
                sel = [r for r in rows if r["config"] == c and r["reaim"] == a]
                o = np.array([r["orientation_deg"] for r in sel])
                ax.errorbar(o, [r["mean_deg"] for r in sel], yerr=[r["std_deg"] for r in sel], capsize=2,
                            label=f"{c}: mean +- std")
                ax.plot(o, [r["max_abs_deg"] for r in sel], "--", label=f"{c}: max abs")
            ax.axvspan(*HIGH_CONFIDENCE, color="0.92", zorder=0)
            ax.set_xlabel("true wall orientation (deg)")
            ax.set_title("re-aimed virtual sensor" if a else "fixed pair (elements 0, 1)")
            ax.set_yscale("symlog", linthresh=0.1)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=7)
        axs[0].set_ylabel("wall angle error (deg)")
        fig.suptitle(f"Fig. 9 replica: {distance_m} m, 91 mm baseline, {sigma_us} us noise")
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)

    columns = ["orientation_deg", "config", "reaim", "receivers_heard", "n", "valid_frac", "reaimed_frac",
               "mean_deg", "std_deg", "max_abs_deg", "rms_deg"]
    return ExperimentResult("fig9", "wall angle error vs orientation", columns, rows, md, plot, summary=summary)


def _half() -> float:
    from ..layout import load_layout

    return float(load_layout().transducer.beam_half_angle)
