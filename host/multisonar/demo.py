"""`make demo`: the main job, the most complete simulation the project has, on one scene.

Backends (``--backend``):

* ``twin`` (default): the full-system twin (multisonar.twin): scene -> acoustic model ->
  the device's RTL in Verilator (sonar core with phased triggers and gated receivers, VexRiscv
  running firmware/app/sonar: geometry, classification, re-aiming; host link; USB
  device core) -> USB/IP on 127.0.0.1 -> the unchanged pyusb driver -> numpy. The map comes
  from the firmware's geometry records; the golden model runs the same scene alongside for the
  per-sensor rates.
* ``golden``: the golden model alone (acoustics -> tick-exact fast-firing scheduler and
  receive gating -> host geometry), ~100x faster.

Both write build/demo/: map.png (world coordinates like the paper's Fig. 10: edges as dots,
wall patches as short oriented segments, robot path, ground truth faint), summary.md
(per-sensor rates, accuracy against the scene's truth), fixes.csv, events.npz and (twin)
frames.msrec, the frames as recorded by the driver (`multisonar export` reads it).
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .constants import DEVICE_DECISION_LEAD, TICK_HZ
from .errors import DeviceDisconnected

#: the firmware's busy-budget window (sonar_app main.c BUSY_WINDOW, 10 ms)
BUSY_WINDOW_TICKS = TICK_HZ // 100

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


def _progress(done: float, total: float, t0: float, what: str = "") -> None:
    frac = min(done / total, 1.0) if total > 0 else 1.0
    bar = "#" * int(30 * frac)
    wall = time.time() - t0
    rate = f", {done / wall:.4f} sonar-s/wall-s" if wall > 0 and done > 0 else ""
    sys.stderr.write(f"\r  {what}[{bar:<30}] {done:5.2f}/{total:.2f} s sonar time, {wall:6.1f} s wall{rate}   ")
    sys.stderr.flush()


#: the maximum load: 8 virtual sensors (the table's size), one transmitter and three receivers
#: each, so all 24 receivers listen, at the highest fast-firing order
RING8_SENSORS = [(f"ring{k}", [3 * k + 1], [3 * k, 3 * k + 1, 3 * k + 2]) for k in range(8)]
SENSOR_SETS = {"demo": (DEMO_SENSORS, 1), "ring8": (RING8_SENSORS, 4)}


def max_load_echoes(range_m: float = 2.5) -> Any:
    """Echoes that keep every ``ring8`` sensor tracking, so the table runs at the highest rate
    the scheduler reaches: each receiver hears every firing at ``range_m`` (+ 0-2 cm by
    receiver), closing at 1 m/s, with ring-down and 2 spurious pulses/s per channel (seed 1).
    For the twin: ``run_demo("empty", ..., sensors="ring8", compare=False, echo_source=...)``."""
    from .fastfiring import SyntheticEchoSource

    return SyntheticEchoSource({rx: range_m + 0.01 * (rx % 3) for rx in range(24)}, velocity_mps=1.0,
                               ringdown_ticks=50_000, spurious_rate_hz=2.0, seed=1)


def demo_sensors(which: str = "demo") -> list[Any]:
    """The virtual sensors of a sensor set: ``demo`` (five, order 1) or ``ring8`` (the maximum
    load: eight, every receiver, order 4)."""
    from .schedule import VirtualSensor

    if which not in SENSOR_SETS:
        raise ValueError(f"unknown sensor set {which!r}; known: {', '.join(SENSOR_SETS)}")
    sensors, order = SENSOR_SETS[which]
    return [VirtualSensor(name, tx=tx, rx=rx, order=order) for name, tx, rx in sensors]


@dataclass
class DemoRun:
    """What a backend produced: per-sensor pulse / sample counts, fixes in world coordinates,
    the ToF events as named columns."""
    backend: str
    duration: float
    wall_s: float
    resolved: list[Any]
    pulses: dict[int, int]
    init_pings: dict[int, int]
    samples: dict[int, int]
    fixes: list[Fix]
    events: dict[str, np.ndarray]
    notes: list[str] = field(default_factory=list)
    #: twin: the host geometry's fixes from the same run's ToF frames (every pulse with three or
    #: more first echoes in its windows, whether or not the firmware fixed it)
    host_fixes: list[Fix] | None = None
    #: machine-readable figures of the run (summary.json)
    metrics: dict[str, Any] = field(default_factory=dict)


def _world(scene: Any, t: float, p: Any) -> tuple[np.ndarray, float]:
    px, py, ph = (float(v) for v in scene.pose(t))
    rot = np.array([[math.cos(ph), -math.sin(ph)], [math.sin(ph), math.cos(ph)]])
    return rot @ np.asarray(p, float) + (px, py), ph


def _by_receiver_count(positions: np.ndarray, inputs: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
                       ) -> Iterator[tuple[list[int], np.ndarray, np.ndarray, np.ndarray]]:
    """Geometry inputs ``(receivers, path lengths, source)`` stacked for the vectorised solvers,
    one group per receiver count: (the group's indices into ``inputs``, receiver positions
    (M,N,2), path lengths (M,N), sources (M,2))."""
    by_n: dict[int, list[int]] = {}
    for i, (rx, _, _) in enumerate(inputs):
        by_n.setdefault(len(rx), []).append(i)
    for rows in by_n.values():
        yield (rows, np.stack([positions[inputs[i][0]] for i in rows]), np.stack([inputs[i][1] for i in rows]),
               np.stack([inputs[i][2] for i in rows]))


def _host_fixes(scene: Any, pulses: list[tuple[float, str, np.ndarray, np.ndarray, np.ndarray]]) -> list[Fix]:
    """The host geometry's fixes of pulses ``(t, sensor name, receivers, path lengths (m) from
    source (robot frame))``: the classification (multisonar.geometry.classify) and, where it
    says edge or wall, that model's fit, placed with the pose at ``t``; a pulse whose
    classification gives no valid edge or wall makes no fix. One vectorised call per receiver
    count (a per-pulse classify fits every model twice), fixes in pulse order."""
    from . import geometry

    fixes: dict[int, Fix] = {}
    for rows, C, R, S in _by_receiver_count(scene.layout.positions, [p[2:] for p in pulses]):
        kind = geometry.classify_batch(C, R, S).kind
        for what, solve in (("wall", geometry.solve_wall_batch), ("edge", geometry.solve_point_batch)):
            sel = np.flatnonzero(kind == geometry.KINDS.index(what))
            if not sel.size:
                continue
            fit = solve(C[sel], R[sel], S[sel], tol=np.inf, max_gdop=np.inf)
            for j in np.flatnonzero(fit.valid):
                i = rows[sel[j]]
                t, name = pulses[i][0], pulses[i][1]
                if what == "wall":
                    foot, ph = _world(scene, t, fit.foot[j])
                    fixes[i] = Fix(t, name, "wall", *foot, float(fit.normal_angle[j]) + ph,
                                   _truth_distance(foot, scene, walls=True, points=False))
                else:
                    p, _ = _world(scene, t, fit.position[j])
                    fixes[i] = Fix(t, name, "edge", *p, 0.0, _truth_distance(p, scene, walls=True, points=True))
    return [fixes[i] for i in sorted(fixes)]


def run_golden(scene: Any, duration: float, *, progress: bool = True, sensors: str = "demo",
               miss_hold: bool = True) -> DemoRun:
    """The golden model on the demo's sensors: tick-exact scheduler and gating, host geometry
    (``miss_hold``: RX_FILTER.miss_hold, default its reset value)."""
    from .fastfiring import SEQ_W, FastFiringModel, SceneEchoSource
    from .georecord import sensor_paths
    from .schedule import Schedule

    layout = scene.layout
    schedule = Schedule(layout, demo_sensors(sensors), temperature_c=scene.temperature_c)
    resolved = schedule.validate()
    # the device's decision lead: the model of the device, not the paper's zero-latency rule
    model = FastFiringModel(schedule, SceneEchoSource(scene), decision_lead=DEVICE_DECISION_LEAD,
                            miss_hold=miss_hold)
    c = scene.speed_of_sound
    t_wall = time.time()
    chunk = int(0.05 * TICK_HZ)
    events, pulses = [], []
    done, total = 0, int(duration * TICK_HZ)
    while done < total:
        step = min(chunk, total - done)
        res = model.run(step)
        events += res.events
        pulses += res.pulses
        done += step
        if progress:
            _progress(done / TICK_HZ, duration, t_wall, "golden model ")
    if progress:
        sys.stderr.write("\n")
    wall_s = time.time() - t_wall

    # Events carry the pulse number modulo 2**SEQ_W (as the RTL's FIFO word does): map each
    # back to the latest pulse of that sensor and residue issued before the event.
    issued: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for p in pulses:
        issued.setdefault((p.sensor, p.seq % (1 << SEQ_W)), []).append((p.t0, p.seq))
    t0_of = {(p.sensor, p.seq): p.t0 for p in pulses}
    by_pulse: dict[tuple[int, int], dict[int, int]] = {}
    for e in events:
        if e.sample:
            cands = [seq for t0, seq in issued.get((e.sensor, e.seq), []) if t0 <= e.tick]
            if cands:
                by_pulse.setdefault((e.sensor, cands[-1]), {})[e.rx] = e.tof
    todo = []
    for (sid, seq), tofs in by_pulse.items():
        r = resolved[sid]
        if len(tofs) < 3 or (sid, seq) not in t0_of:
            continue
        rx = np.array(sorted(tofs))
        source, paths = sensor_paths(layout, r, np.array([tofs[i] for i in rx]), c)
        todo.append((t0_of[(sid, seq)] / TICK_HZ, r.name, rx, paths, source))
    fixes = _host_fixes(scene, todo)
    ev = {k: np.array([getattr(e, k) for e in events]) for k in
          ("tick", "sensor", "seq", "rx", "tof", "in_window", "first_echo", "window_empty", "init_ping", "gated")}
    return DemoRun("golden", duration, wall_s, list(resolved),
                   pulses={r.id: sum(1 for p in pulses if p.sensor == r.id) for r in resolved},
                   init_pings={r.id: sum(1 for p in pulses if p.sensor == r.id and p.init) for r in resolved},
                   samples={r.id: sum(1 for e in events if e.sensor == r.id and e.sample)
                            for r in resolved},
                   fixes=fixes, events=ev)


def _thread_cpu() -> dict[int, float]:
    """CPU seconds of each thread of this process by native id (Linux /proc; {} elsewhere)."""
    import os

    out: dict[int, float] = {}
    try:
        hz = os.sysconf("SC_CLK_TCK")
        for d in Path("/proc/self/task").iterdir():
            fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            out[int(d.name)] = (int(fields[11]) + int(fields[12])) / hz  # utime + stime
    except (OSError, ValueError, IndexError):
        return {}
    return out


def _thread_busy(before: dict[int, float], after: dict[int, float], wall: float) -> dict[str, float]:
    """Each named thread's CPU time over ``wall`` seconds, those above 1 %, busiest first."""
    import threading

    names = {t.native_id: t.name for t in threading.enumerate()}
    share = {names.get(tid, str(tid)): (cpu - before.get(tid, 0.0)) / wall for tid, cpu in after.items()} \
        if wall > 0 else {}
    return {k: round(v, 3) for k, v in sorted(share.items(), key=lambda kv: -kv[1]) if v >= 0.01}


def run_twin(scene: Any, duration: float, *, out: Path, fst: str | None = None, usbip: bool = True,
             progress: bool = True, sensors: str = "demo", echo_source: Any = None) -> DemoRun:
    """The full-system twin on the demo's sensors: configured, started and streamed through the
    driver; fixes are the firmware's geometry records (robot frame) placed with the pose at t0.
    ``echo_source``: the echoes in place of the scene's (multisonar.fastfiring sources)."""
    from . import protocol as P
    from .device import RECORDING_FORMAT, RecordingWriter
    from .twin import open_twin

    t_wall = time.time()
    frames: list[Any] = []
    notes: list[str] = []
    if progress:
        sys.stderr.write("demo: building / loading the twin (make twin: Verilator, about 1-2 min the first time)\n")
    with open_twin(scene, usbip=usbip, fst=fst, echo_source=echo_source) as tw:
        t_boot = time.time()
        dev = tw.device
        sched = dev.configure(demo_sensors(sensors), temperature_c=scene.temperature_c)
        resolved = sched.validate()
        total = int(round(duration * TICK_HZ))
        meta = {"format": RECORDING_FORMAT, "protocol_version": P.PROTOCOL_VERSION, "url": tw.url, "started_unix": time.time(),
                "device_info": dev.info().__dict__, "sensors": dev._sensor_meta(), "scene": scene.name,
                "source": "multisonar demo --backend twin"}
        t_run, cpu0 = time.time(), _thread_cpu()
        start = tw.start()
        last = 0.0
        with RecordingWriter(out / "frames.msrec", meta) as rec:
            try:
                for f in dev.stream(idle_timeout_s=600.0):
                    frames.append(f)
                    rec.write(f)
                    done = tw.sim.tick - start
                    if progress and time.time() - last > 0.5:
                        last = time.time()
                        _progress(done / TICK_HZ, duration, t_run, "RTL twin ")
                    if done >= total:
                        break
            except DeviceDisconnected:
                if tw.server is not None and tw.server.failure is not None:
                    raise tw.server.failure  # the twin's own error, not the USB symptom
                raise
        wall_run = time.time() - t_run
        threads_busy = _thread_busy(cpu0, _thread_cpu(), wall_run)
        if progress:
            _progress(duration, duration, t_run, "RTL twin ")
            sys.stderr.write("\n")
        counters = dev.counters()
        cycles = {k[len("fw_cycles_"):]: int(v) for k, v in counters.items() if k.startswith("fw_cycles_")}
        harness = tw.sim.counters()
        mail = np.array(tw.sim.mailbox(), dtype=np.uint32)
        tags = mail >> 28
        commit = (mail[tags == 0x2] & 0x0FFFFFFF).astype(float)
        busy = (mail[tags == 0x4] & 0x0FFFFFFF).astype(float)
        geo_jobs = mail[tags == 0x6] & 0x0FFFFFFF
        geo_what, geo_cycles = geo_jobs >> 24, (geo_jobs & 0xFFFFFF).astype(float)
        moves = _reaim_log(mail, frames, start, resolved, scene.layout.n)
        reaims = sum(1 for m in moves if not m["refused"])
        usb = dict(tw.function.stats)
        notes.append(f"Device time simulated: {tw.sim.seconds:.3f} s ({tw.sim.cycles:,} clocks at 48 MHz: boot, "
                     f"enumeration and configuration {(start / TICK_HZ) * 1e3:.1f} ms, then {duration:.2f} s of sonar "
                     f"time) in {time.time() - t_wall:.1f} s wall ({t_boot - t_wall:.1f} s build/load); "
                     f"streaming ran at {duration / wall_run:.4f} sonar-s per wall-s "
                     f"({total / wall_run / 1e6:.3f} M clocks/s).")
        notes.append(f"Device counters: frames sent {counters['frames_sent']}, dropped {counters['frames_dropped']}, "
                     f"FIFO overflows {counters['fifo_overflows']}, watchdog {counters['watchdog']}, bad commands "
                     f"{counters['bad_commands']}; driver: {counters['host_frames']} frames, lost {counters['host_lost']}, "
                     f"bad CRC {counters['host_bad_crc']}.")
        notes.append(f"USB (full-speed bus time kept, transaction level): {usb['bytes_in']:,} bytes in / "
                     f"{usb['bytes_out']:,} out in {usb['in_packets']} / {usb['out_packets']} data packets, "
                     f"{usb['in_naks']} NAKed IN polls (every 50 us while no frame waits).")
        if len(commit):
            notes.append(f"Firmware (mailbox): {len(commit)} ToF frames; pulse completion (its last window's "
                         f"terminal event) to ToF frame committed median {np.median(commit) / 48:.0f} us, 99 % "
                         f"{np.percentile(commit, 99) / 48:.0f} us, max {commit.max() / 48:.0f} us; main-loop busy "
                         f"cycles per frame median {np.median(busy):.0f}, 99 % {np.percentile(busy, 99):.0f}, max "
                         f"{busy.max():.0f}; {reaims} re-aims taken.")
        if moves:
            notes.append("Re-aims (each restarts every sensor's track): " + "; ".join(
                f"{m['sensor']} to shift {m['shift']:+d} ({m['why']}"
                + (f", refused: {m['refused']}" if m["refused"] else "")
                + (f") at {m['t_s']:.3f} s" if m["t_s"] is not None else ")") for m in moves) + ".")
        if cycles:
            notes.append("Firmware worst cycles per path (FW_STATS): " + ", ".join(
                f"{k.replace('_max', '')} {v:,}" for k, v in cycles.items()) + ".")
        busy_win = int(counters.get("fw_busy_window_max", 0))
        notes.append(f"Firmware busy budget: the busiest 10 ms window was {busy_win / BUSY_WINDOW_TICKS:.1%} busy "
                     f"({busy_win:,} cycles; the budget keeps it at most half plus one job); "
                     f"{len(commit) / duration:.0f} ToF frames per second of sonar time.")
        fixed = geo_what == 0
        notes.append(f"Geometry jobs: {int(fixed.sum())} fixes (cycles per fix with its frame: median "
                     f"{np.median(geo_cycles[fixed]) if fixed.any() else 0:.0f}, max "
                     f"{geo_cycles[fixed].max() if fixed.any() else 0:.0f}), {int(np.sum(geo_what == 1))} skipped "
                     f"(queue full), {int(np.sum(geo_what == 2))} declined by the bounded fast path, "
                     f"{int(np.sum(geo_what == 3))} stale (re-aimed twice since).")
        notes.append("Harness: " + ", ".join(f"{k} {v}" for k, v in harness.items()) + f", pulses fired "
                     f"{len(tw.sim.fires)}, comparator pulses driven {tw.sim.echo_rows}.")
        if threads_busy:
            notes.append("Threads busy while streaming (CPU time / wall time; the twin runs in usbip-in over USB/IP, "
                         "in MainThread in-process): "
                         + ", ".join(f"{k} {v:.0%}" for k, v in threads_busy.items()) + ".")
        es = tw.sim.echo_stats
        notes.append(f"Acoustic model: {es['calls']} calls, {es['threaded']} on the echo thread (docs/twin.md); "
                     f"the harness reached {es['fences']} fences and waited there {es['waited_s']:.2f} s of the "
                     f"{wall_run:.1f} s of streaming.")
        if harness["echoes_late"] or harness["trig_orphans"] or harness["fires_incomplete"]:
            notes.append("**Warning: the harness clipped echoes or could not attribute triggers (see counters).**")
        fw_host = _fw_vs_host(scene, resolved, frames, scene.speed_of_sound)
        host_fixes = _host_fixes_of_frames(scene, resolved, frames, tw.scene_time)
        fixes: list[Fix] = []
        for f in frames:
            t = tw.scene_time(f.t0)
            name = resolved[f.vs].name if f.vs < len(resolved) else f"vs{f.vs}"
            for g in f.geo:
                kind = P.GEO_CLASSES[int(g["cls"])] if int(g["cls"]) < len(P.GEO_CLASSES) else "none"
                p_robot = (int(g["x_mm"]) * 1e-3, int(g["y_mm"]) * 1e-3)
                if kind == "wall":
                    foot, ph = _world(scene, t, p_robot)
                    normal = int(g["normal"]) * 2 * math.pi / 65536 + ph
                    fixes.append(Fix(t, name, "wall", *foot, normal,
                                     _truth_distance(foot, scene, walls=True, points=False)))
                elif kind in ("edge", "cylinder"):
                    p, _ = _world(scene, t, p_robot)
                    fixes.append(Fix(t, name, "edge", *p, 0.0, _truth_distance(p, scene, walls=True, points=True)))
    ev_rows = P.frames_to_events(frames)
    flags = ev_rows["flags"].astype(int)
    ev = {"t0": ev_rows["t0"], "timestamp": ev_rows["timestamp"], "sensor": ev_rows["vs"],
          "seq": ev_rows["pulse_seq"], "rx": ev_rows["rx"], "tof": ev_rows["tof"],
          "in_window": (flags & 1) > 0, "first_echo": (flags & 2) > 0, "window_empty": (flags & 4) > 0,
          "init_ping": (flags & 8) > 0, "gated": (flags & P.TOF_GATED) > 0}
    pulse_frames = [f for f in frames if not f.is_geometry]
    vs = np.array([f.vs for f in pulse_frames], dtype=int)
    init = np.array([bool(f.flags & P.FRAME_INIT_PING) for f in pulse_frames], dtype=bool)
    samples = ev["first_echo"] & ev["in_window"] & ~ev["gated"]
    lat_us = commit / (TICK_HZ / 1e6)
    metrics = {
        "sonar_s": duration, "wall_s": round(wall_run, 3), "sonar_s_per_wall_s": round(duration / wall_run, 5),
        "echo_thread": {k: round(v, 3) if isinstance(v, float) else v for k, v in es.items()},
        "thread_busy": threads_busy,
        "fifo_overflows": int(counters["fifo_overflows"]), "frames_lost": int(counters["host_lost"]),
        "frames_dropped": int(counters["frames_dropped"]), "watchdog": int(counters["watchdog"]),
        "frames_flagged_lost": int(sum(1 for f in pulse_frames if f.flags & P.FRAME_LOST)),
        "frames_cut": int(sum(1 for f in pulse_frames if f.flags & P.FRAME_CUT)),
        "geo_fixes": int(np.sum(geo_what == 0)), "geo_skipped": int(np.sum(geo_what == 1)),
        "geo_declined": int(np.sum(geo_what == 2)), "geo_stale": int(np.sum(geo_what == 3)),
        "geo_cycles_max": int(geo_cycles[geo_what == 0].max()) if np.any(geo_what == 0) else 0,
        "latency_us": {"p50": _pct(lat_us, 50), "p99": _pct(lat_us, 99),
                       "max": round(float(lat_us.max()), 1) if len(lat_us) else None},
        "busy_cycles_max": int(busy.max()) if len(busy) else 0,
        "busy_cycles_p99": _pct(busy, 99),
        # the firmware's busy budget (firmware/README.md "Busy budget"): its busiest 10 ms window
        "busy_share_max": round(busy_win / BUSY_WINDOW_TICKS, 3),
        # the firmware's worst cycles per bounded path (FW_STATS; firmware/README.md)
        "firmware_cycles": cycles,
        "reaims": reaims, "reaim_log": moves, "fw_vs_host": fw_host["summary"],
    }
    return DemoRun("twin", duration, time.time() - t_wall, list(resolved),
                   pulses={r.id: int(np.sum(vs == r.id)) for r in resolved},
                   init_pings={r.id: int(np.sum(init & (vs == r.id))) for r in resolved},
                   samples={r.id: int(np.sum(samples & (ev["sensor"] == r.id))) for r in resolved},
                   fixes=fixes, events=ev, notes=notes + fw_host["notes"], metrics=metrics,
                   host_fixes=host_fixes)


#: why the firmware moved a sensor (reaim.c, the low nibble of its 0x3 mailbox record)
REAIM_WHY = {1: "fix off axis", 2: "track lost"}


def _reaim_log(mail: np.ndarray, frames: list[Any], start: int, resolved: list[Any],
               n_elements: int) -> list[dict[str, Any]]:
    """The firmware's re-aim records (mailbox tag 0x3: vs, shift, refusal, why) in order, each
    taken move with the sonar time of the new table's first frame (the tag-0x5 record before it
    names that frame's sequence number; None if that frame never arrived). The shift, elements
    the groups sit from their configured place, is signed (the firmware keeps it mod the ring)."""
    t0_of_seq = {f.seq: f.t0 for f in frames}
    half = n_elements // 2
    out: list[dict[str, Any]] = []
    first_seq = None
    for w in (int(x) for x in mail):
        if w >> 28 == 0x5:
            first_seq = w & 0x0FFFFFFF
        elif w >> 28 == 0x3:
            vs, shift, err, why = (w >> 16) & 0xF, (w >> 8) & 0xFF, (w >> 4) & 0xF, w & 0xF
            t0 = t0_of_seq.get(first_seq) if not err else None
            out.append({"sensor": resolved[vs].name if vs < len(resolved) else f"vs{vs}",
                        "shift": (shift + half) % n_elements - half, "why": REAIM_WHY.get(why, str(why)),
                        "refused": err, "t_s": None if t0 is None else round(((t0 - start) & 0xFFFFFFFF) / TICK_HZ, 4)})
            first_seq = None
    return out


def _pct(v: np.ndarray, q: float) -> float | None:
    return round(float(np.percentile(v, q)), 1) if len(v) else None


def _first_echo_paths(layout: Any, resolved: list[Any], frame: Any, c: float) -> tuple[Any, ...] | None:
    """A ToF frame's first echoes in their windows as geometry input: its sensor, receivers
    (ascending), the source and the path lengths (m), with the sensor's groups moved by the
    re-aim shift that maps its configured receivers onto the frame's; None with fewer than
    three or for a sensor not in ``resolved``."""
    from . import protocol as P
    from .georecord import receiver_shift, sensor_paths

    if frame.vs >= len(resolved):
        return None
    sensor, n = resolved[frame.vs], layout.n
    firsts = {int(x["rx"]): int(x["tof"]) for x in frame.tof if int(x["flags"]) & P.TOF_SAMPLE_MASK == P.TOF_SAMPLE}
    rxs = sorted(firsts)
    shift = receiver_shift(sensor.rx, rxs, n)
    if shift is None or len(rxs) < 3:
        return None
    source, paths = sensor_paths(layout, sensor, np.array([firsts[e] for e in rxs]), c, shift)
    return sensor, np.array(rxs), source, paths


def _host_fixes_of_frames(scene: Any, resolved: list[Any], frames: list[Any], scene_time: Any) -> list[Fix]:
    """The host geometry on the twin's own ToF frames: a fix from every pulse with at least three
    first echoes in its windows (not lost), as the golden run makes them from its events. Set
    against the firmware's fixes of the same run, it separates what the firmware computes from
    what the data holds (echoes of other pulses that line up, re-aimed groups)."""
    from . import protocol as P

    layout, c = scene.layout, scene.speed_of_sound
    todo = []
    for f in frames:
        got = None if f.is_geometry or f.flags & P.FRAME_LOST else _first_echo_paths(layout, resolved, f, c)
        if got is None:
            continue
        r, rxs, source, paths = got
        todo.append((scene_time(f.t0), r.name, rxs, paths, source))
    return _host_fixes(scene, todo)


#: a firmware class other than the host's is no mismatch where it is the host's with one test
#: decided the other way, the host's value lying within this fraction of the test's bound: the
#: firmware's fixed-point chi-square is accurate to 1e-2 (tests/test_fw_geometry.py,
#: test_classify_matches_python), so its tests there may go either way
CLASS_THRESHOLD_BAND = 0.01


def _geo_class(edge: bool, wall: bool, gap: float) -> int:
    """GEO_CLASSES index of geometry.classify's decision from the edge (point) and wall models'
    accept tests and their chi-square gap (point - wall), the cylinder not accepted (the
    firmware has no cylinder model)."""
    from .geometry import decide_kind

    return int(decide_kind(edge, wall, False, gap)) + 1  # KINDS index -> GEO_CLASSES index


def _at_threshold(fw_cls: int, host_cls: int, chi2: Sequence[float], threshold: Sequence[float],
                  accepted: Sequence[bool]) -> bool:
    """Whether the firmware's geometry class (GEO_CLASSES: 1 edge, 2 wall, 4 uncertain) differs
    from the host's only by the host's tests decided the other way where their values lie
    within CLASS_THRESHOLD_BAND of their bounds: the point (edge) or the wall model's accept test
    (its chi-square against its threshold; the two together where both are at theirs), or, both
    accepted, the likelihood-ratio test (their chi-square gap against geometry.LR_GAP, to the
    band of their sum). ``chi2``, ``threshold``, ``accepted``: the host's
    (geometry.classify_batch) for the point and the wall model."""
    from .geometry import LR_GAP

    if fw_cls == host_cls or not {fw_cls, host_cls} <= {1, 2, 4}:
        return False
    (x_p, x_w), (t_p, t_w), (e, w) = chi2[:2], threshold[:2], (bool(accepted[0]), bool(accepted[1]))
    gap, band = x_p - x_w, CLASS_THRESHOLD_BAND

    def near(x: float, bound: float, scale: float) -> bool:
        return math.isfinite(x) and abs(x - bound) <= band * scale

    flipped = []
    if near(x_p, t_p, t_p):
        flipped.append(_geo_class(not e, w, gap))
    if near(x_w, t_w, t_w):
        flipped.append(_geo_class(e, not w, gap))
        if near(x_p, t_p, t_p):  # (both at their bounds)
            flipped.append(_geo_class(not e, not w, gap))
    if e and w and near(abs(gap), LR_GAP, x_p + x_w):
        flipped.append(4 if abs(gap) > LR_GAP else 1 if gap < 0 else 2)
    return fw_cls in flipped


def _fw_vs_host(scene: Any, resolved: list[Any], frames: list[Any], c: float) -> dict[str, Any]:
    """Every firmware geometry record against the record the host computes from the same
    pulse's ToF records (multisonar.georecord, as the simulated device does): same class and,
    for a fix (edge, wall), x, y within 1 mm, or a mismatch (a class decided at a threshold,
    CLASS_THRESHOLD_BAND, is counted apart as borderline). An 'uncertain' record's position
    (the point fit of data neither model explains, often ill-conditioned) is not a fix: its
    distance is reported apart (``uncertain_max_mm``). The firmware has no cylinder model (firmware/geometry/
    ms_geom.h: where Python answers 'cylinder' it answers 'uncertain'), so a host cylinder
    counts as uncertain. The pulse's groups may have been moved by re-aiming: the shift is the
    rotation that maps the configured receivers onto the ToF records'."""
    from . import geometry
    from . import protocol as P
    from .georecord import geo_records

    layout = scene.layout
    last_tof: dict[tuple[int, int], Any] = {}
    compared = mismatches = borderline = 0
    max_mm = uncertain_max_mm = 0.0
    examples: list[str] = []
    pairs = []  # (geometry frame, sensor, receivers, source, path lengths of its pulse's ToF frame)
    for f in frames:
        key = (f.vs, f.pulse_seq)
        if not f.is_geometry:
            last_tof[key] = f
            continue
        tf = last_tof.get(key)
        got = None if tf is None or tf.t0 != f.t0 else _first_echo_paths(layout, resolved, tf, c)
        if got is not None:
            pairs.append((f, *got))
    wants: list[Any] = [None] * len(pairs)
    tests: list[Any] = [None] * len(pairs)  # the host's (chi2, threshold, accepted) of the point, wall
    for rows, C, R, S in _by_receiver_count(layout.positions, [(rxs, paths, source)
                                                               for _, _, rxs, source, paths in pairs]):
        for i, rec in zip(rows, geo_records(C, R, S)):
            wants[i] = rec
        with np.errstate(all="ignore"):
            cb = geometry.classify_batch(C, R, S)
        thr = cb.threshold[:2].tolist()  # (the same for every row of a receiver count)
        for k, i in enumerate(rows):
            tests[i] = (cb.chi2[k, :2].tolist(), thr, cb.accepted[k, :2].tolist())
    for (f, r, rxs, source, paths), want, test in zip(pairs, wants, tests):
        for g in f.geo:
            compared += 1
            if want is None:
                mismatches += 1
                continue
            d = math.hypot(int(g["x_mm"]) - int(want["x_mm"]), int(g["y_mm"]) - int(want["y_mm"]))
            want_cls = 4 if int(want["cls"]) == 3 else int(want["cls"])
            is_fix = want_cls in (1, 2)
            if is_fix:
                max_mm = max(max_mm, d)
            elif int(g["cls"]) == want_cls:
                uncertain_max_mm = max(uncertain_max_mm, d)
            if test is not None and _at_threshold(int(g["cls"]), want_cls, *test):
                borderline += 1  # either answer is right at a threshold
                continue
            if int(g["cls"]) != want_cls or (is_fix and (abs(int(g["x_mm"]) - int(want["x_mm"])) > 1
                                                         or abs(int(g["y_mm"]) - int(want["y_mm"])) > 1)):
                mismatches += 1
                if len(examples) < 3:
                    examples.append(f"{r.name} pulse {f.pulse_seq}: firmware {P.GEO_CLASSES[int(g['cls'])]} "
                                    f"({int(g['x_mm'])}, {int(g['y_mm'])}) mm, host "
                                    f"{P.GEO_CLASSES[int(want['cls'])]} ({int(want['x_mm'])}, {int(want['y_mm'])}) mm")
    notes = [f"Firmware geometry vs host geometry on the same ToF records: {compared} compared, {mismatches} "
             f"mismatches (class, a host cylinder counting as uncertain, or a fix's x / y more than 1 mm "
             f"apart), largest distance of a fix {max_mm:.1f} mm (of an uncertain record's position "
             f"{uncertain_max_mm:.1f} mm); {borderline} other class at a threshold (the host's chi-square "
             f"within {CLASS_THRESHOLD_BAND:.0%} of it, where the fixed-point test may decide either way)."
             + ("".join(f" E.g. {e}." for e in examples))]
    return {"summary": {"compared": compared, "mismatches": mismatches, "borderline": borderline,
                        "max_mm": round(max_mm, 1), "uncertain_max_mm": round(uncertain_max_mm, 1)},
            "notes": notes}


BACKENDS = ("twin", "golden")
#: sonar time of the twin demo by default: the corridor's straight run past the door
TWIN_DEFAULT_SECONDS = 2.0


def run_demo(scene_name: str = "corridor", out: str | Path = "build/demo", seconds: float | None = None, *,
             backend: str = "twin", fst: str | None = None, usbip: bool = True, compare: bool = True,
             sensors: str = "demo", echo_source: Any = None) -> int:
    from .scene import load_scene

    if backend not in BACKENDS:
        raise ValueError(f"unknown demo backend {backend!r}; known: {', '.join(BACKENDS)}")
    n_sensors = len(demo_sensors(sensors))
    if fst is not None and backend != "twin":
        raise ValueError("--fst needs the twin backend (the golden model has no waveforms)")
    if echo_source is not None and (backend != "twin" or compare):
        raise ValueError("an echo source other than the scene's runs on the twin alone (compare=False)")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scene = load_scene(scene_name)
    if seconds is None:
        seconds = min(scene.duration_s, TWIN_DEFAULT_SECONDS) if backend == "twin" else scene.duration_s
    duration = float(seconds)
    if not duration > 0:
        raise ValueError(f"sonar time to simulate must be positive, got {duration}")
    what = ("RTL twin (Verilator: sonar core + VexRiscv firmware + USB device; driver over "
            + ("USB/IP)" if usbip else "an in-process backend)")) if backend == "twin" else "golden model"
    print(f"demo: scene {scene.name!r} ({scene.n_reflectors} reflectors), {n_sensors} virtual sensors ({sensors}), "
          f"{duration:.2f} s of sonar time, {what}")
    if backend == "twin":
        main = run_twin(scene, duration, out=out, fst=fst, usbip=usbip, sensors=sensors, echo_source=echo_source)
        ref = run_golden(scene, duration, sensors=sensors) if compare else None
    else:
        main, ref = run_golden(scene, duration, sensors=sensors), None
    summary = _summary(scene, main, ref, fst)
    (out / "summary.md").write_text(summary)
    (out / "summary.json").write_text(json.dumps(_summary_json(scene, main, ref), indent=2) + "\n")
    with open(out / "fixes.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "sensor", "kind", "x_m", "y_m", "normal_rad", "error_m"])
        for f in main.fixes:
            w.writerow([f"{f.t:.6f}", f.sensor, f.kind, f"{f.x:.5f}", f"{f.y:.5f}", f"{f.normal:.5f}", f"{f.error:.5f}"])
    np.savez_compressed(out / "events.npz", **main.events)
    _plot_map(scene, main.fixes, duration, out / "map.png", main.backend)
    print(summary)
    files = [out / "map.png", out / "summary.md", out / "summary.json", out / "fixes.csv", out / "events.npz"]
    if backend == "twin":
        files.append(out / "frames.msrec")
    if fst:
        files.append(Path(fst))
    print("demo: wrote " + ", ".join(str(f) for f in files))
    return 0


def _fix_errors(fixes: list[Fix]) -> dict[str, Any]:
    out = {}
    for kind in ("wall", "edge"):
        e = np.array([f.error for f in fixes if f.kind == kind]) * 1e3
        out[kind] = {"count": int(len(e)), "median_mm": round(float(np.median(e)), 1) if len(e) else None,
                     "p95_mm": round(float(np.percentile(e, 95)), 1) if len(e) else None}
    return out


def _summary_json(scene: Any, run: DemoRun, ref: DemoRun | None) -> dict[str, Any]:
    """summary.json: the run's figures, per-sensor rates and per fix kind the median and 95 %
    error of the device's (twin: firmware) fixes, of the host geometry on the same run's ToF
    frames (``host_same_run``, twin) and of the host geometry of the golden model (``host``)."""
    out: dict[str, Any] = {"scene": scene.name, "backend": run.backend, "sonar_s": run.duration,
                           "wall_s": round(run.wall_s, 3)}
    out.update(run.metrics)
    out.setdefault("sonar_s_per_wall_s", round(run.duration / run.wall_s, 5))
    out["sensors"] = {r.name: {"pulses": run.pulses[r.id], "init_pings": run.init_pings[r.id],
                               "samples_per_s_per_rx": round(run.samples[r.id] / len(r.rx) / run.duration, 2)}
                      for r in run.resolved}
    out["fixes"] = {"firmware" if run.backend == "twin" else "host": _fix_errors(run.fixes)}
    if run.host_fixes is not None:
        out["fixes"]["host_same_run"] = _fix_errors(run.host_fixes)
    if ref is not None:
        out["fixes"]["host"] = _fix_errors(ref.fixes)
    return out


def _summary(scene: Any, run: DemoRun, ref: DemoRun | None, fst: str | None) -> str:
    title = "RTL twin" if run.backend == "twin" else "Golden model"
    lines = [f"# Multisonar demo: scene `{scene.name}`, {title}", "",
             f"{title}, {run.duration:.2f} s of sonar time in {run.wall_s:.1f} s wall time "
             f"({run.duration / run.wall_s:.4f} sonar-s per wall-s, all included).", ""]
    for n in run.notes:
        lines += [n, ""]
    head = "| sensor | tx | rx | pulses | init pings | samples/s per receiver | fixes (wall / edge) |"
    rule = "|---|---|---|---:|---:|---:|---|"
    if ref is not None:
        head += " golden model: samples/s per receiver | golden fixes (wall / edge) |"
        rule += "---:|---|"
    lines += [head, rule]
    for r in run.resolved:
        fw = sum(1 for f in run.fixes if f.sensor == r.name and f.kind == "wall")
        fe = sum(1 for f in run.fixes if f.sensor == r.name and f.kind == "edge")
        row = (f"| {r.name} | {list(map(int, r.tx))} | {list(map(int, r.rx))} | {run.pulses[r.id]} | "
               f"{run.init_pings[r.id]} | {run.samples[r.id] / len(r.rx) / run.duration:.1f} | {fw} / {fe} |")
        if ref is not None:
            gw = sum(1 for f in ref.fixes if f.sensor == r.name and f.kind == "wall")
            ge = sum(1 for f in ref.fixes if f.sensor == r.name and f.kind == "edge")
            row += f" {ref.samples[r.id] / len(r.rx) / ref.duration:.1f} | {gw} / {ge} |"
        lines.append(row)
    lines += ["", "| fix kind | source | count | median error [mm] | 95% error [mm] | max error [mm] |",
              "|---|---|---:|---:|---:|---:|"]
    sources = [("firmware (twin)" if run.backend == "twin" else "host geometry (golden)", run.fixes)]
    if run.host_fixes is not None:
        sources.append(("host geometry (twin's ToF frames)", run.host_fixes))
    if ref is not None:
        sources.append(("host geometry (golden)", ref.fixes))
    for kind in ("wall", "edge"):
        for label, fixes in sources:
            errs = np.array([f.error for f in fixes if f.kind == kind])
            if len(errs):
                lines.append(f"| {kind} | {label} | {len(errs)} | {np.median(errs) * 1e3:.1f} | "
                             f"{np.percentile(errs, 95) * 1e3:.1f} | {errs.max() * 1e3:.1f} |")
            else:
                lines.append(f"| {kind} | {label} | 0 | - | - | - |")
    lines += ["", "Error: distance from the fix to the nearest true wall segment or cylinder surface (walls),",
              "or to the nearest true edge/rod, wall or cylinder surface (edges). Fixes are plotted in world coordinates from the pose at",
              "pulse time; the robot's motion during the ~5 ms flight is not compensated."]
    if run.backend == "twin":
        lines += ["The twin's firmware re-aims its virtual sensors at what it finds (adaptive re-aiming); the golden",
                  "model keeps the configured table and starts without the twin's boot and configuration. The scene's",
                  "noise (fading, jitter, spurious pulses) is drawn per pulse, so once the two runs fire at different",
                  "ticks they see different echoes, and a tracking sensor's rate differs as much as between two noise",
                  "seeds of the golden model (`seed:` in the scene file). The tests check the twin against the model",
                  "tick for tick under identical echoes."]
    if fst:
        lines += ["", f"Waveform: {fst} (FST, every signal of ms_system_usb)."]
    return "\n".join(lines) + "\n"


def _plot_map(scene, fixes: list[Fix], duration: float, path: Path, backend: str = "golden") -> None:
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
    what = "RTL twin: firmware fixes" if backend == "twin" else "golden model"
    ax.set_title(f"Multisonar map building, scene '{scene.name}' ({what})")
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
