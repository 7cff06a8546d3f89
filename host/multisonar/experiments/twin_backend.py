"""The experiments' twin backend (``--backend twin``): one case on the full-system twin.

:func:`run_on_twin` boots the twin (:mod:`multisonar.twin`: the device's RTL in Verilator with
the scene's acoustic model in the loop), configures the case's virtual sensors through the
driver, starts them at a chosen scene time and streams frames for a given sonar time (or until
the case says it has seen enough). What it returns is only what the device reported: its ToF
frames as :class:`TwinPulse` (the first echoes the scheduler accepted per receiver, the groups
the pulse was fired with) and the firmware's geometry records as :class:`TwinFix`. fig9, fig10
and person compute their figures from these, the golden model's figures from the model's run.

Re-aiming: the firmware moves a sensor's groups on its own (firmware/README.md, "Re-aiming").
The groups a pulse was fired with are read from its ToF records (their receivers are the
configured ones turned by ``shift`` elements round the ring).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..constants import TICK_HZ
from ..fastfiring import SceneEchoSource
from ..georecord import receiver_shift
from .common import ExperimentError, Progress

#: the firmware's re-aim threshold (firmware/app/sonar/app.h REAIM_DEG): a fix whose bearing (a
#: wall: its normal) is more than this off the sensor's axis moves the groups one element
REAIM_DEG = 10.0


@dataclass
class TwinPulse:
    """One ToF frame: a pulse of one virtual sensor as the device reported it."""

    sensor: int  #: virtual sensor id (frame vs)
    name: str
    index: int  #: its place among the sensor's frames of the run (pulse ids restart at a re-aim)
    seq: int  #: pulse id (u8)
    t0: int  #: trigger tick, relative to START
    t_s: float  #: scene time of t0
    init: bool  #: an initialisation ping
    cut: bool  #: closed early (STOP or a re-aim's hand-over)
    lost: bool
    shift: int  #: the sensor's groups turned by this many elements (the firmware's re-aim)
    tx: list[int]  #: elements it fired
    rx: list[int]  #: receivers it listened with
    firsts: dict[int, int]  #: rx -> ToF (ticks) of the window's first echo the gate accepted
    empty: list[int]  #: receivers whose window closed empty

    @property
    def complete(self) -> bool:
        """Not cut, not lost: every window of the pulse ran to its end."""
        return not (self.cut or self.lost)

    def t_ref(self) -> float:
        """Scene time of the reflection: t0 + half the mean first-echo ToF (t0 without one)."""
        if not self.firsts:
            return self.t_s
        return self.t_s + float(np.mean(list(self.firsts.values()))) / 2 / TICK_HZ


@dataclass
class TwinFix:
    """One geometry record of the firmware (robot frame), with the pulse it came from."""

    sensor: int
    name: str
    t_s: float  #: scene time of the pulse's t0
    t_ref: float  #: scene time of the reflection (its ToF frame's first echoes; t0 without one)
    kind: str  #: protocol.GEO_CLASSES: edge | wall | uncertain | none
    xy: np.ndarray  #: edge position / wall foot point, m, robot frame
    normal: float  #: wall normal, rad, robot frame (0 for points)
    bearing: float  #: from the virtual source, rad, robot frame
    range_m: float
    pulse: TwinPulse | None  #: its ToF frame (None if it did not come)

    @property
    def fixed(self) -> bool:
        """An edge or wall fix (what the firmware re-aims on)."""
        return self.kind in ("edge", "wall")


@dataclass
class TwinRun:
    """What the device reported in one twin case."""

    scene: Any
    resolved: list[Any]
    t_offset_s: float  #: scene time at START
    pulses: list[TwinPulse]
    fixes: list[TwinFix]
    sonar_s: float  #: device time streamed after START
    wall_s: float  #: wall time of the case (boot, configuration and streaming)
    counters: dict[str, int] = field(default_factory=dict)  #: device and driver counters after the run
    harness: dict[str, int] = field(default_factory=dict)  #: the twin harness's counters (echoes late, ...)

    def sensor_pulses(self, sensor: int) -> list[TwinPulse]:
        return [p for p in self.pulses if p.sensor == sensor]

    def reaims(self, sensor: int) -> list[int]:
        """The placements (shifts) the sensor's pulses went through, in order."""
        out: list[int] = []
        for p in self.sensor_pulses(sensor):
            if not out or out[-1] != p.shift:
                out.append(p.shift)
        return out

    def placements(self, sensor: int) -> str:
        """:meth:`reaims` for a table: "0", "0>-1>0", ..."""
        return ">".join(f"{k:+d}" if k else "0" for k in self.reaims(sensor)) or "0"

    def fw_healthy(self) -> list[str]:
        """What went wrong on the link or in the harness (empty if nothing)."""
        bad = [f"{k} {self.counters[k]}" for k in ("frames_dropped", "fifo_overflows", "watchdog", "host_lost",
                                                     "host_bad_crc") if self.counters.get(k)]
        bad += [f"harness {k} {v}" for k, v in self.harness.items() if k in ("echoes_late", "trig_orphans",
                                                                             "fires_incomplete") and v]
        return bad


#: device time streamed after the end for the geometry frames of the pulses already reported
#: (a fix's frame follows its ToF frame by ~0.2 ms when the firmware is not backlogged)
DRAIN_S = 0.005


def run_on_twin(scene: Any, sensors: Sequence[Any], seconds: float, *, t_offset_s: float = 0.0,
                seed: int | None = None, stop: Callable[[TwinRun], bool] | None = None, progress: bool = True,
                label: str = "twin") -> TwinRun:
    """Run ``sensors`` (VirtualSensor) on the twin in ``scene`` (a Scene) from scene time
    ``t_offset_s`` for ``seconds`` of device time after START, or until ``stop(run so far)`` is
    true (checked after every frame); then DRAIN_S more for the geometry frames of the pulses
    reported (later pulses are left out). ``seed``: the acoustic model's random numbers (None:
    the scene's seed). Raises ExperimentError when the twin cannot be built or loaded."""
    from .. import protocol as P
    from ..twin import TwinError, open_twin

    if not seconds > 0:
        raise ValueError(f"sonar time on the twin must be positive, got {seconds}")
    t_wall = time.time()
    rng = None if seed is None else np.random.default_rng(seed)
    echoes = SceneEchoSource(scene, rng=rng)
    layout = scene.layout
    n = layout.n
    run = TwinRun(scene, [], t_offset_s, [], [], 0.0, 0.0)
    bar = Progress(label, seconds, enabled=progress)
    if progress:
        sys.stderr.write(f"  {label}: booting the twin\n")
    try:
        with open_twin(scene, usbip=False, echo_source=echoes) as tw:
            sched = tw.device.configure(list(sensors), temperature_c=scene.temperature_c)
            run.resolved = list(sched.validate())
            by_id = {r.id: r for r in run.resolved}
            start = tw.start(scene_t0=t_offset_s)
            total = int(round(seconds * TICK_HZ))
            shift_now: dict[int, int] = {}
            count: dict[int, int] = {}
            last_tof: dict[tuple[int, int, int], TwinPulse] = {}
            last_bar = 0.0
            end_tick = None  # set when the case is over: only geometry frames from then on
            for f in tw.device.stream(idle_timeout_s=600.0):
                rel = int(round(tw.scene_time(f.t0) * TICK_HZ))
                t_s = t_offset_s + rel / TICK_HZ
                r = by_id.get(f.vs)
                if end_tick is not None and tw.sim.tick >= end_tick:
                    break
                if r is None or (end_tick is not None and not f.is_geometry):
                    continue
                if not f.is_geometry:
                    rxs = {int(x) for x in f.tof["rx"]}
                    k = receiver_shift(r.rx, rxs, n) if rxs else None
                    shift = shift_now.get(f.vs, 0) if k is None else k
                    shift_now[f.vs] = shift
                    fl = f.tof["flags"].astype(int)
                    sample = (fl & P.TOF_SAMPLE_MASK) == P.TOF_SAMPLE
                    firsts = {int(x["rx"]): int(x["tof"]) for x, s in zip(f.tof, sample) if s}
                    empty = sorted({int(x["rx"]) for x, e in zip(f.tof, fl & P.TOF_WINDOW_EMPTY) if e})
                    pulse = TwinPulse(f.vs, r.name, count.get(f.vs, 0), f.pulse_seq, rel, t_s,
                                      bool(f.flags & P.FRAME_INIT_PING), bool(f.flags & P.FRAME_CUT),
                                      bool(f.flags & P.FRAME_LOST), shift, [(int(e) + shift) % n for e in r.tx],
                                      [(int(e) + shift) % n for e in r.rx], firsts, empty)
                    count[f.vs] = pulse.index + 1
                    run.pulses.append(pulse)
                    last_tof[(f.vs, f.pulse_seq, f.t0)] = pulse
                else:
                    pulse = last_tof.get((f.vs, f.pulse_seq, f.t0))
                    if pulse is None and end_tick is not None:  # a pulse after the end
                        continue
                    for g in f.geo:
                        cls = int(g["cls"])
                        kind = P.GEO_CLASSES[cls] if cls < len(P.GEO_CLASSES) else "none"
                        run.fixes.append(TwinFix(
                            f.vs, r.name, t_s, pulse.t_ref() if pulse is not None else t_s, kind,
                            np.array([int(g["x_mm"]), int(g["y_mm"])], float) * 1e-3,
                            float(P.from_binary_angle(int(g["normal"]))),
                            float(P.from_binary_angle(int(g["bearing"]))),
                            int(g["range_mm"]) * 1e-3, pulse))
                if end_tick is not None:
                    continue
                done = tw.sim.tick - start
                run.sonar_s = done / TICK_HZ
                if progress and time.time() - last_bar > 0.5:
                    last_bar = time.time()
                    bar(min(run.sonar_s, seconds))
                if done >= total or (stop is not None and stop(run)):
                    end_tick = tw.sim.tick + int(DRAIN_S * TICK_HZ)
            run.counters = tw.device.counters()
            run.harness = tw.sim.counters()
    except TwinError as e:
        raise ExperimentError(f"the twin cannot run here: {e} (it needs Verilator and the repository: "
                              "`make venv`, then `make twin`)") from None
    bar(min(run.sonar_s, seconds))
    bar.close()
    run.wall_s = time.time() - t_wall
    bad = run.fw_healthy()
    if bad and progress:
        sys.stderr.write(f"  {label}: warning: {', '.join(bad)}\n")
    return run


def placement_axis(layout: Any, sensor: Any, shift: int) -> float:
    """The firmware's axis of a sensor whose groups are turned by ``shift``: its middle transmit
    element's axis (two middles: halfway between them), rad."""
    n = layout.n
    tx = [(int(e) + shift) % n for e in sensor.tx]
    a = float(layout.axes[tx[(len(tx) - 1) // 2]])
    if len(tx) % 2 == 0:
        b = float(layout.axes[tx[len(tx) // 2]])
        a += math.remainder(b - a, 2 * math.pi) / 2
    return a
