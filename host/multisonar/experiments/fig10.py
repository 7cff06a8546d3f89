"""Paper Fig. 10: map building while localising on a-priori known walls (corridor scene).

The golden model (acoustics -> tick-exact fast firing -> per-pulse geometry, as ``multisonar
demo``) runs the demo's five virtual sensors along the corridor path. The sonar time is cut
into chunks that run as independent tasks on the executor (each starts with its own
initialisation pings at its scene time: the chunk boundaries cost one init ping per sensor).

* Map building: every edge / wall fix in world coordinates (pose at the reflection instant,
  t0 + ToF/2), its distance to the nearest true reflector.
* Localisation on known walls (the scene's walls except the door's back wall): a wall fix
  associated with a known wall (normal within 10 deg, foot within 0.3 m of the line, using the
  odometry pose) gives the robot's coordinate along that wall's normal and its heading; the
  errors against the true pose are tabulated per wall with the update rate and the longest gap
  between updates (the paper: at least every 10 ms, the locomotion controller's period).
"""

from __future__ import annotations

import math
import sys
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import TICK_HZ
from .common import ExperimentResult, batch_fixes, finite_stat, md_table, robot_to_world, simulate_scene, wrap_angle
from .executor import run_sweep

KNOWN_WALLS_EXCLUDE = ("door_back",)
BACKENDS = ("model", "twin")
#: sonar time of the twin's corridor at most (full runs; --quick: the model's 0.5 s): the straight
#: run past the door, as `make demo`
TWIN_MAX_S = 2.0
ASSOC_ANGLE = math.radians(10.0)
ASSOC_DIST = 0.3


def _map_fix(scene: Any, known: list[tuple[str, Any]], t_ref: float, sensor: str, kind: str, p_robot: Any,
             normal_robot: float) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """One wall or edge fix (robot frame: the wall's foot point and normal, or the edge's
    position) in the world with the pose at the reflection instant ``t_ref``, its distance to
    the nearest true reflector, and (a wall associated with a known wall) the localisation update."""
    from ..demo import _truth_distance

    px, py, ph = (float(v) for v in scene.pose(t_ref))
    p = robot_to_world(scene, t_ref, p_robot)
    if kind == "edge":
        return ({"t_s": t_ref, "sensor": sensor, "kind": "edge", "x_m": p[0], "y_m": p[1], "normal_rad": 0.0,
                 "error_m": _truth_distance(p, scene, walls=True, points=True)}, None)
    normal_w = normal_robot + ph
    fix = {"t_s": t_ref, "sensor": sensor, "kind": "wall", "x_m": p[0], "y_m": p[1], "normal_rad": normal_w,
           "error_m": _truth_distance(p, scene, walls=True, points=False)}
    # localisation: distance robot origin -> wall line (robot frame) and the wall normal
    nr = np.array([math.cos(normal_robot), math.sin(normal_robot)])
    d_meas = float(np.asarray(p_robot, float) @ nr)
    for name, (a, b) in known:
        tvec = (b - a) / np.linalg.norm(b - a)
        nw = np.array([-tvec[1], tvec[0]])
        cw = float(nw @ a)
        if nw @ np.array([px, py]) > cw:  # orient the normal away from the robot
            nw, cw = -nw, -cw
        ang = math.atan2(nw[1], nw[0])
        if abs(wrap_angle(normal_w - ang)) > ASSOC_ANGLE:
            continue
        u = float((p - a) @ tvec)
        if abs(float(nw @ p) - cw) > ASSOC_DIST or not -ASSOC_DIST <= u <= np.linalg.norm(b - a) + ASSOC_DIST:
            continue
        lat_est = cw - d_meas  # robot origin's coordinate along nw
        return fix, {"t_s": t_ref, "sensor": sensor, "wall": name,
                     "lateral_err_m": lat_est - float(nw @ np.array([px, py])),
                     "heading_err_rad": float(wrap_angle((ang - normal_robot) - ph))}
    return fix, None


def _known_walls(scene: Any) -> list[tuple[str, Any]]:
    return [(n, w) for n, w in zip(scene.wall_names, scene.walls) if n not in KNOWN_WALLS_EXCLUDE]


def chunk_task(scene_name: str, t_offset_s: float, duration_s: float, seed: int) -> dict[str, Any]:
    """One chunk of the corridor run: fixes, localisation updates and per-sensor counts."""
    from ..demo import DEMO_SENSORS
    from ..scene import load_scene
    from ..schedule import VirtualSensor

    scene = load_scene(scene_name)
    sensors = [VirtualSensor(name, tx=tx, rx=rx, order=1) for name, tx, rx in DEMO_SENSORS]
    run = simulate_scene(scene, sensors, duration_s, t_offset_s=t_offset_s, seed=seed)
    layout, c = scene.layout, scene.speed_of_sound
    known = _known_walls(scene)
    fixes, loc = [], []
    for fx in batch_fixes(layout, run.resolved, run.echoes, c):
        pe = fx.echo
        tof = np.array(list(pe.tofs.values()), float)
        t_ref = t_offset_s + (pe.t0 + float(np.mean(tof)) / 2) / TICK_HZ  # reflection instant, scene time
        name = run.resolved[pe.sensor].name
        if fx.kind == "wall" and fx.wall_valid:
            fix, upd = _map_fix(scene, known, t_ref, name, "wall", fx.wall_foot, fx.wall_normal)
        elif fx.kind == "edge" and fx.point_valid:
            fix, upd = _map_fix(scene, known, t_ref, name, "edge", fx.point, 0.0)
        else:
            continue
        fixes.append(fix)
        if upd is not None:
            loc.append(upd)
    counts = []
    for r in run.resolved:
        ps = [p for p in run.pulses if p.sensor == r.id]
        counts.append({"sensor": r.name, "tx": list(map(int, r.tx)), "rx": list(map(int, r.rx)), "pulses": len(ps),
                       "init": sum(p.init for p in ps),
                       "samples": sum(1 for e in run.events if e.sensor == r.id and e.sample),
                       "empty": sum(1 for e in run.events if e.sensor == r.id and e.window_empty and not e.init_ping)})
    return {"t_offset_s": t_offset_s, "duration_s": duration_s, "fixes": fixes, "loc": loc, "counts": counts,
            "wall_s": run.wall_s}


def twin_corridor(scene_name: str, seconds: float, seed: int, progress: bool = True) -> dict[str, Any]:
    """The corridor on the full-system twin: the demo's sensors configured through the driver,
    streamed for ``seconds``; the map and the localisation from the firmware's wall and edge
    records, the counts from the device's ToF frames (the chunk's dict, plus the re-aims)."""
    from ..demo import DEMO_SENSORS
    from ..scene import load_scene
    from ..schedule import VirtualSensor
    from .twin_backend import run_on_twin

    scene = load_scene(scene_name)
    sensors = [VirtualSensor(name, tx=tx, rx=rx, order=1) for name, tx, rx in DEMO_SENSORS]
    run = run_on_twin(scene, sensors, seconds, seed=seed, progress=progress, label="fig10 twin: corridor")
    known = _known_walls(scene)
    fixes, loc = [], []
    for f in run.fixes:
        if f.kind not in ("wall", "edge"):
            continue
        fix, upd = _map_fix(scene, known, f.t_ref, f.name, f.kind, f.xy, f.normal)
        fixes.append(fix)
        if upd is not None:
            loc.append(upd)
    counts = []
    for r in run.resolved:
        ps = run.sensor_pulses(r.id)
        counts.append({"sensor": r.name, "tx": list(map(int, r.tx)), "rx": list(map(int, r.rx)), "pulses": len(ps),
                       "init": sum(p.init for p in ps), "samples": sum(len(p.firsts) for p in ps),
                       "empty": sum(len(p.empty) for p in ps if not p.init),
                       "groups": run.placements(r.id)})
    return {"t_offset_s": 0.0, "duration_s": run.sonar_s, "fixes": fixes, "loc": loc, "counts": counts,
            "wall_s": run.wall_s, "health": run.fw_healthy()}


def _summarise(parts: list[dict[str, Any]], total: float, backend: str) -> dict[str, Any]:
    """The tables' rows of one backend's parts (chunks of the model, or the twin's run)."""
    fixes = [{"backend": backend, **f} for p in parts for f in p["fixes"]]
    loc = [{"backend": backend, **u} for p in parts for u in p["loc"]]
    sens: dict[str, dict[str, Any]] = {}
    for p in parts:
        for cnt in p["counts"]:
            s = sens.setdefault(cnt["sensor"], {**cnt, "pulses": 0, "init": 0, "samples": 0, "empty": 0})
            for k in ("pulses", "init", "samples", "empty"):
                s[k] += cnt[k]
    sensor_rows = []
    for name, s in sens.items():
        fw = sum(1 for f in fixes if f["sensor"] == name and f["kind"] == "wall")
        fe = sum(1 for f in fixes if f["sensor"] == name and f["kind"] == "edge")
        sensor_rows.append({"backend": backend, "sensor": name, "tx": s["tx"], "rx": s["rx"],
                            "groups": s.get("groups", "-"), "pulses": s["pulses"], "init": s["init"],
                            "rate": s["samples"] / len(s["rx"]) / total, "fix_rate": (fw + fe) / total,
                            "miss": s["empty"] / max(s["empty"] + s["samples"], 1), "fixes": f"{fw} / {fe}"})
    acc_rows = []
    for kind in ("wall", "edge"):
        e = np.array([f["error_m"] for f in fixes if f["kind"] == kind])
        acc_rows.append({"backend": backend, "kind": kind, "n": len(e), "med": finite_stat(e, np.median) * 1e3,
                         "p95": finite_stat(e, lambda v: np.percentile(v, 95)) * 1e3,
                         "max": finite_stat(e, np.max) * 1e3})
    loc_rows = []
    for wall in sorted({u["wall"] for u in loc}):
        us = sorted((u for u in loc if u["wall"] == wall), key=lambda u: u["t_s"])
        t = np.array([u["t_s"] for u in us])
        lat = np.abs([u["lateral_err_m"] for u in us])
        hd = np.degrees(np.abs([u["heading_err_rad"] for u in us]))
        loc_rows.append({"backend": backend, "wall": wall, "n": len(us), "span": f"{t[0]:.2f}..{t[-1]:.2f}",
                         "rate": len(us) / max(t[-1] - t[0], 1e-9) if len(us) > 1 else float("nan"),
                         "lat_med": float(np.median(lat)) * 1e3, "lat_p95": float(np.percentile(lat, 95)) * 1e3,
                         "hd_med": float(np.median(hd)), "hd_p95": float(np.percentile(hd, 95))})
    t_all = np.sort([u["t_s"] for u in loc])
    gaps = np.diff(t_all) if t_all.size > 1 else np.array([])
    wall_err = np.array([f["error_m"] for f in fixes if f["kind"] == "wall"])
    return {"backend": backend, "fixes": fixes, "loc": loc, "sensor_rows": sensor_rows, "acc_rows": acc_rows,
            "loc_rows": loc_rows,
            "max_gap_ms": float(gaps.max()) * 1e3 if gaps.size else float("nan"),
            "share_10ms": float(np.mean(gaps <= 0.010)) if gaps.size else float("nan"),
            "n_wall_fixes": int(wall_err.size), "wall_median_m": finite_stat(wall_err, np.median),
            "loc_updates": len(loc), "sonar_s": total}


def run(executor: Executor, *, quick: bool = False, scene_name: str = "corridor", seconds: float | None = None,
        chunk_s: float = 0.5, seed: int = 10, progress: bool = True, backend: str = "model") -> ExperimentResult:
    from ..scene import load_scene

    if backend not in BACKENDS:
        raise ValueError(f"unknown backend {backend!r} for fig10; known: {', '.join(BACKENDS)}")
    scene = load_scene(scene_name)
    total = float(seconds if seconds is not None else (0.5 if quick else scene.duration_s))
    n_chunks = max(1, int(math.ceil(total / chunk_s - 1e-9)))
    tasks = [{"scene_name": scene_name, "t_offset_s": k * chunk_s, "duration_s": min(chunk_s, total - k * chunk_s),
              "seed": seed + k} for k in range(n_chunks)]
    parts = run_sweep(executor, chunk_task, tasks, label="fig10", progress=progress)
    sim_wall = sum(p["wall_s"] for p in parts)
    m = _summarise(parts, total, "model")
    tw: dict[str, Any] | None = None
    twin_total = min(total, TWIN_MAX_S)
    if backend == "twin":
        if progress:
            print(f"  fig10: twin: {twin_total:.2f} s of the corridor", file=sys.stderr)
        tpart = twin_corridor(scene_name, twin_total, seed, progress)
        tw = _summarise([tpart], tpart["duration_s"], "twin")
        tw.update(wall_s=tpart["wall_s"], health=tpart["health"])
    both = [m] + ([tw] if tw else [])
    fixes = [f for b in both for f in b["fixes"]]
    loc = [u for b in both for u in b["loc"]]
    if tw:
        twin_note = (
            f"Twin rows (`--backend twin`): the full-system twin (RTL sonar core, VexRiscv firmware, USB device, the "
            f"driver in-process) on the same scene and sensors for {tw['sonar_s']:.2f} s of sonar time from scene time "
            f"0 in one run (the model: {n_chunks} chunk(s) of {chunk_s} s"
            + (f"; the twin is capped at {TWIN_MAX_S} s, the corridor's straight run past the door, as `make demo`"
               if total > TWIN_MAX_S else "")
            + "). Map and localisation from the firmware's geometry records (wall: foot point and normal; edge: "
            "position; robot frame, placed with the pose at t0 + half the pulse's mean first-echo ToF), counts from "
            "the device's ToF frames. The firmware re-aims on its own ('groups': the shifts each sensor went "
            "through; each move restarts every sensor with init pings); the model keeps the configured table. "
            "The firmware reports whole millimetres: on walls parallel to the robot's path a foot point rounds to the "
            "wall's own coordinate, so such errors show as 0.0 mm. The scene's noise is drawn per pulse, so once the "
            "two runs fire at different ticks their echoes differ, and a sensor's rate differs as between two noise "
            "seeds of the model (`make demo` shows the same). "
            f"Twin wall time {tw['wall_s']:.0f} s ({tw['sonar_s'] / max(tw['wall_s'], 1e-9):.4f} sonar-s per "
            f"wall-s, boot included); device / harness: "
            f"{', '.join(tw['health']) or 'nothing dropped, lost or clipped'}.")
    else:
        twin_note = "Twin rows: not run (`--backend twin` runs the corridor on the full-system twin)."
    gap_lines = [f"All known walls together ({b['backend']}): {b['loc_updates']} "
                 f"localisation updates, longest gap {b['max_gap_ms']:.1f} ms, {b['share_10ms']:.0%} of the gaps "
                 "<= 10 ms (the paper's locomotion controller period)." for b in both]
    md = "\n".join([
        f"# Fig. 10: map building while localising on known walls (scene `{scene.name}`)", "",
        f"Golden model, {total:.2f} s of sonar time in {n_chunks} chunk(s) of {chunk_s} s "
        f"({sim_wall:.1f} s of model wall time, {total / max(sim_wall, 1e-9):.2f} sonar-s per wall-s per worker).", "",
        md_table([("backend", "backend"), ("sensor", "sensor"), ("tx", "tx"), ("rx", "rx"), ("groups", "groups"),
                  ("pulses", "pulses"), ("init", "init pings"),
                  ("rate", "samples/s per receiver"), ("miss", "empty windows"), ("fix_rate", "fixes/s"),
                  ("fixes", "fixes (wall / edge)")], [r for b in both for r in b["sensor_rows"]],
                 {"rate": ".1f", "miss": ".1%", "fix_rate": ".1f"}), "",
        "Map accuracy: distance from each fix to the nearest true wall / cylinder surface (walls) or edge, wall or "
        "cylinder (edges); pose at the reflection instant.", "",
        md_table([("backend", "backend"), ("kind", "fix kind"), ("n", "count"), ("med", "median error (mm)"),
                  ("p95", "95% (mm)"), ("max", "max (mm)")], [r for b in both for r in b["acc_rows"]],
                 {"med": ".1f", "p95": ".1f", "max": ".1f"}), "",
        "Localisation on known walls: robot position across the wall and heading from each associated wall fix, "
        "against the true pose.", "",
        md_table([("backend", "backend"), ("wall", "known wall"), ("n", "updates"), ("span", "time span (s)"),
                  ("rate", "updates/s"), ("lat_med", "|position error| median (mm)"), ("lat_p95", "95% (mm)"),
                  ("hd_med", "|heading error| median (deg)"), ("hd_p95", "95% (deg)")],
                 [r for b in both for r in b["loc_rows"]],
                 {"rate": ".0f", "lat_med": ".1f", "lat_p95": ".1f", "hd_med": ".2f", "hd_p95": ".2f"}), "",
        *gap_lines, "", twin_note, ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(14, 6), gridspec_kw={"width_ratios": [1.4, 1]})
        for (a, b) in scene.walls:
            ax.plot([a[0], b[0]], [a[1], b[1]], color="0.8", lw=3, zorder=1)
        if len(scene.points):
            ax.scatter(scene.points[:, 0], scene.points[:, 1], marker="o", s=60, facecolors="none", edgecolors="0.6")
        for (cx, cy), rad in zip(scene.cylinders, scene.cylinder_radius):
            ax.add_patch(plt.Circle((cx, cy), rad, color="0.85", zorder=1))
        ts = np.linspace(0, total, 200)
        x, y, _ = scene.pose(ts)
        ax.plot(x, y, color="tab:blue", lw=1.5, label="robot path", zorder=2)
        colours = {"model": ("tab:red", "k"), "twin": ("tab:purple", "tab:green")}
        for b in both:
            wall_c, edge_c = colours[b["backend"]]
            for f in b["fixes"]:
                if f["kind"] == "wall":
                    dx, dy = -math.sin(f["normal_rad"]) * 0.04, math.cos(f["normal_rad"]) * 0.04
                    ax.plot([f["x_m"] - dx, f["x_m"] + dx], [f["y_m"] - dy, f["y_m"] + dy], color=wall_c, lw=1.2,
                            zorder=3)
            ed = np.array([(f["x_m"], f["y_m"]) for f in b["fixes"] if f["kind"] == "edge"])
            if len(ed):
                ax.scatter(ed[:, 0], ed[:, 1], s=6, color=edge_c, zorder=4, label=f"edges ({b['backend']})")
            ax.plot([], [], color=wall_c, label=f"wall patches ({b['backend']})")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(f"map building, scene '{scene.name}' ({' and '.join(b['backend'] for b in both)})")
        ax.legend(loc="upper left", fontsize=8)
        for b in both:
            for wall in sorted({u["wall"] for u in b["loc"]}):
                us = [u for u in b["loc"] if u["wall"] == wall]
                ax2.plot([u["t_s"] for u in us], [u["lateral_err_m"] * 1e3 for u in us],
                         "." if b["backend"] == "model" else "x", ms=3, label=f"{wall} ({b['backend']})")
        ax2.set_xlabel("scene time (s)")
        ax2.set_ylabel("position error across the wall (mm)")
        ax2.set_title("localisation on known walls")
        ax2.grid(alpha=0.3)
        ax2.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)

    columns = ["backend", "t_s", "sensor", "kind", "x_m", "y_m", "normal_rad", "error_m"]
    keys = ("n_wall_fixes", "wall_median_m", "loc_updates", "max_gap_ms", "share_10ms", "sonar_s")
    summary: dict[str, Any] = {"n_wall_fixes": m["n_wall_fixes"], "wall_median_m": m["wall_median_m"],
                               "loc_updates": m["loc_updates"], "loc_max_gap_ms": m["max_gap_ms"],
                               "loc_rows": m["loc_rows"], "sensor_rows": m["sensor_rows"], "backend": backend}
    json_data = None
    if tw:
        summary["twin"] = {**{k: tw[k] for k in keys}, "loc_rows": tw["loc_rows"], "sensor_rows": tw["sensor_rows"],
                           "acc_rows": tw["acc_rows"], "wall_s": tw["wall_s"], "health": tw["health"]}
        json_data = {"summary": {**{k: v for k, v in summary.items() if k != "twin"}, "acc_rows": m["acc_rows"],
                                 "share_10ms": m["share_10ms"], "twin": summary["twin"]}}
    return ExperimentResult(
        "fig10", "map building and localisation", columns, sorted(fixes, key=lambda f: (f["backend"], f["t_s"])), md,
        plot, summary=summary, json_data=json_data,
        extra_csv={"fig10_localisation": (["backend", "t_s", "sensor", "wall", "lateral_err_m", "heading_err_rad"],
                                          sorted(loc, key=lambda u: (u["backend"], u["t_s"])))})
