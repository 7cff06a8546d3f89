"""Scoreboard of the twin against the golden model, and random schedules for property runs.

:func:`stream` configures a table through the driver, STARTs it and streams frames for a span
of device time; :func:`compare_with_model` replays the same span on
:class:`multisonar.fastfiring.FastFiringModel` (start tick = the scheduler's, decision lead =
the RTL's) with an echo source that gives the same echoes, and requires the same pulses (tick,
sensor, elements, phasing delays) and, for every frame, the model's ToF records of that pulse.
The firmware may re-aim a sensor on its own (a new table restarts the schedule): the comparison
covers the first table. Used by tests/test_twin.py and scripts/bench_twin_schedules.py.
"""

from __future__ import annotations

import random
from collections import defaultdict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from .. import protocol as P
from ..constants import DEVICE_DECISION_LEAD, TICK_HZ

LEAD = DEVICE_DECISION_LEAD  # the scheduler's decision lead (ticks), FastFiringModel(decision_lead=)


class TwinMismatch(AssertionError):
    """The twin and the golden model disagree (the message names the pulse or frame)."""


@dataclass
class StreamRun:
    schedule: Any
    frames: list[Any]
    fires: list[tuple[int, int, Any, Any]]
    start: int        #: the scheduler's first start tick
    end: int          #: end of the first table's span (the restart tick, or the last tick simulated)
    restarts: int     #: schedule starts after the first (firmware re-aims)
    counters: dict[str, int]
    harness: dict[str, int]
    start_status: str = "OK"
    extra: dict[str, Any] = field(default_factory=dict)


def stream(tw: Any, sensors: Sequence[Any], seconds: float, *, temperature_c: float = 20.0) -> StreamRun:
    """Configure ``sensors`` through the driver, START, stream ``seconds`` of device time."""
    dev = tw.device
    sched = dev.configure(list(sensors), temperature_c=temperature_c)
    tw.start()
    frames = []
    end = tw.sim.tick + int(seconds * TICK_HZ)
    for f in dev.stream(idle_timeout_s=600):
        frames.append(f)
        if tw.sim.tick >= end:
            break
    last = tw.sim.tick
    harness = tw.sim.counters()
    s0, s_last = tw.sim.first_schedule_start, tw.sim.schedule_start
    return StreamRun(sched, frames, list(tw.sim.fires), s0, s_last if harness["schedule_starts"] > 1 else last,
                     harness["schedule_starts"] - 1, dev.counters(), harness)


@dataclass
class FixedRun:
    """What one single-threaded session gave (:func:`fixed_session`)."""

    bulk_in: bytes                             #: every byte the device sent on bulk IN
    mailbox: list[int]                         #: the firmware's mailbox words
    fires: list[tuple[int, int, Any, Any]]     #: the pulses the device fired
    tick: int                                  #: the tick at the end
    state: bytes                               #: the model's whole state at the end (TwinSim.state)
    boot_state: bytes                          #: ... right after boot (before START)
    skip_stats: tuple[int, int]                #: (skips, clocks skipped)


def booted_corridor(seed: int, *, library: Any = None) -> Any:
    """A TwinSim on the noisy corridor (the scene's noise drawn from ``seed``), reset and booted:
    what :func:`fixed_session` starts from. ``library``: another build of the harness."""
    import numpy as np

    from ..fastfiring import SceneEchoSource
    from ..scene import load_scene
    from . import BOOT_CLOCKS
    from .sim import TwinSim

    sim = TwinSim(SceneEchoSource(load_scene("corridor"), rng=np.random.default_rng(seed)), library=library)
    sim.reset()
    sim.run(BOOT_CLOCKS)
    return sim


def start_table(sim: Any, *, skip: bool = False, stop_after: bool = False, harness_poll: bool = True) -> Any:
    """The start of a deterministic session on the booted twin ``sim``: enumerate,
    SET_CONFIGURATION 1, the exact skip on or off (TwinSim.set_skip, ``stop_after`` too), START
    the compiled-in table. Returns the twin's USB function (TwinUsbFunction)."""
    from .usbhost import ADDR, TwinUsbFunction

    fn = TwinUsbFunction(sim, harness_poll=harness_poll)
    fn.host.control_nodata(ADDR, 0x00, 9, 1, 0)  # SET_CONFIGURATION 1
    sim.set_skip(skip, stop_after=stop_after)
    fn.bulk_out(0x01, P.encode_command(P.Opcode.START, seq=1))
    return fn


def fixed_session(sim: Any, seconds: float, *, skip: bool = False, poll_s: float = 0.5e-3) -> FixedRun:
    """Run the booted twin ``sim`` deterministically in device time: enumerate, SET_CONFIGURATION,
    START the compiled-in table, then every ``poll_s`` of device time read bulk IN until it
    NAKs, for ``seconds``; one thread, no wall-clock timeouts (the driver's reader thread and its
    wall-clock deadlines make :func:`stream`'s USB timing vary run to run). The same sim and echo
    source give the same run, byte for byte, with or without ``skip`` (TwinSim.set_skip) if the
    skip is exact (tests/test_twin_skip.py)."""
    from .usbhost import ADDR, PID_DATA0, PID_DATA1

    boot = sim.state()
    fn = start_table(sim, skip=skip)
    end = sim.tick + int(seconds * TICK_HZ)
    data = bytearray()
    poll = int(poll_s * TICK_HZ)
    while sim.tick < end:
        sim.run(poll)
        while True:
            r = fn.host.in_token(ADDR, 1)
            if r.pid not in (PID_DATA0, PID_DATA1):
                break
            data += r.payload
    return FixedRun(bytes(data), sim.mailbox(), list(sim.fires), sim.tick, sim.state(), boot, sim.skip_stats)


def compare_with_model(run: StreamRun, echo_source: Any, **model_kw: Any) -> dict[str, int]:
    """Raise TwinMismatch unless the first table's pulses and frames equal the model's; returns
    the counts compared. ``echo_source`` must give the echoes the twin's gave (a fresh copy)."""
    from ..fastfiring import FastFiringModel

    h = run.harness
    if h["echoes_late"] or h["trig_orphans"] or h["fires_incomplete"]:
        raise TwinMismatch(f"harness could not keep up or attribute triggers: {h}")
    model = FastFiringModel(run.schedule, echo_source, start_tick=run.start, decision_lead=LEAD, **model_kw)
    res = model.run(run.end - run.start)
    cut = run.end - 2 * LEAD  # a restart's validation and rebuild take well under LEAD clocks
    got = [(t0, vs) for t0, vs, _, _ in run.fires if t0 < cut]
    want = [(p.t0, p.sensor) for p in res.pulses if p.t0 < cut]
    if got != want:
        k = next((i for i, (a, b) in enumerate(zip(got, want)) if a != b), min(len(got), len(want)))
        raise TwinMismatch(f"pulse {k}: twin {got[k:k + 3]} model {want[k:k + 3]} ({len(got)} vs {len(want)} pulses)")
    resolved = run.schedule.validate()
    for t0, vs, el, delays in (f for f in run.fires if f[0] < cut):
        r = resolved[vs]
        if sorted(zip(el.tolist(), delays.tolist())) != sorted(zip(map(int, r.tx), map(int, r.delays))):
            raise TwinMismatch(f"pulse at {t0} of sensor {vs}: elements {el.tolist()} delays {delays.tolist()}, "
                               f"table {list(map(int, r.tx))} {list(map(int, r.delays))}")
    closed = {(p.sensor, p.seq & 0xFF) for p in res.pulses if max((w[2] for w in p.windows), default=p.t0) < cut}
    t0_of: dict[tuple[int, int], int] = {}
    for p in res.pulses:
        t0_of.setdefault((p.sensor, p.seq & 0xFF), p.t0 & 0xFFFFFFFF)
    groups: dict[tuple[int, int], list[tuple[int, ...]]] = defaultdict(list)
    for e in res.events:
        groups[(e.sensor, e.seq)].append(P.tof_record(e))
    n_frames = n_rec = 0
    seen = set()
    for f in run.frames:
        key = (f.vs, f.pulse_seq)
        if not (f.timestamp < cut and key in closed) or key in seen:
            continue
        seen.add(key)
        rec = [tuple(int(r[n]) for n in ("tof", "rx", "seq", "vs", "flags")) for r in f.tof]
        if f.t0 != t0_of[key]:
            raise TwinMismatch(f"pulse {key}: frame t0 {f.t0}, model {t0_of[key]} (the hardware's pulse record)")
        if rec != groups.get(key, []):
            raise TwinMismatch(f"pulse {key}: frame records {rec}, model {groups.get(key)}")
        n_frames += 1
        n_rec += len(rec)
    return {"pulses": len(got), "frames": n_frames, "records": n_rec, "model_pulses": len(res.pulses),
            "conflicts": _conflicts(res.pulses, res.cancelled)}


def _conflicts(pulses: Sequence[Any], cancelled: Sequence[Any] = ()) -> int:
    """Receive windows that overlap a transmit blank (dead zone / crosstalk) on one element."""
    cut = {(s, k, rx): t for s, k, rx, t in cancelled}
    wins: dict[int, list[tuple[int, int]]] = defaultdict(list)
    blanks: dict[int, list[tuple[int, int]]] = defaultdict(list)
    for p in pulses:
        for e, a, b in p.windows:
            wins[e].append((a, min(b, cut.get((p.sensor, p.seq, e), b))))
        for e, a, b in p.blanks:
            blanks[e].append((a, b))
    return sum(1 for e, ws in wins.items() for w in ws for b in blanks.get(e, []) if b[0] < w[1] and w[0] < b[1])


def random_sensors(rng: random.Random, layout: Any, *, max_sensors: int = 4,
                   validate: Callable[[list[Any]], Any] | None = None) -> list[Any]:
    """A random table the validator accepts: 1..max_sensors virtual sensors, adjacent transmit
    groups of 1..3 elements (phased toward the default virtual source), 1..4 receivers, orders 0..4, track or
    init-only mode, random phase and miss limit. Tables the validator refuses are drawn again."""
    from ..schedule import Schedule, ScheduleError, VirtualSensor

    n = layout.n
    for _ in range(1000):
        sensors = []
        for i in range(rng.randint(1, max_sensors)):
            tx0, k = rng.randrange(n), rng.randint(1, 3)
            centre = tx0 + (k - 1) / 2
            rx = sorted({int(round(centre + rng.choice([-1, 0, 0, 1]) * rng.random() * 2)) % n
                         for _ in range(rng.randint(1, 4))})
            sensors.append(VirtualSensor(
                f"s{i}", tx=[(tx0 + j) % n for j in range(k)], rx=rx, order=rng.randint(0, 4),
                mode=rng.choice(["track", "track", "track", "init"]), phase=rng.random() * 5e-3,
                miss_limit=rng.randint(1, 4), max_range_m=rng.choice([1.0, 1.5, 2.5, 3.5])))
        try:
            (validate or (lambda s: Schedule(layout, s).validate()))(sensors)
        except (ScheduleError, ValueError):
            continue
        return sensors
    raise RuntimeError("no valid random table in 1000 draws")
