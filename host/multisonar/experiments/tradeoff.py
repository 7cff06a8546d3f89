"""The speed/accuracy trade as one report (DESIGN.md section 5).

Knobs: firing order n, window width (T_V = T_N), receivers per virtual sensor, geometry
arithmetic (host float64 golden model; the firmware library's f64 / f32 / Q32.32 variants
through their host builds, plus their measured soft-core cycles per fix). Measures: sample
rate, fix rate, latency, miss rate, range error, angle error. Table + Pareto plot.

Scenario (stated): the robot drives at 1.5 m/s along x; a 7 m wall on its left runs from
(-1, 3.6) to (6, 1.6), so the range shrinks from ~3.3 m to ~2.4 m (T_E ~17 -> 12 ms) and
the echo times drift every pulse (prediction and window width matter). One virtual sensor:
transmitter 5 (axis 75 deg, nearest the wall normal), receivers 1: [5], 2: [5, 6],
3: [4, 5, 6], 5: [3..7]; the scene's noise (1 us jitter, spurious pulses, fading).

Definitions: *sample rate* = in-window first echoes per receiver per second (tracking);
*fix rate* = pulses whose every receiver has an echo and whose fit is valid, per second
(1 receiver: every echo is a range fix); *latency* = age of a fix when it is ready: from the
mean echo arrival to the close of the pulse's last window, plus the soft-core time of the fix
(variant's measured median cycles / 48 MHz; 0 for one receiver and for the host golden model);
*miss rate* = empty tracking windows / tracking windows; *range error* = |fitted distance
from the transmitter to the wall - truth| (1 receiver: c*ToF/2), *angle error* = fitted wall
normal - truth; truth = the wall in the robot frame at the reflection instant t0 + ToF/2;
*outliers* = fixes off by more than 2 deg (1 receiver: 20 mm), i.e. a wrong pulse (spurious,
second echo) inside a window: the price of a wide window.
"""

from __future__ import annotations

import math
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np

from ..constants import TICK_HZ
from .common import ExperimentResult, md_table, simulate_scene, world_to_robot
from .executor import run_sweep

TX = 5
RX_SETS = {1: [5], 2: [5, 6], 3: [4, 5, 6], 5: [3, 4, 5, 6, 7]}
ORDERS = [1, 2, 3, 4]
WINDOWS_MS = [0.1, 0.25, 0.5, 1.0]
BASE = {"order": 2, "window_ms": 0.5, "n_rx": 3}
OUTLIER_DEG = 2.0  #: a fix whose angle is off by more than this is an outlier (a wrong echo in a window)
OUTLIER_MM = 20.0  #: the same for range-only fixes (1 receiver)
SCENE_DOC: dict[str, Any] = {
    "name": "tradeoff_wall",
    "description": "Robot at 1.5 m/s along x, a wall on the left closing in from 3.3 m to 2.4 m.",
    "layout": "ring24",
    "temperature_c": 20,
    "seed": 5,
    "duration_s": 2.0,
    "trajectory": [{"t": 0, "x": 0, "y": 0, "heading_deg": 0}, {"speed": 1.5, "x": 3.0, "y": 0}],
    "walls": [{"name": "wall", "a": [-1.0, 3.6], "b": [6.0, 1.6]}],
    "noise": {"jitter_s": 1.0e-6, "spurious_rate_hz": 2.0, "threshold": 0.01, "fading_db": 1.5},
}


def scenario() -> Any:
    from ..scene import parse_scene

    return parse_scene(SCENE_DOC, "tradeoff_wall")


def _truth(scene: Any, t: float, src: np.ndarray) -> tuple[float, float]:
    """Distance from the robot-frame point ``src`` to the wall, and the wall normal (robot
    frame, pointing from the robot to the wall), at scene time t."""
    a, b = (world_to_robot(scene, t, p) for p in scene.walls[0])
    d = (b - a) / np.linalg.norm(b - a)
    n = np.array([-d[1], d[0]])
    if n @ a < 0:
        n = -n
    return float(n @ a - n @ src), math.atan2(n[1], n[0])


def config_task(order: int, window_ms: float, n_rx: int, duration_s: float, seed: int) -> list[dict[str, Any]]:
    """One (order, window, receivers) point: a golden-model run, then every arithmetic variant
    on the same echoes. Returns one row per variant."""
    from .. import geometry as g
    from ..schedule import VirtualSensor
    from . import fwgeom

    scene = scenario()
    rx = RX_SETS[n_rx]
    sensor = VirtualSensor("wall", tx=[TX], rx=rx, order=order, t_v=window_ms * 1e-3, t_n=window_ms * 1e-3)
    run = simulate_scene(scene, [sensor], duration_s, seed=seed)
    c = scene.speed_of_sound
    lay = scene.layout
    src = lay.positions[TX]
    track_events = [e for e in run.events if not e.init_ping]
    samples = sum(1 for e in track_events if e.sample)
    empty = sum(1 for e in track_events if e.window_empty)
    used = [p.order for p in run.pulses if not p.init]
    full = [pe for pe in run.echoes if len(pe.tofs) == n_rx and not pe.init]
    tofs = np.array([[pe.tofs[r] for r in rx] for pe in full], float).reshape(-1, n_rx)
    t_ref = np.array([(pe.t0 + tofs[i].mean() / 2) / TICK_HZ for i, pe in enumerate(full)])
    age = np.array([(pe.close - (pe.t0 + tofs[i].mean())) / TICK_HZ for i, pe in enumerate(full)])
    truth = [_truth(scene, t, src) for t in t_ref]
    d_true = np.array([x[0] for x in truth])
    n_true = np.array([x[1] for x in truth])
    paths = c * tofs / TICK_HZ
    base = {"order": order, "window_ms": window_ms, "n_rx": n_rx, "pulses": len(run.pulses),
            "init_pings": sum(p.init for p in run.pulses),
            "order_used": float(np.median(used)) if used else float("nan"),
            "sample_rate_hz": samples / n_rx / duration_s, "miss_rate": empty / max(empty + samples, 1),
            "sim_wall_s": run.wall_s}
    variants: list[tuple[str, Any]] = [("host f64", None)]
    if n_rx >= 2 and fwgeom.ensure_built():
        variants += [(v, fwgeom.FwWall(v)) for v in fwgeom.VARIANTS]
    rows = []
    for name, solver in variants:
        if n_rx == 1:
            valid = np.ones(len(full), bool)
            dist = paths[:, 0] / 2
            ang = np.full(len(full), np.nan)
        elif len(full) == 0:
            valid, dist, ang = np.zeros(0, bool), np.zeros(0), np.zeros(0)
        else:
            C = lay.positions[rx]
            axis = float(np.angle(np.exp(1j * lay.axes[rx]).mean()))
            if solver is None:
                with np.errstate(all="ignore"):
                    wb = g.solve_wall_batch(C, paths, src, axis=axis, tol=np.inf, max_gdop=np.inf)
                valid, dist, ang = wb.valid, wb.distance, wb.normal_angle
            else:
                valid, dist, ang = solver.solve(C, paths, src, np.full(len(full), axis))
        cyc = 0 if (solver is None or n_rx == 1) else fwgeom.FIX_CYCLES[name]
        rerr = np.abs(dist[valid] - d_true[valid]) * 1e3
        aerr = np.degrees(np.abs((ang[valid] - n_true[valid] + np.pi) % (2 * np.pi) - np.pi)) if n_rx >= 2 else np.zeros(0)
        lat = age[valid] + cyc / fwgeom.SOC_HZ
        rows.append({**base, "variant": name, "fix_cycles": cyc, "fixes": int(valid.sum()),
                     "fix_rate_hz": float(valid.sum()) / duration_s,
                     "latency_ms": float(lat.mean()) * 1e3 if lat.size else float("nan"),
                     "range_err_med_mm": float(np.median(rerr)) if rerr.size else float("nan"),
                     "range_err_p95_mm": float(np.percentile(rerr, 95)) if rerr.size else float("nan"),
                     "angle_err_med_deg": float(np.median(aerr)) if aerr.size else float("nan"),
                     "angle_err_rms_deg": float(np.sqrt(np.mean(aerr ** 2))) if aerr.size else float("nan"),
                     "outlier_frac": float(np.mean((aerr > OUTLIER_DEG) if n_rx >= 2 else (rerr > OUTLIER_MM)))
                     if rerr.size else float("nan")})
    return rows


def pareto(points: list[tuple[float, float]]) -> list[bool]:
    """Non-dominated flags for (maximise x, minimise y); NaN points are never on the front."""
    flags = []
    for i, (x, y) in enumerate(points):
        if not (math.isfinite(x) and math.isfinite(y)):
            flags.append(False)
            continue
        dom = any(math.isfinite(x2) and math.isfinite(y2) and x2 >= x and y2 <= y and (x2 > x or y2 < y)
                  for j, (x2, y2) in enumerate(points) if j != i)
        flags.append(not dom)
    return flags


def run(executor: Executor, *, quick: bool = False, seconds: float | None = None, seed: int = 11,
        progress: bool = True) -> ExperimentResult:
    if quick:
        configs = sorted({(1, 0.5, 3), (3, 0.5, 3), (2, 0.25, 3), (2, 1.0, 3), (2, 0.5, 1), (2, 0.5, 2), (2, 0.5, 3)})
        dur = seconds or 0.4
    else:
        configs = [(n, w, k) for n in ORDERS for w in WINDOWS_MS for k in RX_SETS]
        dur = seconds or 2.0
    tasks = [{"order": n, "window_ms": w, "n_rx": k, "duration_s": dur, "seed": seed} for n, w, k in configs]
    rows = [r for part in run_sweep(executor, config_task, tasks, label="tradeoff", progress=progress) for r in part]
    variants = sorted({r["variant"] for r in rows}, key=lambda v: ("host f64", "f64", "f32", "q").index(v))
    main_variant = "q" if "q" in variants else "host f64"
    main = [r for r in rows if r["variant"] == main_variant or r["n_rx"] == 1]
    on_front = pareto([(r["fix_rate_hz"], r["angle_err_rms_deg"]) for r in main])
    for r, f in zip(main, on_front):
        r["pareto"] = f
    for r in rows:
        r.setdefault("pareto", False)
    cols = [("order", "order"), ("order_used", "order used (median)"), ("window_ms", "T_V = T_N (ms)"),
            ("n_rx", "receivers"), ("variant", "arithmetic"), ("sample_rate_hz", "samples/s per rx"),
            ("fix_rate_hz", "fixes/s"), ("latency_ms", "latency (ms)"), ("miss_rate", "miss rate"),
            ("range_err_med_mm", "range error median (mm)"), ("range_err_p95_mm", "95% (mm)"),
            ("angle_err_med_deg", "angle error median (deg)"), ("angle_err_rms_deg", "rms (deg)"),
            ("outlier_frac", "outliers"), ("pareto", "Pareto")]
    fmt = {"order_used": ".0f", "window_ms": ".2f", "sample_rate_hz": ".1f", "fix_rate_hz": ".1f", "latency_ms": ".2f",
           "miss_rate": ".1%", "range_err_med_mm": ".2f", "range_err_p95_mm": ".2f", "angle_err_med_deg": ".3f",
           "angle_err_rms_deg": ".3f", "outlier_frac": ".1%"}
    base = [r for r in rows if (r["order"], r["window_ms"], r["n_rx"]) == (BASE["order"], BASE["window_ms"], BASE["n_rx"])]
    var_cols = [("variant", "arithmetic"), ("fix_cycles", "soft-core cycles per fix"), ("fixes", "valid fixes"),
                ("latency_ms", "latency (ms)"), ("range_err_med_mm", "range error median (mm)"),
                ("range_err_p95_mm", "95% (mm)"), ("angle_err_med_deg", "angle error median (deg)"),
                ("angle_err_rms_deg", "rms (deg)")]
    front = [r for r in main if r["pareto"]]
    md = "\n".join([
        "# Speed against accuracy: firing order, window, receivers, arithmetic", "",
        f"Golden model, scenario `tradeoff_wall` (robot at 1.5 m/s, wall closing in from ~3.3 m to ~2.4 m on the left), "
        f"{dur:g} s of sonar time per configuration, transmitter {TX}; definitions in "
        "host/multisonar/experiments/tradeoff.py. Arithmetic of the sweep table: "
        f"`{main_variant}` (the firmware's default variant; latency includes its measured soft-core cycles per fix).",
        "", md_table(cols, main, fmt), "",
        f"Arithmetic variants at order {BASE['order']}, T_V = T_N = {BASE['window_ms']} ms, {BASE['n_rx']} receivers "
        "(the same echoes through each solver; cycles: PicoRV32 at 48 MHz, median fix, scripts/bench_fw_cycles.py):", "",
        md_table(var_cols, base, {k: v for k, v in fmt.items()} | {"fix_cycles": ","}), "",
        "Pareto front (most fixes per second against the lowest rms angle error): "
        + ("; ".join(f"order {r['order']}, {r['window_ms']} ms, {r['n_rx']} rx ({r['fix_rate_hz']:.0f} fixes/s, "
                     f"{r['angle_err_rms_deg']:.3f} deg)" for r in front) or "-") + ".", ""])

    def plot(path: Path) -> None:
        import matplotlib.pyplot as plt

        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 5))
        marks = {1: "o", 2: "s", 3: "^", 4: "D"}
        colours = {1: "tab:grey", 2: "tab:blue", 3: "tab:orange", 5: "tab:green"}
        for r in main:
            if not math.isfinite(r["angle_err_rms_deg"]):
                continue
            ax.scatter(r["fix_rate_hz"], r["angle_err_rms_deg"], marker=marks[r["order"]], color=colours[r["n_rx"]],
                       s=20 + 40 * r["window_ms"], edgecolors="k" if r["pareto"] else "none", linewidths=1.2)
        fr = sorted(((r["fix_rate_hz"], r["angle_err_rms_deg"]) for r in main if r["pareto"]))
        if fr:
            ax.plot(*zip(*fr), "k--", lw=0.8, label="Pareto front")
        for n, m in marks.items():
            ax.scatter([], [], marker=m, color="0.5", label=f"order {n}")
        for k, col in colours.items():
            if k > 1:
                ax.scatter([], [], marker="o", color=col, label=f"{k} receivers")
        ax.set_xlabel("fixes per second")
        ax.set_ylabel("wall angle error, rms (deg)")
        ax.set_title(f"speed vs angle accuracy ({main_variant}; marker size = window)")
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
        for r in main:
            ax2.scatter(r["sample_rate_hz"], r["miss_rate"] * 100, marker=marks[r["order"]], color=colours[r["n_rx"]],
                        s=20 + 40 * r["window_ms"])
        ax2.set_xlabel("samples per second per receiver")
        ax2.set_ylabel("miss rate (% empty windows)")
        ax2.set_title("sample rate vs miss rate")
        ax2.grid(alpha=0.3)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)

    columns = ["order", "order_used", "window_ms", "n_rx", "variant", "fix_cycles", "pulses", "init_pings",
               "sample_rate_hz", "fix_rate_hz", "fixes", "latency_ms", "miss_rate", "range_err_med_mm",
               "range_err_p95_mm", "angle_err_med_deg", "angle_err_rms_deg", "outlier_frac", "pareto", "sim_wall_s"]
    return ExperimentResult("tradeoff", "speed/accuracy trade", columns, rows, md, plot,
                            summary={"rows": rows, "main_variant": main_variant})
