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

Twin backend (``backend="twin"``): a few orientations (``--quick``: 60, 90, 120 deg; else every
15 deg) also run on the full-system twin: the wall of the case in the wall_1m scene (acoustic
model with its 1 us jitter, fading, spurious pulses), the sensor (tx 0, the receivers of the
configuration) configured through the driver, frames streamed until the sensor has settled (see
:func:`twin_case`). The angle comes from the device: 3 receivers, the firmware's wall records
(a pulse the firmware classes edge / uncertain, or does not fix, is a miss); 2 receivers (the
firmware fixes three or more only), the wall fit (as the model's) on the device's ToF records.
The firmware re-aims on its own (a fix more than 10 deg off the transmitter's axis moves the
groups one element toward it): "fixed" on the twin = the pulses of the configured groups,
"re-aimed" = those of the groups the firmware ended on. The golden model on the same scene and
sensor (no re-aim) is run alongside for reference.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import TICK_HZ, speed_of_sound
from .common import ExperimentResult, md_table, wrap_angle
from .executor import run_sweep

CONFIGS = {"2 rx": (0, (0, 1)), "3 rx": (0, (23, 0, 1))}  # name -> (tx, receivers) of the fixed pair
HIGH_CONFIDENCE = (75.0, 115.0)
BACKENDS = ("model", "twin")
TWIN_ORIENT_QUICK = (60.0, 90.0, 120.0)  #: --quick: one facing wall, one turned either way (re-aimed)
TWIN_ORIENT_STEP = 15.0  #: full: every 15 deg of the model's orientations
TWIN_PULSES = 12  #: complete pulses on the final groups before a twin case stops
TWIN_MAX_S = 0.3  #: sonar time cap per twin case (two re-aims, 100 ms apart, fit in it)
TWIN_STATS = ("n", "valid_frac", "mean_deg", "std_deg", "max_abs_deg", "rms_deg")
SCENE_MODEL_S = 0.08  #: golden model on the twin's scene (no re-aim): init ping + ~14 pulses


def wall_scene(layout: Any, tx: int, distance: float, normal: float, **overrides: Any) -> Any:
    """The wall_1m scene with the wall line at ``distance`` from element ``tx`` along the normal
    ``normal`` (rad, robot frame), 6 m long."""
    from ..scene import load_scene

    n = np.array([math.cos(normal), math.sin(normal)])
    q = layout.positions[tx] + distance * n  # foot of the perpendicular from the transmitter
    bearing = math.degrees(math.atan2(q[1], q[0]))
    return load_scene("wall_1m", distance=float(np.hypot(*q)), bearing_deg=bearing,
                      orientation_deg=math.degrees(normal) + 90.0 - bearing, length=6.0, **overrides)


def _heard(layout: Any, tx: int, rx: tuple[int, ...], distance: float, normal: float) -> list[int]:
    """Receivers that hear the wall, decided by the acoustic model (``AcousticModel.truth`` on
    the wall_1m scene with this wall line: first-order echo inside both beams, amplitude above
    the comparator threshold)."""
    from ..acoustics import AcousticModel, Firing, PulseKind

    scene = wall_scene(layout, tx, distance, normal)
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


def _err_stats(valid: np.ndarray, est: np.ndarray, truth: float) -> dict[str, Any]:
    """n, share valid and the error statistics (deg) of per-pulse estimates against the truth."""
    valid = np.asarray(valid, bool)
    err = np.degrees(wrap_angle(np.asarray(est, float)[valid] - truth)) if valid.size else np.zeros(0)
    nan = float("nan")
    return {"n": int(valid.size), "valid_frac": float(valid.mean()) if valid.size else nan,
            "mean_deg": float(err.mean()) if err.size else nan, "std_deg": float(err.std()) if err.size else nan,
            "max_abs_deg": float(np.abs(err).max()) if err.size else nan,
            "rms_deg": float(np.sqrt(np.mean(err ** 2))) if err.size else nan}


def _host_walls(layout: Any, tx: int, rx: list[int], tofs: list[dict[int, int]], c: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Per pulse (first-echo ToF ticks per receiver) the host's wall estimate from a single
    transmitter: 2 receivers, the wall fit (as the model's Monte Carlo); 3 or more, what the
    firmware computes (``georecord.geo_records``: a wall only when the classification says wall).
    A pulse without a first echo on every receiver is a miss. (valid, normal angle)."""
    from .. import geometry as g
    from ..georecord import geo_records

    valid, est = np.zeros(len(tofs), bool), np.zeros(len(tofs))
    full = [k for k, t in enumerate(tofs) if all(r in t for r in rx)]
    if not full:
        return valid, est
    C, S = layout.positions[rx], layout.positions[tx]
    R = c * np.array([[tofs[k][r] for r in rx] for k in full], float) / TICK_HZ
    if len(rx) < 3:
        axis = float(np.angle(np.exp(1j * layout.axes[rx]).mean()))
        with np.errstate(all="ignore"):
            b = g.solve_wall_batch(C, R, S, axis=axis)
        valid[full], est[full] = b.valid, b.normal_angle
        return valid, est
    for k, rec in zip(full, geo_records(C, R, S)):
        if rec is not None and int(rec["cls"]) == 2:
            valid[k], est[k] = True, int(rec["normal"]) * 2 * math.pi / 65536
    return valid, est


def twin_case(orientation_deg: float, config: str, distance_m: float = 1.0, seed: int = 9,
              progress: bool = True) -> dict[str, Any]:
    """One (orientation, configuration) on the full-system twin and, for reference, on the golden
    model with the same scene and sensor. The twin runs until the groups the sensor ended on have
    TWIN_PULSES complete pulses and (3 receivers) no fix of theirs is more than the firmware's
    re-aim threshold off their axis (the firmware has no reason to move them again), at most
    TWIN_MAX_S of sonar time."""
    from ..layout import load_layout
    from ..schedule import VirtualSensor
    from .common import simulate_scene
    from .twin_backend import REAIM_DEG, TwinRun, placement_axis, run_on_twin

    layout = load_layout()
    tx, rx = CONFIGS[config]
    mid = float(np.angle(np.exp(1j * layout.axes[[0, 1]]).mean()))
    na = mid + math.radians(orientation_deg - 90.0)
    scene = wall_scene(layout, tx, distance_m, na)
    c = scene.speed_of_sound
    sensor = VirtualSensor("wall", tx=[tx], rx=list(rx))

    def settled(run: TwinRun) -> bool:
        shift = run.pulses[-1].shift if run.pulses else 0
        if sum(p.complete and p.shift == shift for p in run.pulses) < TWIN_PULSES:
            return False
        axis = placement_axis(layout, run.resolved[0], shift)
        return len(rx) < 3 or all(abs(math.remainder(f.bearing - axis, 2 * math.pi)) <= math.radians(REAIM_DEG)
                                  for f in run.fixes if f.fixed and f.pulse is not None and f.pulse.shift == shift)

    run = run_on_twin(scene, [sensor], TWIN_MAX_S, seed=seed, stop=settled, progress=progress,
                      label=f"fig9 twin: {orientation_deg:g} deg, {config}")
    pulses = [p for p in run.pulses if p.complete]
    if len(rx) >= 3:  # the firmware's wall records
        wall_of = {id(f.pulse): f.normal for f in run.fixes if f.kind == "wall" and f.pulse is not None}
        valid = np.array([id(p) in wall_of for p in pulses], bool)
        est = np.array([wall_of.get(id(p), 0.0) for p in pulses])
        source = "firmware"
    else:  # the host's wall fit on the device's ToF records, per placement
        valid, est = np.zeros(len(pulses), bool), np.zeros(len(pulses))
        for shift in sorted({p.shift for p in pulses}):
            idx = [k for k, p in enumerate(pulses) if p.shift == shift]
            v, e = _host_walls(layout, pulses[idx[0]].tx[0], pulses[idx[0]].rx, [pulses[k].firsts for k in idx], c)
            valid[idx], est[idx] = v, e
        source = "host fit on the device's ToF"
    shifts = run.reaims(0)
    final = shifts[-1] if shifts else 0
    sel0 = np.array([p.shift == 0 for p in pulses], bool)
    sel1 = np.array([p.shift == final for p in pulses], bool)
    gold = simulate_scene(scene, [sensor], SCENE_MODEL_S, seed=seed)
    end = int(round(SCENE_MODEL_S * TICK_HZ))
    gv, ge = _host_walls(layout, tx, list(rx), [pe.tofs for pe in gold.echoes if pe.close < end], c)
    # receivers with a first echo on at least half of the configured groups' pulses
    p0 = [p for p in pulses if p.shift == 0]
    heard = [r for r in rx if 2 * sum(r in p.firsts for p in p0) >= max(len(p0), 1)]
    return {"orientation_deg": orientation_deg, "config": config, "source": source,
            "shifts": run.placements(0), "final_shift": final,
            "heard": f"{len(heard)} of {len(rx)}",
            "fixed": _err_stats(valid[sel0], est[sel0], na), "reaimed": _err_stats(valid[sel1], est[sel1], na),
            "scene_model": _err_stats(gv, ge, na), "pulses": len(run.pulses), "fw_fixes": len(run.fixes),
            "sonar_s": run.sonar_s, "wall_s": run.wall_s, "health": run.fw_healthy()}


def twin_orientations(orient: list[float], quick: bool) -> list[float]:
    """The model's orientations that also run on the twin."""
    if quick:
        return [o for o in orient if any(abs(o - t) < 1e-9 for t in TWIN_ORIENT_QUICK)]
    return [o for o in orient if abs(math.remainder(o - orient[0], TWIN_ORIENT_STEP)) < 1e-9]


def run(executor: Executor, *, quick: bool = False, cases: int | None = None, step_deg: float | None = None,
        distance_m: float = 1.0, sigma_us: float = 1.0, seed: int = 9, progress: bool = True,
        backend: str = "model", twin_orient: list[float] | None = None,
        twin_configs: list[str] | None = None) -> ExperimentResult:
    """``twin_orient`` / ``twin_configs``: the orientations (of the model's) and configurations the twin
    runs [TWIN_ORIENT_QUICK with ``quick``, else every TWIN_ORIENT_STEP; both configurations]."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r} for fig9; known: {', '.join(BACKENDS)}")
    cases = cases or (300 if quick else 2000)
    step = step_deg or (15.0 if quick else 5.0)
    orient = [float(o) for o in np.arange(45.0, 135.0 + 1e-9, step)]
    tasks = [{"orientation_deg": o, "cases": cases, "distance_m": distance_m, "sigma_us": sigma_us, "seed": seed}
             for o in orient]
    rows = [r for part in run_sweep(executor, orientation_point, tasks, label="fig9", progress=progress) for r in part]
    twin_cases: list[dict[str, Any]] = []
    t_twin = time.time()
    if backend == "twin":
        t_orient = twin_orientations(orient, quick) if twin_orient is None else \
            [o for o in orient if any(abs(o - t) < 1e-9 for t in twin_orient)]
        bad = [c for c in (twin_configs or []) if c not in CONFIGS]
        if bad or not t_orient:
            raise ValueError(f"twin cases: configurations {bad} unknown (known: {', '.join(CONFIGS)})" if bad else
                             f"twin cases: none of the orientations {twin_orient} is one of the model's {orient}")
        # one twin per case, as many at once as the executor has workers (each its own process)
        tasks = [{"orientation_deg": o, "config": c, "distance_m": distance_m, "seed": seed, "progress": False}
                 for o in t_orient for c in (twin_configs or CONFIGS)]
        twin_cases = run_sweep(executor, twin_case, tasks, label="fig9 twin", progress=progress)
    t_twin = time.time() - t_twin
    tw_of = {(t["orientation_deg"], t["config"]): t for t in twin_cases}
    for r in rows:
        t = tw_of.get((r["orientation_deg"], r["config"]))
        st = (t["reaimed"] if r["reaim"] else t["fixed"]) if t else {}
        r.update({f"twin_{k}": st.get(k, float("nan")) for k in TWIN_STATS})
        r["twin_source"] = t["source"] if t else ""
        r["twin_shifts"] = (t["shifts"] if r["reaim"] else "0") if t else ""
        sm = t["scene_model"] if t and not r["reaim"] else {}
        r.update({f"scene_model_{k}": sm.get(k, float("nan")) for k in ("valid_frac", "mean_deg", "std_deg")})

    def key(cfg: str, reaim: bool) -> str:
        return f"{cfg}, {'re-aimed' if reaim else 'fixed'}"

    def cell(st: dict[str, Any], n: bool = False) -> str:
        miss = f"{1 - st['valid_frac']:.0%} miss" + (f" of {st['n']}" if n else "")
        if not np.isfinite(st["mean_deg"]):
            return f"-, {miss}"
        return f"{st['mean_deg']:+.3f} / {st['std_deg']:.3f} / {st['max_abs_deg']:.3f}, {miss}"

    keys = [key(c, a) for c in CONFIGS for a in (False, True)]
    twin_keys = [f"twin: {k}" for k in keys] if twin_cases else []
    wide = []
    for o in orient:
        line: dict[str, Any] = {"o": o}
        for r in rows:
            if r["orientation_deg"] == o:
                k = key(r["config"], r["reaim"])
                line[k] = cell(r)
                t = tw_of.get((o, r["config"]))
                if t is not None:
                    st = t["reaimed"] if r["reaim"] else t["fixed"]
                    line[f"twin: {k}"] = cell(st, n=True) + (f" [{t['shifts']}]" if r["reaim"] else "")
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
        md_table([("o", "orientation (deg)")] + [(k, k) for k in keys + twin_keys], wide, {"o": ".0f"}), "",
        "Summary (deg; paper: max abs error ~0.5 deg in 75..115 deg, std 0.25 deg, severe outliers outside):", "",
        md_table([("what", "configuration"), ("core_max", "75..115: max abs"), ("core_std", "75..115: mean std"),
                  ("out_rms", "outside: rms"), ("all_rms", "45..135: rms"), ("all_max", "45..135: max abs"),
                  ("miss", "miss rate")], summ_rows,
                 {"core_max": ".3f", "core_std": ".3f", "out_rms": ".3f", "all_rms": ".3f", "all_max": ".3f", "miss": ".1%"}),
        "", _twin_note(twin_cases, rows, orient, t_twin), ""])

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
               "mean_deg", "std_deg", "max_abs_deg", "rms_deg", "twin_source", "twin_shifts"] \
        + [f"twin_{k}" for k in TWIN_STATS] + ["scene_model_valid_frac", "scene_model_mean_deg", "scene_model_std_deg"]
    summary["backend"] = backend
    json_data = None
    if twin_cases:
        summary["twin"] = twin_cases
        summary["twin_wall_s"] = t_twin
        json_data = {"summary": summary, "rows": rows}
    return ExperimentResult("fig9", "wall angle error vs orientation", columns, rows, md, plot, summary=summary,
                            json_data=json_data)


def _twin_note(twin_cases: list[dict[str, Any]], rows: list[dict[str, Any]], orient: list[float], wall_s: float) -> str:
    """The twin's part of the report: what its columns are, the case table, what it cannot do."""
    if not twin_cases:
        return "Twin columns: not run (`--backend twin` runs a few orientations on the full-system twin)."
    t_orient = sorted({t["orientation_deg"] for t in twin_cases})
    sonar = sum(t["sonar_s"] for t in twin_cases)
    model = {(r["orientation_deg"], r["config"]): r for r in rows if not r["reaim"]}

    def st(s: dict[str, Any]) -> str:
        if not np.isfinite(s["mean_deg"]):
            return f"-, {1 - s['valid_frac']:.0%} miss of {s['n']}"
        return f"{s['mean_deg']:+.2f} / {s['std_deg']:.2f}, {1 - s['valid_frac']:.0%} miss of {s['n']}"

    case_rows = [{"o": t["orientation_deg"], "cfg": t["config"], "src": t["source"], "groups": t["shifts"],
                  "heard": t["heard"],
                  "model": st(model[(t["orientation_deg"], t["config"])]), "scene": st(t["scene_model"]),
                  "fixed": st(t["fixed"]), "reaimed": st(t["reaimed"]), "sonar": t["sonar_s"], "wall": t["wall_s"],
                  "health": ", ".join(t["health"]) or "ok"} for t in twin_cases]
    skipped = [o for o in orient if o not in t_orient]
    return "\n".join([
        "Twin columns (`--backend twin`): the full-system twin (RTL sonar core and scheduler, VexRiscv firmware, USB "
        "device, the driver in-process) on the wall_1m scene with this wall (acoustic model: 1 us jitter, fading, "
        f"spurious pulses), at {', '.join(f'{o:g}' for o in t_orient)} deg. Cells as the model's, over the device's "
        "complete pulses (init pings included), n = pulses. 3 rx: the firmware's wall records; a pulse without one "
        "(classed edge or uncertain, or not fixed) is a miss. 2 rx: the host's wall fit (as the model's) on the "
        "device's ToF records: the firmware fixes three receivers or more, so it never re-aims a 2-receiver sensor "
        "and its re-aimed cell is its fixed one. Twin 're-aimed' is the firmware's own re-aim, not the experiment's "
        "(an offline re-measurement of the pair facing the wall): [groups] = the shifts its groups went through "
        "(elements, + = counter-clockwise). The firmware moves them one element when a fix is more than "
        "10 deg off the transmitter's axis (0 deg for element 0, where the experiment's 75..115 deg interval is "
        "centred on the pair's 7.5 deg), re-checks after a 100 ms hold-off, and has no scan for a sensor without "
        "fixes. Where only two of three receivers hear the wall the model's Monte Carlo fits the two (its 3 rx cell is "
        "a 2-receiver fit there) while the firmware declines the subset (the general path is not in its image): "
        "the device then has no fix and no reason to re-aim.",
        "",
        md_table([("o", "orientation (deg)"), ("cfg", "config"), ("src", "twin angle from"), ("groups", "groups"),
                  ("heard", "receivers hearing (configured groups)"),
                  ("model", "model, fixed: mean / std"), ("scene", "golden model, same scene: mean / std"),
                  ("fixed", "twin, configured groups"), ("reaimed", "twin, final groups"),
                  ("sonar", "sonar s"), ("wall", "wall s"), ("health", "device / harness")], case_rows,
                 {"o": ".0f", "sonar": ".3f", "wall": ".1f"}),
        "",
        f"Golden model, same scene: the scene and sensor on the tick-exact model for {SCENE_MODEL_S} s (no re-aim; "
        "the same estimator as the twin's column). Twin: "
        f"{len(twin_cases)} cases, {sonar:.2f} s of sonar time in {wall_s:.0f} s wall"
        f" ({sonar / max(wall_s, 1e-9):.4f} sonar-s per wall-s, boots included)."
        + (f" Not run on the twin (`-`): {', '.join(f'{o:g}' for o in skipped)} deg." if skipped else "")])


def _half() -> float:
    from ..layout import load_layout

    return float(load_layout().transducer.beam_half_angle)
