"""`make demo`: the most complete simulation the project has, on one scene.

Until the full-system twin exists (RTL + firmware + USB, issue #7) this runs the golden
model end to end: scene -> acoustic model -> tick-exact fast-firing scheduler and receive
gating -> geometry (edge / wall classification with three receivers) -> a map in world
coordinates like the paper's Fig. 10, per-sensor sample rates and an accuracy table checked
against the scene's ground truth.
"""

from __future__ import annotations

import csv
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .constants import TICK_HZ

#: Virtual sensors of the demo: a phased 3-element front sensor (virtual source at the robot
#: origin) and single-transmitter sensors with three receivers towards the sides and
#: diagonals, as the paper's map-building experiment aims them at walls and openings.
DEMO_SENSORS = [
    ("front", [23, 0, 1], [23, 0, 1]),
    ("front_left", [3], [2, 3, 4]),
    ("left", [6], [5, 6, 7]),
    ("right", [18], [17, 18, 19]),
    ("front_right", [21], [20, 21, 22]),
]


@dataclass
class Fix:
    t: float  # s, pulse time
    sensor: str
    kind: str  # edge | wall | uncertain
    x: float  # world position of the edge / wall foot point, m
    y: float
    normal: float  # world bearing of the wall normal (walls), rad
    error: float  # m, distance to the nearest true reflector of that kind


def _segment_distance(p: np.ndarray, walls: np.ndarray) -> np.ndarray:
    a, b = walls[:, 0], walls[:, 1]
    ab = b - a
    u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    return np.linalg.norm(a + u[:, None] * ab - p, axis=1)


def _truth_distance(p: np.ndarray, scene, *, walls: bool, points: bool) -> float:
    """Distance from a fix to the nearest true reflector surface it may belong to: wall
    segments, edges/rods (points) and cylinder surfaces (a bin looks like an edge or a short
    wall patch to three receivers)."""
    d = [np.inf]
    if walls and len(scene.walls):
        d.append(np.min(_segment_distance(p, scene.walls)))
    if points and len(scene.points):
        d.append(np.min(np.linalg.norm(scene.points - p, axis=1)))
    if len(scene.cylinders):
        d.append(np.min(np.abs(np.linalg.norm(scene.cylinders - p, axis=1) - scene.cylinder_radius)))
    return float(min(d))


def _progress(done: float, total: float, t0: float) -> None:
    frac = min(done / total, 1.0)
    bar = "#" * int(30 * frac)
    sys.stderr.write(f"\r  simulating [{bar:<30}] {done:5.2f}/{total:.2f} s sonar time, {time.time() - t0:5.1f} s wall")
    sys.stderr.flush()


def run_demo(scene_name: str = "corridor", out: str | Path = "build/demo", seconds: float | None = None) -> int:
    from . import geometry
    from .fastfiring import SEQ_W, FastFiringModel, SceneEchoSource
    from .scene import load_scene
    from .schedule import Schedule, VirtualSensor

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene(scene_name)
    layout = scene.layout
    duration = float(seconds if seconds is not None else scene.duration_s)
    if not duration > 0:
        raise ValueError(f"sonar time to simulate must be positive, got {duration}")
    sensors = [VirtualSensor(name, tx=tx, rx=rx, order=1) for name, tx, rx in DEMO_SENSORS]
    schedule = Schedule(layout, sensors, temperature_c=scene.temperature_c)
    resolved = schedule.validate()
    model = FastFiringModel(schedule, SceneEchoSource(scene))
    c = scene.speed_of_sound
    print(f"demo: scene {scene.name!r} ({scene.n_reflectors} reflectors), {len(sensors)} virtual sensors, "
          f"{duration:.2f} s of sonar time, golden model (RTL twin: issue #7)")

    t_wall = time.time()
    chunk = int(0.05 * TICK_HZ)
    events, pulses = [], []
    done = 0
    total = int(duration * TICK_HZ)
    while done < total:
        step = min(chunk, total - done)
        res = model.run(step)
        events += res.events
        pulses += res.pulses
        done += step
        _progress(done / TICK_HZ, duration, t_wall)
    sys.stderr.write("\n")
    wall_s = time.time() - t_wall

    # ---- group first echoes per pulse, solve geometry
    # Events carry the pulse number modulo 2**SEQ_W (as the RTL's FIFO word does): map each
    # back to the latest pulse of that sensor and residue issued before the event.
    issued: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for p in pulses:
        issued.setdefault((p.sensor, p.seq % (1 << SEQ_W)), []).append((p.t0, p.seq))
    t0_of = {(p.sensor, p.seq): p.t0 for p in pulses}
    by_pulse: dict[tuple[int, int], dict[int, int]] = {}
    for e in events:
        if e.first_echo and e.in_window:
            cands = [seq for t0, seq in issued.get((e.sensor, e.seq), []) if t0 <= e.tick]
            if cands:
                by_pulse.setdefault((e.sensor, cands[-1]), {})[e.rx] = e.tof
    fixes: list[Fix] = []
    for (sid, seq), tofs in by_pulse.items():
        r = resolved[sid]
        if len(tofs) < 3 or (sid, seq) not in t0_of:
            continue
        rx = np.array(sorted(tofs))
        tof_s = np.array([tofs[i] for i in rx]) / TICK_HZ
        if len(r.tx) == 1:
            source = layout.positions[r.tx[0]]
            paths = c * tof_s
        else:  # phased group: the wave leaves the virtual source min|c_j - s|/c before t0
            source = np.asarray(r.source, float)
            paths = c * tof_s + np.min(np.linalg.norm(layout.positions[r.tx] - source, axis=1))
        cls = geometry.classify(layout.positions[rx], paths, source=source)
        t = t0_of[(sid, seq)] / TICK_HZ
        px, py, ph = (float(v) for v in scene.pose(t))
        rot = np.array([[math.cos(ph), -math.sin(ph)], [math.sin(ph), math.cos(ph)]])
        if cls.kind == "wall" and cls.wall.valid:
            foot = rot @ np.asarray(cls.wall.foot) + (px, py)
            err = _truth_distance(foot, scene, walls=True, points=False)
            fixes.append(Fix(t, r.name, "wall", *foot, cls.wall.normal_angle + ph, err))
        elif cls.kind == "edge" and cls.point.valid:
            p = rot @ np.asarray(cls.point.position) + (px, py)
            fixes.append(Fix(t, r.name, "edge", *p, 0.0, _truth_distance(p, scene, walls=True, points=True)))

    # ---- tables
    lines = [f"# Multisonar demo: scene `{scene.name}`", "",
             f"Golden model, {duration:.2f} s of sonar time in {wall_s:.1f} s wall time "
             f"({duration / wall_s:.2f} sonar-s per wall-s).", "",
             "| sensor | tx | rx | pulses | init pings | samples/s per receiver | fixes (wall / edge) |",
             "|---|---|---|---:|---:|---:|---|"]
    for r in resolved:
        ps = [p for p in pulses if p.sensor == r.id]
        n_samples = sum(1 for e in events if e.sensor == r.id and e.first_echo and e.in_window)
        fw = sum(1 for f in fixes if f.sensor == r.name and f.kind == "wall")
        fe = sum(1 for f in fixes if f.sensor == r.name and f.kind == "edge")
        rate = n_samples / len(r.rx) / duration
        lines.append(f"| {r.name} | {list(map(int, r.tx))} | {list(map(int, r.rx))} | {len(ps)} | "
                     f"{sum(p.init for p in ps)} | {rate:.1f} | {fw} / {fe} |")
    lines += ["", "| fix kind | count | median error [mm] | 95% error [mm] | max error [mm] |", "|---|---:|---:|---:|---:|"]
    for kind in ("wall", "edge"):
        errs = np.array([f.error for f in fixes if f.kind == kind])
        if len(errs):
            lines.append(f"| {kind} | {len(errs)} | {np.median(errs) * 1e3:.1f} | {np.percentile(errs, 95) * 1e3:.1f} | {errs.max() * 1e3:.1f} |")
        else:
            lines.append(f"| {kind} | 0 | - | - | - |")
    lines += ["", "Error: distance from the fix to the nearest true wall segment or cylinder surface (walls),",
              "or to the nearest true edge/rod, wall or cylinder surface (edges). Fixes are plotted in world coordinates from the pose at",
              "pulse time; the robot's motion during the ~5 ms flight is not compensated."]
    summary = "\n".join(lines) + "\n"
    (out / "summary.md").write_text(summary)
    with open(out / "fixes.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "sensor", "kind", "x_m", "y_m", "normal_rad", "error_m"])
        for f in fixes:
            w.writerow([f"{f.t:.6f}", f.sensor, f.kind, f"{f.x:.5f}", f"{f.y:.5f}", f"{f.normal:.5f}", f"{f.error:.5f}"])
    np.savez_compressed(out / "events.npz",
                        **{k: np.array([getattr(e, k) for e in events]) for k in
                           ("tick", "sensor", "seq", "rx", "tof", "in_window", "first_echo", "window_empty", "init_ping")})
    _plot_map(scene, fixes, duration, out / "map.png")
    print(summary)
    print(f"demo: wrote {out / 'map.png'}, {out / 'summary.md'}, {out / 'fixes.csv'}, {out / 'events.npz'}")
    return 0


def _plot_map(scene, fixes: list[Fix], duration: float, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 7))
    for (a, b) in scene.walls:
        ax.plot([a[0], b[0]], [a[1], b[1]], color="0.8", lw=3, zorder=1)
    if len(scene.points):
        ax.scatter(scene.points[:, 0], scene.points[:, 1], marker="o", s=60, facecolors="none", edgecolors="0.6", zorder=1)
    for (cx, cy), rad in zip(scene.cylinders, scene.cylinder_radius):
        ax.add_patch(plt.Circle((cx, cy), rad, color="0.85", zorder=1))
    ts = np.linspace(0, duration, 200)
    x, y, _ = scene.pose(ts)
    ax.plot(x, y, color="tab:blue", lw=1.5, label="robot path", zorder=2)
    half = 0.04
    for f in fixes:
        if f.kind == "wall":
            dx, dy = -math.sin(f.normal) * half, math.cos(f.normal) * half
            ax.plot([f.x - dx, f.x + dx], [f.y - dy, f.y + dy], color="tab:red", lw=1.2, zorder=3)
    edges = np.array([(f.x, f.y) for f in fixes if f.kind == "edge"])
    if len(edges):
        ax.scatter(edges[:, 0], edges[:, 1], s=6, color="k", zorder=4, label="edges")
    ax.plot([], [], color="tab:red", label="wall patches")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"Multisonar map building, scene '{scene.name}' (golden model)")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
