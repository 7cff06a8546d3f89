"""Tick-exact golden model of the fast-firing scheduler (windowing + interlacing + tracking).

This is the cycle-level reference the RTL scheduler must match tick for tick; the contract
(ordering within a tick, interval conventions, prediction rule, deferral rule, event format)
is written out in ``docs/fast_firing.md``. All per-pulse arithmetic is on integer ticks.

Usage::

    sched = Schedule(load_layout(), [VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=2)])
    model = FastFiringModel(sched, SyntheticEchoSource(1.5))
    result = model.run(seconds_to_ticks(0.2))
    result.events      # ToFEvent list, in event-FIFO order
    result.words       # every event-FIFO word in order: ToF events and pulse records
    result.triggers    # TriggerEvent list (tick, element, sensor, seq)
"""

from __future__ import annotations

import heapq
import itertools
from bisect import bisect_left, bisect_right
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, NamedTuple, Protocol, Sequence, runtime_checkable

import numpy as np

from .constants import TICK_HZ, speed_of_sound
from .event_word import (CANCEL_FIELDS, CANCEL_RECORD_BIT, EVENT_FIELDS, EVENT_OVERFLOW_BIT,  # noqa: F401
                         PULSE_FIELDS, PULSE_ID_W, PULSE_RECORD_BIT)
from .layout import Layout
from .schedule import (DEFAULT_GLITCH_MIN, MISS_W, SEQ_W, TIMESTAMP_W, WIN_SLOTS, Mode,
                       ResolvedSensor, Schedule, effective_order, pulse_period)

SEQ_MASK = (1 << SEQ_W) - 1
#: RX_FILTER.miss_hold reset value: a sensor with a missed window stops interlacing (section 4.4)
DEFAULT_MISS_HOLD = True
#: RX_FILTER.miss_gate reset value, ticks (10.4 us): the gated miss rule of the RTL scheduler
DEFAULT_MISS_GATE = 500
TIMESTAMP_MASK = (1 << TIMESTAMP_W) - 1
MISS_MAX = (1 << MISS_W) - 1

# phases inside one tick (docs/fast_firing.md section 3)
_EDGE, _CLOSE, _SCHED = 0, 1, 2


# --------------------------------------------------------------------------------------
# Events
# --------------------------------------------------------------------------------------

class TriggerEvent(NamedTuple):
    tick: int  #: absolute tick the element's drive burst starts (RTL counter = tick mod 2**32)
    element: int
    sensor: int
    seq: int  #: pulse sequence number mod 2**SEQ_W




def _pack_fields(fields: dict[str, tuple[int, int]], values: Any, what: str, word: int = 0) -> int:
    """``word`` with each named field of ``values`` at its (lsb, width); ValueError if one does
    not fit its width."""
    for name, (lsb, width) in fields.items():
        v = int(getattr(values, name))
        if not 0 <= v < (1 << width):
            raise ValueError(f"{what} field {name}={v} does not fit {width} bits")
        word |= v << lsb
    return word


def _unpack_fields(fields: dict[str, tuple[int, int]], word: int) -> dict[str, int]:
    return {n: (word >> lsb) & ((1 << w) - 1) for n, (lsb, w) in fields.items()}


class ToFEvent(NamedTuple):
    tick: int  #: tick the event is written to the FIFO (not part of the word)
    sensor: int
    seq: int  #: mod 2**SEQ_W
    rx: int
    tof: int  #: edge tick - pulse t0 (window_empty: window end - t0)
    in_window: bool
    first_echo: bool
    window_empty: bool
    init_ping: bool
    #: a first echo the gated miss rule rejected (docs/fast_firing.md section 4.4): reported, but
    #: its window counts as a miss; geometry skips it
    gated: bool = False

    @property
    def sample(self) -> bool:
        """The first echo of its window that the gate accepted: a tracking sample and a geometry
        input (firmware, simulated device, host)."""
        return self.in_window and self.first_echo and not self.gated

    def pack(self) -> int:
        return _pack_fields(EVENT_FIELDS, self, "event")

    @classmethod
    def unpack(cls, word: int, tick: int = -1) -> "ToFEvent":
        f = _unpack_fields(EVENT_FIELDS, word)
        return cls(tick=tick, sensor=f["sensor"], seq=f["seq"], rx=f["rx"], tof=f["tof"],
                   in_window=bool(f["in_window"]), first_echo=bool(f["first_echo"]),
                   window_empty=bool(f["window_empty"]), init_ping=bool(f["init_ping"]), gated=bool(f["gated"]))




class PulseStart(NamedTuple):
    """The scheduler's record of an issued pulse, written in the SCHED phase of its decision
    tick (t0 - decision lead), before any event of the pulse."""
    tick: int  #: tick the record is written to the FIFO (not part of the word)
    sensor: int
    pulse_id: int  #: per-sensor pulse number mod 2**16 (its low 8 bits are the events' seq)
    t0: int  #: trigger tick mod 2**32
    init_ping: bool
    n_win: int  #: windows the pulse opened: one terminal event (first echo or window_empty) each

    def pack(self) -> int:
        return _pack_fields(PULSE_FIELDS, self, "pulse record", PULSE_RECORD_BIT)

    @classmethod
    def unpack(cls, word: int, tick: int = -1) -> "PulseStart":
        if word & (PULSE_RECORD_BIT | CANCEL_RECORD_BIT) != PULSE_RECORD_BIT:
            raise ValueError(f"event word {word:#018x} is not a pulse record (bit 62 set, 61 clear)")
        f = _unpack_fields(PULSE_FIELDS, word)
        return cls(tick=tick, sensor=f["sensor"], pulse_id=f["pulse_id"], t0=f["t0"],
                   init_ping=bool(f["init_ping"]), n_win=f["n_win"])


class SensorCancel(NamedTuple):
    """The scheduler's record of a re-initialisation that cancelled every pending window of a
    sensor (safety rule or forced re-init), written where the cancel happens (the CLOSE phase
    after the window that missed, or the SCHED phase before the init ping's record): every
    earlier pulse of the sensor gets no more events."""
    tick: int  #: logical tick of the cancel (mod 2**32 in the word)
    sensor: int

    def pack(self) -> int:
        return _pack_fields(CANCEL_FIELDS, self._replace(tick=self.tick & 0xFFFFFFFF), "cancel record",
                            PULSE_RECORD_BIT | CANCEL_RECORD_BIT)

    @classmethod
    def unpack(cls, word: int, tick: int = -1) -> "SensorCancel":
        if word & (PULSE_RECORD_BIT | CANCEL_RECORD_BIT) != PULSE_RECORD_BIT | CANCEL_RECORD_BIT:
            raise ValueError(f"event word {word:#018x} is not a cancel record (bits 62 and 61)")
        return cls(**_unpack_fields(CANCEL_FIELDS, word))


def unpack_word(word: int, tick: int = -1) -> "ToFEvent | PulseStart | SensorCancel":
    """An event-FIFO word as what it is: a record (bit 62: a pulse, or with bit 61 a cancel) or
    a ToF event."""
    if not word & PULSE_RECORD_BIT:
        return ToFEvent.unpack(word, tick)
    return SensorCancel.unpack(word, tick) if word & CANCEL_RECORD_BIT else PulseStart.unpack(word, tick)


@dataclass(frozen=True)
class PulseRecord:
    sensor: int
    seq: int  #: unwrapped pulse number (events carry seq mod 2**SEQ_W)
    due: int
    t0: int  #: issue tick (deferral = t0 - due)
    init: bool
    order: int  #: effective order n used for the period (-1 for an init ping)
    period: int  #: ticks until the next pulse of this sensor is due
    windows: tuple[tuple[int, int, int], ...]  #: (rx, start, end) absolute, half-open
    blanks: tuple[tuple[int, int, int], ...]  #: (element, start, end) absolute dead zone / crosstalk


@dataclass
class RunResult:
    triggers: list[TriggerEvent]
    events: list[ToFEvent]
    pulses: list[PulseRecord]
    #: windows cancelled by a re-initialisation: (sensor, seq, rx, tick); no event is written
    cancelled: list[tuple[int, int, int, int]] = field(default_factory=list)
    #: every event-FIFO word in FIFO order: ToF events and records (PulseStart, SensorCancel)
    words: list[int] = field(default_factory=list)
    records: list[Any] = field(default_factory=list)

    def samples(self, sensor: int | None = None, rx: int | None = None) -> list[ToFEvent]:
        """First echoes in window (the tracking samples), optionally filtered."""
        return [e for e in self.events if e.first_echo and (sensor is None or e.sensor == sensor)
                and (rx is None or e.rx == rx)]


# --------------------------------------------------------------------------------------
# Comparator input
# --------------------------------------------------------------------------------------

@runtime_checkable
class EchoSource(Protocol):
    def fire(self, t0_tick: int, elements: np.ndarray, delay_ticks: np.ndarray) -> Any:
        """Comparator pulses caused by one pulse: rows (rx, start_tick, width_ticks), absolute
        ticks, start >= t0_tick. A numpy structured array with those fields, an (m, 3) int array
        or a sequence of triples. Optional: ``noise(t_start_tick, t_end_tick)``, same format."""
        ...


def _rows(pulses: Any) -> np.ndarray:
    if pulses is None:
        return np.zeros((0, 3), dtype=np.int64)
    if isinstance(pulses, np.ndarray) and pulses.dtype.names:
        return np.stack([np.asarray(pulses["rx"]), np.asarray(pulses["start"]), np.asarray(pulses["width"])],
                        axis=1).astype(np.int64).reshape(-1, 3)
    a = np.asarray(pulses, dtype=np.int64)
    return a.reshape(-1, 3)


class SyntheticEchoSource:
    """Reflector at a range per receiver (one-way metres from the virtual source), echo ToF
    = round(2 r / c * TICK_HZ), measured from t0. Optional constant closing speed (m/s,
    positive = approaching: tof = 2 (r0 - v t0) / (c + v)), a step change at ``step_tick``
    (pulses fired at or after it see ``step_ranges_m``; ``occlude`` hides the old ranges) and a
    ring-down pulse on each firing element. Receivers not in ``ranges_m`` get no echo.
    ``spurious_rate_hz``: Poisson comparator pulses per receiver (``spurious_width_ticks``
    wide) from a generator seeded with ``seed``, as the scenes' noise model has them.
    """

    def __init__(self, ranges_m: float | Mapping[int, float | Sequence[float]], *, receivers: Iterable[int] = range(24),
                 temperature_c: float = 20.0, velocity_mps: float = 0.0, step_tick: int | None = None,
                 step_ranges_m: float | Mapping[int, float | Sequence[float]] | None = None, occlude: bool = True,
                 width_ticks: int = 9600, ringdown_ticks: int = 0, spurious_rate_hz: float = 0.0,
                 spurious_width_ticks: int = 2400, seed: int = 0) -> None:
        if spurious_rate_hz < 0:
            raise ValueError(f"spurious_rate_hz must be >= 0, got {spurious_rate_hz}")
        self.c = speed_of_sound(temperature_c)
        self.receivers = sorted(int(r) for r in receivers)
        self.spurious_rate, self.spurious_width = float(spurious_rate_hz), int(spurious_width_ticks)
        self._rng = np.random.default_rng(seed)
        self.ranges = self._norm(ranges_m, self.receivers)
        self.step_ranges = self._norm(step_ranges_m, self.receivers) if step_ranges_m is not None else None
        self.v, self.step_tick, self.occlude = velocity_mps, step_tick, occlude
        self.width, self.ringdown = int(width_ticks), int(ringdown_ticks)

    @staticmethod
    def _norm(r: Any, receivers: Iterable[int]) -> dict[int, list[float]]:
        if isinstance(r, Mapping):
            return {int(k): (list(v) if isinstance(v, (list, tuple)) else [float(v)]) for k, v in r.items()}
        return {int(k): [float(r)] for k in receivers}

    def tof_ticks(self, r0: float, t0_tick: int) -> int:
        t0 = t0_tick / TICK_HZ
        return int(round(2.0 * (r0 - self.v * t0) / (self.c + self.v) * TICK_HZ))

    def fire(self, t0_tick: int, elements: np.ndarray, delay_ticks: np.ndarray) -> list[tuple[int, int, int]]:
        out: list[tuple[int, int, int]] = []
        if self.ringdown:
            out += [(int(e), int(t0_tick + d), self.ringdown) for e, d in zip(elements, delay_ticks)]
        stepped = self.step_ranges is not None and self.step_tick is not None and t0_tick >= self.step_tick
        tables = ([self.step_ranges] if stepped else []) + ([self.ranges] if not (stepped and self.occlude) else [])
        for tab in tables:
            for rx, rs in tab.items():
                for r in rs:
                    tof = self.tof_ticks(r, t0_tick)
                    if tof > 0:
                        out.append((rx, t0_tick + tof, self.width))
        return out

    def noise(self, t_start_tick: int, t_end_tick: int) -> np.ndarray:
        """Spurious comparator pulses (rx, start tick, width) in [t_start_tick, t_end_tick)."""
        span = max(0, int(t_end_tick) - int(t_start_tick))
        if not self.spurious_rate or not span:
            return np.zeros((0, 3), dtype=np.int64)
        n = self._rng.poisson(self.spurious_rate * span / TICK_HZ, len(self.receivers))
        rx = np.repeat(np.asarray(self.receivers, dtype=np.int64), n)
        start = int(t_start_tick) + self._rng.integers(0, span, len(rx))
        rows = np.stack([rx, start, np.full(len(rx), self.spurious_width, dtype=np.int64)], axis=1)
        return rows[np.argsort(rows[:, 1], kind="stable")]


class PointEchoSource:
    """Geometric point reflector (optionally moving, position taken at t0): the echo reaches
    receiver r at min_i (t0 + d_i + (|c_i - p| + |p - c_r|) / c), the first wavefront of the
    phased group. No beam pattern; every listed receiver hears it."""

    rows_from_t0 = True  # (TwinSim may call it on its echo thread)

    def __init__(self, layout: Layout, point: Sequence[float], *, velocity: Sequence[float] = (0.0, 0.0),
                 temperature_c: float = 20.0, receivers: Iterable[int] | None = None, width_ticks: int = 9600) -> None:
        self.pos = layout.positions
        self.p0, self.vel = np.asarray(point, float), np.asarray(velocity, float)
        self.c = speed_of_sound(temperature_c)
        self.rx = np.arange(layout.n) if receivers is None else np.asarray(list(receivers), dtype=np.int64)
        self.width = int(width_ticks)

    def fire(self, t0_tick: int, elements: np.ndarray, delay_ticks: np.ndarray) -> np.ndarray:
        p = self.p0 + self.vel * (t0_tick / TICK_HZ)
        out_leg = np.linalg.norm(self.pos[np.asarray(elements)] - p, axis=1) / self.c * TICK_HZ + np.asarray(delay_ticks)
        back = np.linalg.norm(self.pos[self.rx] - p, axis=1) / self.c * TICK_HZ
        start = t0_tick + np.rint(out_leg.min() + back).astype(np.int64)
        return np.stack([self.rx, start, np.full(len(self.rx), self.width)], axis=1)


class SceneEchoSource:
    """Adapter for :mod:`multisonar.acoustics` (imported lazily): ticks <-> seconds. A comparator
    pulse starting at s seconds is first sampled high at tick ceil(s * TICK_HZ); its width is
    round(width * TICK_HZ) ticks (at least 1). ``t_offset_s`` maps tick 0 to scene time."""

    rows_from_t0 = True  # fire()'s rows start at t0 or later, noise()'s within its span

    def __init__(self, scene: Any, *, rng: Any = None, burst_cycles: int = 8, t_offset_s: float = 0.0,
                 model: Any = None) -> None:
        from . import acoustics  # lazy: written in parallel
        if isinstance(scene, str):
            from .scene import load_scene
            scene = load_scene(scene)
        self._ac = acoustics
        self.model = model if model is not None else acoustics.AcousticModel(scene, rng=rng)
        self.burst_cycles, self.t_offset = burst_cycles, t_offset_s

    def _convert(self, arr: np.ndarray) -> np.ndarray:
        if len(arr) == 0:
            return np.zeros((0, 3), dtype=np.int64)
        start = np.ceil((np.asarray(arr["start"], float) - self.t_offset) * TICK_HZ - 1e-6).astype(np.int64)
        width = np.maximum(1, np.rint(np.asarray(arr["width"], float) * TICK_HZ)).astype(np.int64)
        return np.stack([np.asarray(arr["rx"], dtype=np.int64), start, width], axis=1)

    def fire(self, t0_tick: int, elements: np.ndarray, delay_ticks: np.ndarray) -> np.ndarray:
        f = self._ac.Firing(t0=t0_tick / TICK_HZ + self.t_offset, elements=np.asarray(elements, dtype=np.int64),
                            delays=np.asarray(delay_ticks, dtype=np.float64) / TICK_HZ, burst_cycles=self.burst_cycles)
        rows = self._convert(self.model.fire(f))
        return rows[rows[:, 1] >= t0_tick] if len(rows) else rows

    def noise(self, t_start_tick: int, t_end_tick: int) -> np.ndarray:
        if not hasattr(self.model, "noise_pulses"):
            return np.zeros((0, 3), dtype=np.int64)
        return self._convert(self.model.noise_pulses(t_start_tick / TICK_HZ + self.t_offset,
                                                     t_end_tick / TICK_HZ + self.t_offset))


# --------------------------------------------------------------------------------------
# Model state
# --------------------------------------------------------------------------------------

@dataclass
class _Window:
    start: int
    end: int
    close: int  # tick its result is final (end - 1 + latency)
    sensor: int
    seq: int
    rx: int
    t0: int
    init: bool
    epoch: int
    n_edges: int = 0
    cancelled: bool = False
    rejected: bool = False  # (gated miss rule) the first echo was too far from the prediction


@dataclass
class _RxState:
    tracked: bool = False
    tof: int = 0  # last sample, ticks
    seq: int = 0  # pulse number of the last sample
    v: int = 0  # ticks per pulse
    miss: int = 0
    init: bool = False  # the last sample came from the init ping (its period differs)
    vel: bool = False  # v was measured (the last sample followed one of the previous pulse): gated miss rule on


@dataclass
class _SensorState:
    cfg: ResolvedSensor
    due: int
    seq: int = 0
    epoch: int = 0
    tracking: bool = False  # next pulse is a tracking pulse
    in_init: bool = False  # an init ping's open window is pending
    init_open: int = 0
    quiet: int = 0  # an init ping may not go before this tick (last t0 + max_tof - blank)
    rx: dict[int, _RxState] = field(default_factory=dict)
    track_pulses: int = 0  # tracking pulses since the last init ping (reinit_every option)
    wins_close: int = 0  # close tick of the last tracking pulse's windows (miss hold)


class _Line:
    """Merged comparator level of one receiver and the glitch filter's state."""

    __slots__ = ("starts", "ends", "last", "high")

    def __init__(self) -> None:
        self.starts: list[int] = []
        self.ends: list[int] = []
        self.last = -(1 << 62)  # start of the last run the filter processed
        self.high = False  # filtered level after that run

    def insert(self, s: int, e: int) -> None:
        i = bisect_left(self.ends, s)  # first run with end >= s (touching or overlapping)
        j = bisect_right(self.starts, e)  # runs with start <= e touch or overlap
        if i < j:
            s, e = min(s, self.starts[i]), max(e, self.ends[j - 1])
        self.starts[i:j] = [s]
        self.ends[i:j] = [e]

    def prune(self) -> None:
        i = bisect_left(self.starts, self.last) - 2
        if i > 32:
            del self.starts[:i], self.ends[:i]

    def rises(self, n: int, g: int) -> bool:
        """The run starting at ``n`` is processed (at tick n + latency): whether the filtered
        level rises there (runs are processed in order; glitch_min ``g``)."""
        if n <= self.last:
            return False
        i = bisect_right(self.starts, n) - 1
        if i < 0 or self.starts[i] != n:
            return False  # merged into an earlier run
        e = self.ends[i]
        prev_end = self.ends[i - 1] if i > 0 else None
        self.last = n
        if self.high and prev_end is not None and n - prev_end < g:
            return False  # gap shorter than glitch_min: the filtered level never fell
        self.high = e - n >= g
        self.prune()
        return self.high


def share_matrix(cfg: Sequence[ResolvedSensor]) -> list[list[bool]]:
    """[a][b]: sensors a and b touch a common element (tx, crosstalk neighbour or rx), so the
    earliest-due-first rule orders them."""
    touch = [set(map(int, r.tx)) | set(map(int, r.xtalk_elements)) | set(map(int, r.rx)) for r in cfg]
    return [[bool(a & b) for b in touch] for a in touch]


class FastFiringModel:
    """Cycle-level model of scheduler + receive gating. ``run`` may be called repeatedly."""

    def __init__(self, schedule: Schedule, echo_source: EchoSource, *, glitch_min: int = DEFAULT_GLITCH_MIN,
                 max_echoes_per_window: int = 1, win_slots: int = WIN_SLOTS, start_tick: int = 0,
                 decision_lead: int = 0, miss_gate: int | None = DEFAULT_MISS_GATE,
                 reinit_every: int | None = None, miss_hold: bool = DEFAULT_MISS_HOLD) -> None:
        self.schedule = schedule
        self.cfg = schedule.validate()
        self.source = echo_source
        self.g = max(int(glitch_min), 1)
        self.latency = 1 + self.g  # edge timestamp n is detected (rise_o) at tick n + latency
        self.max_echoes = int(max_echoes_per_window)
        self.slots = int(win_slots)
        #: decision lead P (docs/fast_firing.md section 3.1): the SCHED decision taken at tick T is
        #: for a pulse with t0 = T + P, on the state as of tick T (the RTL computes it serially)
        self.lead = int(decision_lead)
        if self.lead < 0:
            raise ValueError(f"decision_lead {self.lead} must be >= 0 ticks")
        #: Gated miss rule (RTL: RX_FILTER.miss_gate, taken when the firmware loads the table;
        #: docs/fast_firing.md section 4.4): a tracking window's first echo farther than
        #: ``miss_gate`` ticks from the prediction is reported but neither updates the track nor
        #: resets the miss count (the window counts as empty), so another pulse's echo cannot
        #: keep a lost track alive. It applies once the track's velocity is measured
        #: (``_RxState.vel``: the last sample followed one of the previous pulse; before that the
        #: prediction assumes v = 0 and a moving reflector would fail the gate); the sample that
        #: would measure the velocity is gated at v_max per pulse instead (an echo implying a
        #: faster change is no sample of this track: it would set a clamped, wrong velocity).
        #: 0 or None = off (the rule before the register existed). Default: the register's reset
        #: value. Forced re-initialisation: each sensor's ``reinit_every`` M (VirtualSensor field,
        #: RTL MODE.reinit_every, 0 = off): a tracking sensor that has sent M tracking pulses since
        #: its last init ping cancels its windows and sends an init ping next, bounding the time an
        #: obstacle can hide behind an alias that passes the gate. The ``reinit_every`` argument,
        #: when given, overrides it for every sensor (experiments: multisonar.safety).
        #: Miss hold (RTL: RX_FILTER.miss_hold, taken when the firmware loads the table; section
        #: 4.4): while a tracked receiver of a sensor has a miss, the sensor does not interlace:
        #: it decides its next tracking pulse only once its last tracking pulse's windows have
        #: closed, and if a miss is still pending then, at order 0; so no pulse fired after the
        #: miss can put an alias into a window in flight. False: the rule before the register.
        if miss_gate is not None and not 0 <= miss_gate < (1 << 16):
            raise ValueError(f"miss_gate {miss_gate} must be 0..65535 ticks (RX_FILTER.miss_gate, 0 = off) or None")
        if reinit_every is not None and not 1 <= reinit_every <= 255:
            raise ValueError(f"reinit_every {reinit_every} must be 1..255 pulses (MODE.reinit_every) or None")
        self.miss_gate = int(miss_gate) if miss_gate else None
        self.reinit_every = reinit_every
        self.miss_hold = bool(miss_hold)
        self.now = int(start_tick)
        n_el = schedule.layout.n
        self.windows: list[list[_Window]] = [[] for _ in range(n_el)]
        self.blank_until = [self.now] * n_el
        #: end of the dead zone of each element's latest trigger: a tx element is not triggered
        #: again before it (docs/fast_firing.md section 5, rule 5; T_dead >= burst by validation,
        #: so two bursts never overlap on one element)
        self.tx_until = [self.now] * n_el
        self.lines = [_Line() for _ in range(n_el)]
        self.sensors = [_SensorState(cfg=r, due=self.now + r.phase) for r in self.cfg]
        self._shares = share_matrix(self.cfg)
        self._heap: list[tuple[int, int, int, int, Any]] = []
        self._ctr = itertools.count()
        self.triggers: list[TriggerEvent] = []
        self.events: list[ToFEvent] = []
        self.pulses: list[PulseRecord] = []
        self.cancelled: list[tuple[int, int, int, int]] = []
        self.words: list[int] = []
        self.records: list[Any] = []
        for s in self.sensors:
            self._push(max(s.due - self.lead, self.now), _SCHED, s.cfg.id, None)

    # -- public ---------------------------------------------------------------------
    def run(self, duration_ticks: int) -> RunResult:
        """Advance ``duration_ticks`` ticks; return what happened in that span."""
        end = self.now + int(duration_ticks)
        nt, ne, npu, nc = len(self.triggers), len(self.events), len(self.pulses), len(self.cancelled)
        nw, nr = len(self.words), len(self.records)
        noise = getattr(self.source, "noise", None)
        if callable(noise):
            for rx, st, w in _rows(noise(self.now, end)):
                self._add_pulse(int(rx), max(int(st), self.now), int(w))
        heap = self._heap
        while heap and heap[0][0] < end:
            tick, phase, key, _, payload = heapq.heappop(heap)
            self.now = tick
            if phase == _EDGE:
                self._on_edge(key, payload)
            elif phase == _CLOSE:
                self._on_close(payload)
            else:
                self._try_issue(self.sensors[key])
        self.now = end
        trig = sorted(self.triggers[nt:])
        return RunResult(triggers=trig, events=self.events[ne:], pulses=self.pulses[npu:],
                         cancelled=self.cancelled[nc:], words=self.words[nw:], records=self.records[nr:])

    def predicted_tof(self, sensor: int, rx: int, seq: int | None = None) -> int | None:
        """T_E the sensor would use for receiver rx in pulse seq (default: the next pulse)."""
        s = self.sensors[sensor]
        st = s.rx.get(rx)
        if st is None or not st.tracked:
            return None
        return self._predict(s, st, s.seq if seq is None else seq)

    # -- internals ------------------------------------------------------------------
    def _push(self, tick: int, phase: int, key: int, payload: Any) -> None:
        heapq.heappush(self._heap, (tick, phase, key, next(self._ctr), payload))

    def _emit(self, ev: ToFEvent) -> None:
        self.events.append(ev)
        self.words.append(ev.pack())

    def _record(self, rec: PulseStart | SensorCancel) -> None:
        self.records.append(rec)
        self.words.append(rec.pack())

    def _add_pulse(self, rx: int, start: int, width: int) -> None:
        if width <= 0 or not 0 <= rx < len(self.lines):
            return
        self.lines[rx].insert(start, start + width)
        self._push(start + self.latency, _EDGE, rx, start)

    def _on_edge(self, rx: int, n: int) -> None:
        if self.lines[rx].rises(n, self.g):
            self._rise(rx, n)

    def _rise(self, rx: int, n: int) -> None:
        for w in self.windows[rx]:
            if w.start <= n < w.end:
                break
        else:
            return  # outside every window: dropped (blanking, dead zone, unexpected echo)
        w.n_edges += 1
        if w.n_edges > self.max_echoes:
            return
        first = w.n_edges == 1
        s = self.sensors[w.sensor]
        st = s.rx.get(rx)
        if (first and w.epoch == s.epoch and self.miss_gate is not None and not w.init and st is not None
                and st.tracked and (st.vel or not st.init)):
            # with a measured velocity: G around the prediction; without (the sample that would
            # measure it): v_max per pulse of the gap (k - j mod 2^8), the clamp v would hit
            bound = self.miss_gate if st.vel else s.cfg.vmax * ((w.seq - st.seq) & SEQ_MASK)
            if abs(n - w.t0 - self._predict(s, st, w.seq)) > bound:
                w.rejected = True  # reported flagged 'gated'; counts as a miss at close
        self._emit(ToFEvent(self.now, w.sensor, w.seq & SEQ_MASK, rx, n - w.t0, True, first, False, w.init,
                            first and w.rejected))
        if first and w.epoch == s.epoch:
            if w.rejected:  # re-evaluated like a sample
                if s.due - self.lead <= self.now:
                    self._push(self.now, _SCHED, s.cfg.id, None)
                return
            self._sample(s, st, w, n - w.t0)

    def _sample(self, s: _SensorState, st: _RxState, w: _Window, tof: int) -> None:
        if w.init:
            st.tracked, st.tof, st.seq, st.v, st.miss, st.init, st.vel = True, tof, w.seq, 0, 0, True, False
        else:
            if not st.tracked:
                return
            gap = w.seq - st.seq  # RTL: (seq - last_seq) mod 2**SEQ_W, accepted if 1..127
            if gap <= 0:
                return
            if st.vel and gap > 1:
                # after a skipped pulse the sample moves the track but keeps its velocity, the
                # gate and the miss count: only a gated sample of the next pulse resets the count
                # (docs/fast_firing.md section 4.4)
                st.tof, st.seq = tof, w.seq
            elif st.vel and self.miss_gate is not None:
                # a sample the gate passed, with a measured velocity: the velocity takes half
                # the residual from the prediction (rounded down), so that one echo off the
                # track (an alias within the gate) bends the prediction only half as much
                vmax = s.cfg.vmax
                st.v = max(-vmax, min(vmax, st.v + ((tof - self._predict(s, st, w.seq)) >> 1)))
                st.tof, st.seq, st.miss = tof, w.seq, 0
            else:
                vmax = s.cfg.vmax
                st.vel = gap == 1 and not st.init
                st.v = max(-vmax, min(vmax, tof - st.tof)) if st.vel else 0
                st.tof, st.seq, st.miss, st.init = tof, w.seq, 0, False
        if s.due - self.lead <= self.now:
            self._push(self.now, _SCHED, s.cfg.id, None)

    def _on_close(self, w: _Window) -> None:
        if w.cancelled:
            return
        self.windows[w.rx].remove(w)
        s = self.sensors[w.sensor]
        if w.n_edges == 0 or w.rejected:
            if w.n_edges == 0:
                self._emit(ToFEvent(self.now, w.sensor, w.seq & SEQ_MASK, w.rx, w.end - w.t0,
                                    False, False, True, w.init))
            if not w.init and w.epoch == s.epoch:
                st = s.rx[w.rx]
                st.miss = min(st.miss + 1, MISS_MAX)
                if st.miss >= s.cfg.miss_limit and s.tracking:
                    s.tracking = False  # safety: next pulse is an init ping, due now,
                    s.due = min(s.due, self.now)  # and the sensor's pending windows are cancelled
                    self._cancel(s.cfg.id)
                    self._wake(after=-1)  # its eligibility changed (quiet rule)
        if w.init and w.epoch == s.epoch:
            s.init_open -= 1
            if s.init_open == 0:
                s.in_init = False
                s.tracking = s.cfg.mode is Mode.TRACK and any(st.tracked for st in s.rx.values())
        if s.due - self.lead <= self.now:
            self._push(self.now, _SCHED, s.cfg.id, None)

    def _cancel(self, sensor: int) -> None:
        """Free every window slot of ``sensor`` (pending or open): no event is written for them;
        the cancel record says so."""
        self._record(SensorCancel(self.now, sensor))
        for ws in self.windows:
            for w in ws:
                if w.sensor == sensor:
                    w.cancelled = True
                    self.cancelled.append((w.sensor, w.seq, w.rx, self.now))
            ws[:] = [w for w in ws if not w.cancelled]

    def _predict(self, s: _SensorState, st: _RxState, seq: int) -> int:
        lo, hi = s.cfg.te_limits()
        return max(lo, min(hi, st.tof + (seq - st.seq) * st.v))

    def _try_issue(self, s: _SensorState) -> None:
        t = self.now + self.lead  # t0 of the pulse decided now (decision lead P)
        if s.in_init or t < s.due:
            return
        c = s.cfg
        k = s.seq
        m = self.reinit_every if self.reinit_every is not None else c.reinit_every
        if m and s.tracking and s.track_pulses >= m:
            s.tracking = False  # forced re-initialisation (MODE.reinit_every)
            self._cancel(c.id)
        init = not s.tracking
        if init and t < s.quiet:
            # echoes of this sensor's earlier pulses (within max range) must not reach the
            # open window: it opens at t + blank, the last echo arrives before t_last + max_tof
            self._push(s.quiet - self.lead, _SCHED, c.id, None)
            return
        for o in self.sensors:  # earliest-due-first on shared elements (no starvation)
            if o is not s and self._shares[c.id][o.cfg.id] and self._eligible(o) and (o.due, o.cfg.id) < (s.due, c.id):
                retry = self._hold_retry(t)  # a t0, like _conflict's answer
                if retry is not None:
                    self._push(retry - self.lead, _SCHED, c.id, None)
                return  # re-evaluated when o issues or stops being eligible
        if init:
            wins = [(int(e), c.blank, c.max_tof) for e in c.rx]
            n_eff, period = -1, c.max_tof
        else:
            te = {e: self._predict(s, st, k) for e, st in s.rx.items() if st.tracked}
            lo, hi = min(te.values()), max(te.values())
            if self.miss_hold and any(st.miss for st in s.rx.values()):
                if self.now < s.wins_close:  # decide again once the windows in flight closed
                    s.due = s.wins_close + self.lead
                    self._push(s.wins_close, _SCHED, c.id, None)
                    self._wake(after=c.id)  # sensors it held by its earlier due
                    return
                n_eff = 0
            else:
                n_eff = effective_order(c.order, lo, hi, c.t_v, c.t_n, c.blank)
            period = pulse_period(n_eff, lo, hi, c.t_v, c.t_n, c.blank)
            wins = [(e, v - c.t_v, v + c.t_n) for e, v in sorted(te.items())]
        blanks = c.blank_intervals()
        retry = self._conflict(t, blanks, wins, n_tx=len(c.tx))
        if retry is not None:
            self._push(retry - self.lead, _SCHED, c.id, None)
            return
        # issue at t
        s.seq += 1
        if init:
            s.epoch ^= 1
            s.rx = {int(e): _RxState() for e in c.rx}
            s.in_init, s.init_open = True, len(wins)
            s.track_pulses = 0
        else:
            s.track_pulses += 1
            s.wins_close = t + hi + c.t_n - 1 + self.latency
        for e, a, b in blanks:
            self.blank_until[e] = max(self.blank_until[e], t + b)
        for e, a, b in blanks[:len(c.tx)]:
            self.tx_until[e] = max(self.tx_until[e], t + b)
        for e, a, b in wins:
            w = _Window(t + a, t + b, t + b - 1 + self.latency, c.id, k, e, t, init, s.epoch)
            self.windows[e].append(w)
            self._push(w.close, _CLOSE, e, w)
        for e, d in zip(c.tx, c.delays):
            self.triggers.append(TriggerEvent(t + int(d), int(e), c.id, k & SEQ_MASK))
        self._record(PulseStart(self.now, c.id, k & ((1 << PULSE_ID_W) - 1), t & 0xFFFFFFFF, init, len(wins)))
        self.pulses.append(PulseRecord(c.id, k, s.due, t, init, n_eff, period,
                                       tuple((e, t + a, t + b) for e, a, b in wins),
                                       tuple((e, t + a, t + b) for e, a, b in blanks)))
        s.due = t + period
        s.quiet = t + c.max_tof - c.blank
        self._push(s.due - self.lead, _SCHED, c.id, None)
        for rx, st, w in _rows(self.source.fire(t, c.tx.copy(), c.delays.copy())):
            self._add_pulse(int(rx), max(int(st), t), int(w))
        self._wake(after=c.id)

    def _eligible(self, s: _SensorState) -> bool:
        """Pending in the RTL sense: due, not waiting for an init result, quiet time over."""
        return s.due - self.lead <= self.now and not s.in_init and (s.tracking or self.now + self.lead >= s.quiet)

    def _hold_retry(self, t: int) -> int | None:
        return None  # event driven: a held sensor waits for _wake

    def _wake(self, after: int) -> None:
        """Re-evaluate pending sensors: later in this tick if their id is higher than ``after``
        (SCHED runs in id order), else next tick."""
        for o in self.sensors:
            if o.due - self.lead <= self.now:
                self._push(self.now if o.cfg.id > after else self.now + 1, _SCHED, o.cfg.id, None)

    def _conflict(self, t: int, blanks: list[tuple[int, int, int]], wins: list[tuple[int, int, int]],
                  n_tx: int = 0) -> int | None:
        """None if the pulse may go at t, else the first tick at which the conflicts seen now
        are resolved (the RTL simply retries every tick; both give the same issue tick).
        ``blanks[:n_tx]`` are the dead zones of the tx elements: their triggers ``t + a`` must
        not come before the element's ``tx_until``."""
        retry = -1
        for e, a, b in blanks[:n_tx]:
            if t + a < self.tx_until[e]:
                retry = max(retry, self.tx_until[e] - a)
        for e, a, b in blanks:
            for w in self.windows[e]:
                if t + a < w.end and w.start < t + b:
                    retry = max(retry, w.end - a)
        for e, a, b in wins:
            if t + a < self.blank_until[e]:
                retry = max(retry, self.blank_until[e] - a)
            ws = self.windows[e]
            for w in ws:
                if t + a < w.end and w.start < t + b:
                    retry = max(retry, w.end - a)
            if len(ws) >= self.slots:
                retry = max(retry, min(w.close for w in ws))
        return None if retry < 0 else retry
