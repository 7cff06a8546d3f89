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

Twin backend (``backend="twin"``): each K also runs on the full-system twin (:func:`twin_crossing`,
a shorter window, ``TWIN_WINDOW_QUICK`` / ``TWIN_WINDOW``), its rows next to the model's.
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
BACKENDS = ("model", "twin")
#: the twin's sonar time (scene time start, duration): it starts where the model does, on the
#: wall before the person is audible (1.98 s); --quick stops ~0.15 s after the detection
#: (occlusion 2.15 s), the full run covers the model's --quick window
TWIN_WINDOW_QUICK = (1.95, 0.40)
TWIN_WINDOW = (1.95, 0.60)


def _pulse_truth(truth_model: Any, scene: Any, t0_s: float, tx: int, rx: list[int], thr: float) -> dict[str, Any]:
    """Acoustic ground truth of one pulse of ``tx`` at scene time ``t0_s``: whether the person's
    echo is the first on some receiver, its arrival per receiver (ticks after t0), and whether
    it hides the wall from a receiver."""
    from ..acoustics import Firing, PulseKind

    person_idx, wall_idx = scene.reflector_index("person"), scene.reflector_index("wall")
    tr = truth_model.truth(Firing.single(t0_s, tx))
    tr = tr[(tr["kind"] == PulseKind.ECHO) & (tr["amplitude"] >= thr)]
    first_person, person_tof, wall_rx = False, {}, set()
    for r in rx:
        e = tr[tr["rx"] == r]
        if len(e):
            first_person |= int(e["source"][np.argmin(e["arrival"])]) == person_idx
            pe = e[e["source"] == person_idx]
            if len(pe):
                person_tof[r] = float((pe["arrival"].min() - t0_s) * TICK_HZ)
            if np.any(e["source"] == wall_idx):
                wall_rx.add(r)
    return {"person_first": first_person, "person_tof": person_tof,
            "occluded": first_person and len(wall_rx) < len(rx)}


def _onset_and_detection(pulses: list[dict[str, Any]]) -> tuple[Any, Any, int | None, int | None]:
    """(first audible pulse, first occluding pulse, detection tick, detecting pulse's number):
    the detection is the first ToF sample (``firsts``: rx -> ticks after t0) at the person's
    true range (within TOF_TOL_S) on a pulse from the occlusion on. Pulses in firing order."""
    audible = next((q for q in pulses if q["person_first"]), None)
    onset = next((q for q in pulses if q["occluded"]), None)
    if onset is not None:
        for q in pulses:
            if q["t0"] < onset["t0"]:
                continue
            hits = [q["t0"] + t for r, t in q["firsts"].items() if r in q["person_tof"]
                    and abs(t - q["person_tof"][r]) <= TOF_TOL_S * TICK_HZ]
            if hits:
                return audible, onset, min(hits), q["seq"]
    return audible, onset, None, None


def _track_point(scene: Any, t_ref: float, point_robot: Any, tx: int, kind: str) -> dict[str, Any] | None:
    """A person fix (robot frame) near the person's true surface at the reflection instant, as a
    centre estimate; None for a fix of something else."""
    pw = robot_to_world(scene, t_ref, point_robot)
    centre = scene.people_positions(t_ref)[0]
    radius = scene.people[0].radius
    if abs(float(np.linalg.norm(pw - centre)) - radius) >= 0.15:
        return None
    # centre estimate: the echo comes from the nearest surface point, so the centre lies a
    # person radius (the tracker's prior, PERSON_RADIUS_M) further along the ray from the source
    sw = robot_to_world(scene, t_ref, scene.layout.positions[tx])
    u = (pw - sw) / max(float(np.linalg.norm(pw - sw)), 1e-9)
    ce = pw + PERSON_RADIUS_M * u
    return {"t_s": t_ref, "x_m": float(ce[0]), "y_m": float(ce[1]), "kind": kind,
            "surface_err_m": abs(float(np.linalg.norm(pw - centre)) - radius),
            "centre_err_m": float(np.linalg.norm(ce - centre)), "cx_m": float(centre[0]), "cy_m": float(centre[1])}


def _part(miss_limit: int, order: int, t_offset_s: float, duration_s: float, pulses: list[dict[str, Any]],
          track: list[dict[str, Any]], events: list[dict[str, Any]], wall_s: float, **extra: Any) -> dict[str, Any]:
    """One case's measurements (model or twin) from its pulses in firing order (seq, t0 in ticks
    from the case's start, init, firsts and the ground truth), its track and its events."""
    audible, onset, det_tick, det_pulse = _onset_and_detection(pulses)
    track_t0 = [q["t0"] for q in pulses if not q["init"]]
    return {"miss_limit": miss_limit, "order": order, "t_offset_s": t_offset_s, "duration_s": duration_s,
            "onset_t0": None if onset is None else onset["t0"], "det_tick": det_tick,
            "audible_t0": None if audible is None else audible["t0"],
            "latency_pulses": None if onset is None or det_pulse is None else det_pulse - onset["seq"] + 1,
            "period_ms": float(np.median(np.diff(track_t0))) / TICK_HZ * 1e3 if len(track_t0) > 2 else float("nan"),
            "n_pulses": len(pulses), "n_init": sum(q["init"] for q in pulses), "track": track, "events": events,
            "truth_person_first": [(t_offset_s + q["t0"] / TICK_HZ, q["person_first"]) for q in pulses],
            "wall_s": wall_s, **extra}


def crossing_task(miss_limit: int, order: int, t_offset_s: float, duration_s: float, seed: int) -> dict[str, Any]:
    """One K on the golden model."""
    from ..acoustics import AcousticModel
    from ..scene import load_scene
    from ..schedule import VirtualSensor

    scene = load_scene("person_crossing")
    name, tx, rx = SENSOR
    sensor = VirtualSensor(name, tx=tx, rx=rx, order=order, miss_limit=miss_limit)
    run = simulate_scene(scene, [sensor], duration_s, t_offset_s=t_offset_s, seed=seed)
    truth_model = AcousticModel(scene, rng=np.random.default_rng(0))
    thr = scene.noise.threshold
    pulses = [{"seq": pe.seq, "t0": pe.t0, "init": pe.init, "firsts": pe.tofs,
               **_pulse_truth(truth_model, scene, t_offset_s + pe.t0 / TICK_HZ, tx[0], rx, thr)} for pe in run.echoes]
    # person fixes: point fits near the person's true position
    track = []
    for fx in batch_fixes(scene.layout, run.resolved, run.echoes, scene.speed_of_sound):
        if not fx.point_valid or fx.kind == "wall":
            continue
        t_ref = t_offset_s + (fx.echo.t0 + float(np.mean(list(fx.echo.tofs.values()))) / 2) / TICK_HZ
        pt = _track_point(scene, t_ref, fx.point, tx[0], fx.kind)
        if pt is not None:
            track.append(pt)
    events = [{"t_s": t_offset_s + e.tick / TICK_HZ, "tof_ms": e.tof / TICK_HZ * 1e3, "rx": e.rx,
               "init": e.init_ping, "empty": e.window_empty} for e in run.events if e.first_echo or e.window_empty]
    return _part(miss_limit, order, t_offset_s, duration_s, pulses, track, events, run.wall_s, backend="model")


def twin_crossing(miss_limit: int, order: int, t_offset_s: float, duration_s: float, seed: int,
                  progress: bool = True) -> dict[str, Any]:
    """One K on the full-system twin: the sensor configured through the driver, started at scene
    time ``t_offset_s``; latency from the device's ToF frames (the ground truth of the pulses it
    fired, with the groups it fired them with), the track from the firmware's geometry records
    (edge, or uncertain with the point fit's position: the firmware has no cylinder class)."""
    from ..acoustics import AcousticModel
    from ..scene import load_scene
    from ..schedule import VirtualSensor
    from .twin_backend import run_on_twin

    scene = load_scene("person_crossing")
    name, tx, rx = SENSOR
    sensor = VirtualSensor(name, tx=tx, rx=rx, order=order, miss_limit=miss_limit)
    run = run_on_twin(scene, [sensor], duration_s, t_offset_s=t_offset_s, seed=seed, progress=progress,
                      label=f"person twin: K = {miss_limit}")
    truth_model = AcousticModel(scene, rng=np.random.default_rng(0))
    thr = scene.noise.threshold
    pulses = [{"seq": p.index, "t0": p.t0, "init": p.init, "firsts": p.firsts,
               **_pulse_truth(truth_model, scene, p.t_s, p.tx[0], p.rx, thr)} for p in run.pulses]
    track = []
    for f in run.fixes:
        if f.kind in ("edge", "uncertain") and f.pulse is not None and f.pulse.firsts:
            pt = _track_point(scene, f.t_ref, f.xy, f.pulse.tx[0], f.kind)
            if pt is not None:
                track.append(pt)
    events = []
    for p in run.pulses:
        events += [{"t_s": p.t_s + t / TICK_HZ, "tof_ms": t / TICK_HZ * 1e3, "rx": r, "init": p.init, "empty": False}
                   for r, t in p.firsts.items()]
        events += [{"t_s": p.t_s, "tof_ms": 0.0, "rx": r, "init": p.init, "empty": True} for r in p.empty]
    return _part(miss_limit, order, t_offset_s, run.sonar_s, pulses, track, events, run.wall_s, backend="twin",
                 groups=run.placements(0), health=run.fw_healthy())


def _velocity(track: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares line through the track: (velocity, position at mean time, mean time)."""
    t = np.array([p["t_s"] for p in track])
    xy = np.array([(p["x_m"], p["y_m"]) for p in track])
    tm = float(t.mean())
    A = np.stack([np.ones_like(t), t - tm], 1)
    coef, *_ = np.linalg.lstsq(A, xy, rcond=None)
    return coef[1], coef[0], tm


def _row(p: dict[str, Any], p_path: Any, v_truth: np.ndarray) -> dict[str, Any]:
    """The table's row of one case (model or twin)."""
    t_off = p["t_offset_s"]
    lat_ms = (p["det_tick"] - p["onset_t0"]) / TICK_HZ * 1e3 \
        if p["det_tick"] is not None and p["onset_t0"] is not None else float("nan")
    aud_ms = (p["det_tick"] - p["audible_t0"]) / TICK_HZ * 1e3 if p["det_tick"] is not None \
        and p["audible_t0"] is not None else float("nan")
    row: dict[str, Any] = {"backend": p["backend"], "window_s": f"{t_off:.2f}..{t_off + p['duration_s']:.2f}",
                           "groups": p.get("groups", "-"),
                           "miss_limit": p["miss_limit"], "order": p["order"], "pulses": p["n_pulses"],
                           "audible_s": float("nan") if p["audible_t0"] is None else t_off + p["audible_t0"] / TICK_HZ,
                           "since_audible_ms": aud_ms,
                           "init_pings": p["n_init"], "period_ms": p["period_ms"],
                           "onset_s": float("nan") if p["onset_t0"] is None else t_off + p["onset_t0"] / TICK_HZ,
                           "latency_ms": lat_ms,
                           "latency_pulses": float("nan") if p["latency_pulses"] is None else p["latency_pulses"],
                           "track_fixes": len(p["track"]), "wall_s": p["wall_s"]}
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
    return row


def run(executor: Executor, *, quick: bool = False, miss_limits: list[int] | None = None, order: int = 2,
        seed: int = 7, progress: bool = True, backend: str = "model",
        twin_window: tuple[float, float] | None = None) -> ExperimentResult:
    """``twin_window``: (scene time at START, sonar time) of the twin's runs [TWIN_WINDOW_QUICK with
    ``quick``, else TWIN_WINDOW]."""
    from ..scene import load_scene

    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r} for person; known: {', '.join(BACKENDS)}")
    scene = load_scene("person_crossing")
    ks = miss_limits or ([2, 3] if quick else [1, 2, 3, 4])
    t_off, dur = (1.95, 0.6) if quick else (1.5, 1.6)
    tasks = [{"miss_limit": k, "order": order, "t_offset_s": t_off, "duration_s": dur, "seed": seed} for k in ks]
    parts = run_sweep(executor, crossing_task, tasks, label="person", progress=progress)
    twin_parts = []
    tw_off, tw_dur = twin_window or (TWIN_WINDOW_QUICK if quick else TWIN_WINDOW)
    if backend == "twin":
        # one twin per K, as many at once as the executor has workers (each its own process)
        twin_parts = run_sweep(executor, twin_crossing,
                               [{"miss_limit": k, "order": order, "t_offset_s": tw_off, "duration_s": tw_dur,
                                 "seed": seed, "progress": False} for k in ks],
                               label="person twin", progress=progress)
    p_path = scene.people[0].path
    t_mid = t_off + dur / 2
    v_truth = (p_path.at(t_mid + 1e-3) - p_path.at(t_mid - 1e-3)) / 2e-3
    rows = [_row(p, p_path, v_truth) for p in parts + twin_parts]
    cols = [("backend", "backend"), ("window_s", "sonar time (s)"), ("groups", "groups"),
            ("miss_limit", "K (miss limit)"), ("order", "order"), ("pulses", "pulses"), ("init_pings", "init pings"),
            ("period_ms", "tracking period (ms)"), ("audible_s", "person audible at (s)"),
            ("onset_s", "wall occluded at (s)"), ("latency_ms", "detection latency (ms)"),
            ("latency_pulses", "latency (pulses)"), ("since_audible_ms", "since audible (ms)"),
            ("track_fixes", "person fixes"), ("surface_med_mm", "fix to surface median (mm)"),
            ("centre_med_mm", "centre estimate error median (mm)"),
            ("vx", "v_x (m/s)"), ("vy", "v_y (m/s)"), ("speed_err", "speed error (m/s)"),
            ("dir_err_deg", "direction error (deg)"),
            ("pred_err_mm", f"path predicted {PREDICT_S} s ahead: error (mm)"), ("wall_s", "wall s")]
    fmt = {"period_ms": ".2f", "onset_s": ".3f", "audible_s": ".3f", "since_audible_ms": ".1f", "centre_med_mm": ".0f",
           "latency_ms": ".1f", "latency_pulses": ".0f", "surface_med_mm": ".1f", "vx": "+.3f", "vy": "+.3f",
           "speed_err": "+.3f", "dir_err_deg": "+.1f", "pred_err_mm": ".0f", "wall_s": ".1f"}
    if twin_parts:
        sonar = sum(p["duration_s"] for p in twin_parts)
        wall = sum(p["wall_s"] for p in twin_parts)
        bad = sorted({h for p in twin_parts for h in p["health"]})
        twin_note = (
            "Twin rows (`--backend twin`): the full-system twin (RTL scheduler and receivers, VexRiscv firmware, USB "
            "device, the driver in-process) on the same scene, the sensor configured through the driver and started "
            f"at scene time {tw_off:.2f} s (the golden model's window: {t_off:.2f} s), {tw_dur:.2f} s of sonar time "
            "per K. Onsets from the acoustic ground truth of the pulses the device fired (with the groups it fired "
            "them with), detection from its ToF frames, the track from the firmware's geometry records (edge, or "
            "uncertain with the point fit's position: the firmware has no cylinder class). The firmware re-aims on "
            "its own (a fix more than 10 deg off the transmitter's axis moves the groups one element): 'groups' = "
            "the shifts the sensor went through (elements; the model keeps element 6); a move restarts the sensor "
            "with an init ping. The twin's noise is drawn per pulse, so its pulses see other noise than the model's. "
            "The tracking period is the median over the window: the wall at order 2 (4.7 ms) before the detection, "
            "the person (~3 ms) after it, in other shares in the shorter window. "
            f"Twin: {len(twin_parts)} runs, {sonar:.2f} s of sonar time in {wall:.0f} s of run time summed over the "
            f"runs ({sonar / max(wall, 1e-9):.4f} sonar-s per wall-s of one twin, boots included; with --workers they "
            f"run side by side, one twin per process); device / harness: "
            f"{', '.join(bad) or 'nothing dropped, lost or clipped'}.")
    else:
        twin_note = "Twin rows: not run (`--backend twin` runs each K on the full-system twin)."
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
        "ping's echo returns after the person's ToF: latency <= (K + n) T_s + MAX_TOF + ToF_person.", "",
        twin_note, ""])

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
        tw = [q for t in twin_parts if t["miss_limit"] == p["miss_limit"] for q in t["track"]]
        if tw:
            ax.scatter([q["x_m"] for q in tw], [q["y_m"] for q in tw], s=14, facecolors="none", edgecolors="tab:purple",
                       label="person centre estimates (twin)")
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
    track_rows = [{"backend": p["backend"], "miss_limit": p["miss_limit"], **q} for p in parts + twin_parts
                  for q in p["track"]]
    summary = {"rows": rows, "v_truth": v_truth, "backend": backend}
    json_data = None
    if twin_parts:
        json_data = {"summary": {"backend": backend, "v_truth": v_truth, "twin_window_s": [tw_off, tw_dur],
                                 "model_window_s": [t_off, dur]},
                     "rows": [{k: v for k, v in r.items() if not k.startswith("_")} for r in rows]}
    return ExperimentResult("person", "person crossing", columns, rows, md, plot, summary=summary,
                            extra_csv={"person_track": (["backend", "miss_limit", "t_s", "x_m", "y_m", "kind",
                                                         "surface_err_m", "centre_err_m", "cx_m", "cy_m"],
                                                        track_rows)},
                            json_data=json_data)
