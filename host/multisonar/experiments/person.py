"""Person crossing: the safety property of fast firing, and tracking a walking person.

Scene ``person_crossing``: the robot drives at 1 m/s parallel to a wall 1.5 m to its left and
tracks it with the virtual sensor ``left`` (transmitter 6, receivers 5, 6, 7, fast firing of
order 2); a person (cylinder, radius 0.2 m) walks the other way at 1.2 m/s between robot and
wall. When the person steps in front of the tracked wall, the wall's windows stay empty; after
K (``miss_limit``) empty windows the sensor goes back to an initialisation ping with an open
window, which reports the person. Measured for each K:

* occluder detection latency: from the first pulse whose first echo (acoustic ground truth,
  ``AcousticModel.truth``) comes from the person, to the first ToF event at the person's
  range (within 0.1 ms of the true arrival); in ms and in pulses of the sensor;
* track: the person fixes (3-receiver point fits, world frame through the robot pose),
  their distance to the person's surface, the velocity estimated by a least-squares line over
  the track against the true 1.2 m/s, and the path predicted 0.5 s ahead from it.
"""

from __future__ import annotations

import math
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import TICK_HZ
from .common import ExperimentResult, batch_fixes, md_table, robot_to_world, simulate_scene
from .executor import run_sweep

SENSOR = ("left", [6], [5, 6, 7])
TOF_TOL_S = 0.1e-3
PREDICT_S = 0.5
PERSON_RADIUS_M = 0.2  #: the tracker's person model (a prior, not read from the scene)


def crossing_task(miss_limit: int, order: int, t_offset_s: float, duration_s: float, seed: int) -> dict[str, Any]:
    from ..acoustics import AcousticModel, Firing, PulseKind
    from ..scene import load_scene
    from ..schedule import VirtualSensor

    scene = load_scene("person_crossing")
    name, tx, rx = SENSOR
    sensor = VirtualSensor(name, tx=tx, rx=rx, order=order, miss_limit=miss_limit)
    run = simulate_scene(scene, [sensor], duration_s, t_offset_s=t_offset_s, seed=seed)
    c = scene.speed_of_sound
    person_idx = scene.reflector_index("person")
    wall_idx = scene.reflector_index("wall")
    truth_model = AcousticModel(scene, rng=np.random.default_rng(0))
    thr = scene.noise.threshold
    # ground truth per pulse: first echo source per receiver, person arrival (ticks after t0)
    pulses = []
    for p in run.pulses:
        t0s = t_offset_s + p.t0 / TICK_HZ
        tr = truth_model.truth(Firing.single(t0s, tx[0]))
        tr = tr[(tr["kind"] == PulseKind.ECHO) & (tr["amplitude"] >= thr)]
        first_person, person_tof, wall_rx = False, {}, set()
        for r in rx:
            e = tr[tr["rx"] == r]
            if len(e):
                first_person |= int(e["source"][np.argmin(e["arrival"])]) == person_idx
                pe = e[e["source"] == person_idx]
                if len(pe):
                    person_tof[r] = float((pe["arrival"].min() - t0s) * TICK_HZ)
                if np.any(e["source"] == wall_idx):
                    wall_rx.add(r)
        pulses.append({"seq": p.seq, "t0": p.t0, "init": p.init, "person_first": first_person, "person_tof": person_tof,
                       "occluded": first_person and len(wall_rx) < len(rx)})
    audible = next((q for q in pulses if q["person_first"]), None)
    onset = next((q for q in pulses if q["occluded"]), None)
    det_tick, det_pulse = None, None
    if onset is not None:
        by_seq = {q["seq"]: q for q in pulses}
        for pe in run.echoes:  # echoes are in pulse order
            if pe.t0 < onset["t0"]:
                continue
            q = by_seq[pe.seq]
            hits = [pe.t0 + t for r, t in pe.tofs.items() if r in q["person_tof"]
                    and abs(t - q["person_tof"][r]) <= TOF_TOL_S * TICK_HZ]
            if hits:
                det_tick, det_pulse = min(hits), pe.seq
                break
    # person fixes: point fits near the person's true position
    track = []
    for fx in batch_fixes(scene.layout, run.resolved, run.echoes, c):
        if not fx.point_valid or fx.kind == "wall":
            continue
        t_ref = t_offset_s + (fx.echo.t0 + float(np.mean(list(fx.echo.tofs.values()))) / 2) / TICK_HZ
        pw = robot_to_world(scene, t_ref, fx.point)
        centre = scene.people_positions(t_ref)[0]
        radius = scene.people[0].radius
        if abs(float(np.linalg.norm(pw - centre)) - radius) < 0.15:
            # centre estimate: the echo comes from the nearest surface point, so the centre lies a
            # person radius (the tracker's prior, PERSON_RADIUS_M) further along the ray from the source
            sw = robot_to_world(scene, t_ref, scene.layout.positions[tx[0]])
            u = (pw - sw) / max(float(np.linalg.norm(pw - sw)), 1e-9)
            ce = pw + PERSON_RADIUS_M * u
            track.append({"t_s": t_ref, "x_m": float(ce[0]), "y_m": float(ce[1]), "kind": fx.kind,
                          "surface_err_m": abs(float(np.linalg.norm(pw - centre)) - radius),
                          "centre_err_m": float(np.linalg.norm(ce - centre)),
                          "cx_m": float(centre[0]), "cy_m": float(centre[1])})
    events = [{"t_s": t_offset_s + e.tick / TICK_HZ, "tof_ms": e.tof / TICK_HZ * 1e3, "rx": e.rx,
               "init": e.init_ping, "empty": e.window_empty} for e in run.events if e.first_echo or e.window_empty]
    return {"miss_limit": miss_limit, "order": order, "t_offset_s": t_offset_s, "duration_s": duration_s,
            "onset_t0": None if onset is None else onset["t0"], "det_tick": det_tick,
            "audible_t0": None if audible is None else audible["t0"],
            "latency_pulses": None if onset is None or det_pulse is None else det_pulse - onset["seq"] + 1,
            "period_ms": float(np.median(np.diff([q["t0"] for q in pulses if not q["init"]]))) / TICK_HZ * 1e3
            if sum(not q["init"] for q in pulses) > 2 else float("nan"),
            "n_pulses": len(pulses), "n_init": sum(q["init"] for q in pulses), "track": track, "events": events,
            "truth_person_first": [(t_offset_s + q["t0"] / TICK_HZ, q["person_first"]) for q in pulses],
            "wall_s": run.wall_s}


def _velocity(track: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares line through the track: (velocity, position at mean time, mean time)."""
    t = np.array([p["t_s"] for p in track])
    xy = np.array([(p["x_m"], p["y_m"]) for p in track])
    tm = float(t.mean())
    A = np.stack([np.ones_like(t), t - tm], 1)
    coef, *_ = np.linalg.lstsq(A, xy, rcond=None)
    return coef[1], coef[0], tm


def run(executor: Executor, *, quick: bool = False, miss_limits: list[int] | None = None, order: int = 2,
        seed: int = 7, progress: bool = True) -> ExperimentResult:
    from ..scene import load_scene

    scene = load_scene("person_crossing")
    ks = miss_limits or ([2, 3] if quick else [1, 2, 3, 4])
    t_off, dur = (1.95, 0.6) if quick else (1.5, 1.6)
    tasks = [{"miss_limit": k, "order": order, "t_offset_s": t_off, "duration_s": dur, "seed": seed} for k in ks]
    parts = run_sweep(executor, crossing_task, tasks, label="person", progress=progress)
    p_path = scene.people[0].path
    t_mid = t_off + dur / 2
    v_truth = (p_path.at(t_mid + 1e-3) - p_path.at(t_mid - 1e-3)) / 2e-3
    rows = []
    for p in parts:
        lat_ms = (p["det_tick"] - p["onset_t0"]) / TICK_HZ * 1e3 if p["det_tick"] is not None and p["onset_t0"] is not None \
            else float("nan")
        aud_ms = (p["det_tick"] - p["audible_t0"]) / TICK_HZ * 1e3 if p["det_tick"] is not None \
            and p["audible_t0"] is not None else float("nan")
        row: dict[str, Any] = {"miss_limit": p["miss_limit"], "order": p["order"], "pulses": p["n_pulses"],
                               "audible_s": float("nan") if p["audible_t0"] is None else t_off + p["audible_t0"] / TICK_HZ,
                               "since_audible_ms": aud_ms,
                               "init_pings": p["n_init"], "period_ms": p["period_ms"],
                               "onset_s": float("nan") if p["onset_t0"] is None else t_off + p["onset_t0"] / TICK_HZ,
                               "latency_ms": lat_ms,
                               "latency_pulses": float("nan") if p["latency_pulses"] is None else p["latency_pulses"],
                               "track_fixes": len(p["track"])}
        tr = p["track"]
        if len(tr) >= 5:
            v, x0, tm = _velocity(tr)
            row.update(vx=float(v[0]), vy=float(v[1]), speed_err=float(np.linalg.norm(v) - np.linalg.norm(v_truth)),
                       dir_err_deg=math.degrees(math.remainder(math.atan2(v[1], v[0]) - math.atan2(v_truth[1], v_truth[0]),
                                                               2 * math.pi)),
                       surface_med_mm=float(np.median([q["surface_err_m"] for q in tr])) * 1e3,
                       centre_med_mm=float(np.median([q["centre_err_m"] for q in tr])) * 1e3)
            # prediction PREDICT_S ahead from the fit at the track's mean time, vs the true motion
            c_now = p_path.at(tm)
            c_then = p_path.at(tm + PREDICT_S)
            row["pred_err_mm"] = float(np.linalg.norm(x0 + v * PREDICT_S - (x0 + (c_then - c_now)))) * 1e3
            row["_fit"] = (v, x0, tm)
        else:
            row.update(vx=float("nan"), vy=float("nan"), speed_err=float("nan"), dir_err_deg=float("nan"),
                       surface_med_mm=float("nan"), centre_med_mm=float("nan"), pred_err_mm=float("nan"))
        rows.append(row)
    cols = [("miss_limit", "K (miss limit)"), ("order", "order"), ("pulses", "pulses"), ("init_pings", "init pings"),
            ("period_ms", "tracking period (ms)"), ("audible_s", "person audible at (s)"),
            ("onset_s", "wall occluded at (s)"), ("latency_ms", "detection latency (ms)"),
            ("latency_pulses", "latency (pulses)"), ("since_audible_ms", "since audible (ms)"),
            ("track_fixes", "person fixes"), ("surface_med_mm", "fix to surface median (mm)"),
            ("centre_med_mm", "centre estimate error median (mm)"),
            ("vx", "v_x (m/s)"), ("vy", "v_y (m/s)"), ("speed_err", "speed error (m/s)"),
            ("dir_err_deg", "direction error (deg)"), ("pred_err_mm", f"path predicted {PREDICT_S} s ahead: error (mm)")]
    fmt = {"period_ms": ".2f", "onset_s": ".3f", "audible_s": ".3f", "since_audible_ms": ".1f", "centre_med_mm": ".0f", "latency_ms": ".1f", "latency_pulses": ".0f", "surface_med_mm": ".1f",
           "vx": "+.3f", "vy": "+.3f", "speed_err": "+.3f", "dir_err_deg": "+.1f", "pred_err_mm": ".0f"}
    md = "\n".join([
        "# Person crossing: occluder detection latency, track, velocity, predicted path", "",
        f"Scene `person_crossing`, sonar time {t_off:.2f}..{t_off + dur:.2f} s; virtual sensor `{SENSOR[0]}` "
        f"(tx {SENSOR[1]}, rx {SENSOR[2]}, order {order}) tracking the wall; golden model. True person velocity "
        f"({v_truth[0]:+.2f}, {v_truth[1]:+.2f}) m/s (world). Latency: from the first pulse whose first echo comes "
        "from the person (acoustic ground truth) to the first ToF event at the person's range.", "",
        "Two onsets (acoustic ground truth): *audible* = the first pulse whose first echo on some receiver comes "
        "from the person (it may still be outside the wall's windows, the wall echo still present); *occluded* = "
        "the first pulse on which the person hides the wall from at least one receiver. Detection latency is "
        "counted from the occlusion (the safety property: an obstacle stepping in front of a tracked wall); "
        "'since audible' shows how long the windowing kept the person out while the wall stayed visible. "
        f"Person centre = fix + {PERSON_RADIUS_M} m (the tracker's person-radius prior) along the ray from the "
        "transmitter; the velocity is a least-squares line through those centres.", "",
        md_table(cols, rows, fmt), "",
        "Safety bound (checked by tests/test_experiments.py): after the occlusion the sensor needs K empty windows "
        "(plus the order-n pulses already in flight) to give up the track, then waits the quiet time before its "
        "initialisation ping (the echoes of its last pulse within MAX_TOF must not reach the open window), and the "
        "ping's echo returns after the person's ToF: latency <= (K + n) T_s + MAX_TOF + ToF_person.", ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        p = parts[min(range(len(parts)), key=lambda i: abs(parts[i]["miss_limit"] - 2))]
        row = rows[parts.index(p)]
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(9, 8), gridspec_kw={"height_ratios": [1, 1.1]})
        for (a, b) in scene.walls:
            ax.plot([a[0], b[0]], [a[1], b[1]], color="0.7", lw=3)
        ts = np.linspace(t_off, t_off + dur, 100)
        x, y, _ = scene.pose(ts)
        ax.plot(x, y, color="tab:blue", label="robot path")
        cp = p_path.at(ts)
        ax.plot(cp[:, 0], cp[:, 1], color="0.5", ls="--", label="person centre (truth)")
        tr = p["track"]
        if tr:
            ax.scatter([q["x_m"] for q in tr], [q["y_m"] for q in tr], s=8, color="tab:red", label="person centre estimates")
        if "_fit" in row:
            v, x0, tm = row["_fit"]
            end = x0 + v * PREDICT_S
            ax.annotate("", xy=end, xytext=x0, arrowprops={"arrowstyle": "->", "color": "tab:green", "lw": 2})
            ax.plot([], [], color="tab:green", label=f"predicted path ({PREDICT_S} s)")
        ax.set_aspect("equal")
        ax.set_xlim(min(x.min(), cp[:, 0].min()) - 0.5, max(x.max(), cp[:, 0].max()) + 0.5)
        ax.set_ylim(-0.6, 1.8)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(fontsize=7, loc="lower right")
        ax.set_title(f"person crossing, K = {p['miss_limit']}, order {p['order']}")
        ev = p["events"]
        for kind, sel, st in (("in-window sample", lambda e: not e["empty"] and not e["init"], dict(s=6, color="tab:blue")),
                              ("init-ping echo", lambda e: not e["empty"] and e["init"], dict(s=14, color="tab:orange")),
                              ("empty window", lambda e: e["empty"], dict(s=6, color="0.6", marker="x"))):
            es = [e for e in ev if sel(e)]
            ax2.scatter([e["t_s"] for e in es], [e["tof_ms"] for e in es], label=kind, **st)
        pf = [t for t, f in p["truth_person_first"] if f]
        if pf:
            ax2.axvspan(min(pf), max(pf), color="tab:red", alpha=0.1, label="person audible (truth)")
        if p["onset_t0"] is not None:
            ax2.axvline(t_off + p["onset_t0"] / TICK_HZ, color="k", lw=1, ls=":", label="wall occluded (truth)")
        if p["det_tick"] is not None:
            ax2.axvline(t_off + p["det_tick"] / TICK_HZ, color="tab:red", lw=1, label="person detected")
        ax2.set_xlabel("scene time (s)")
        ax2.set_ylabel("time of flight (ms)")
        ax2.legend(fontsize=7)
        ax2.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)

    columns = [k for k, _ in cols]
    track_rows = [{"miss_limit": p["miss_limit"], **q} for p in parts for q in p["track"]]
    return ExperimentResult("person", "person crossing", columns, rows, md, plot,
                            summary={"rows": rows, "v_truth": v_truth},
                            extra_csv={"person_track": (["miss_limit", "t_s", "x_m", "y_m", "kind", "surface_err_m",
                                                         "centre_err_m", "cx_m", "cy_m"], track_rows)})
