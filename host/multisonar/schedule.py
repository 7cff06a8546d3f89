"""Virtual sensors and the fast-firing schedule: the configuration the RTL scheduler holds.

A :class:`VirtualSensor` is one transmit group (1..k adjacent elements phased as one virtual
point source), a receive group (any elements) and its fast-firing parameters. A
:class:`Schedule` binds sensors to a layout and an air temperature, resolves every time to
48 MHz ticks, checks feasibility (:meth:`Schedule.validate`, raising :class:`ScheduleError`
that names the sensor and the violated constraint) and produces the integer CSR fields the RTL
virtual-sensor table holds (:meth:`Schedule.to_registers`).

The cycle-level behaviour (windows, interlacing, prediction, deferral) is in
:mod:`multisonar.fastfiring`; the contract is written out in ``docs/fast_firing.md``.

Time arguments: an ``int`` is ticks, a ``float`` is seconds (converted with
:func:`multisonar.constants.seconds_to_ticks`). Resolved values are always integer ticks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Sequence

import numpy as np

from .constants import DEVICE_DECISION_LEAD, TICK_HZ, seconds_to_ticks, speed_of_sound
from .layout import Layout

# --------------------------------------------------------------------------------------
# RTL widths (the contract; docs/fast_firing.md section 7). Aligned with rtl/regs/sonar_regs.rdl
# where that map already has the field.
# --------------------------------------------------------------------------------------
NUM_VS: int = 8  #: virtual-sensor table entries (CAPS.num_vs)
VS_ID_W: int = 3  #: sensor id in events
ELEM_W: int = 5  #: element / receiver index
ORDER_W: int = 4  #: MODE.order field
MAX_ORDER: int = 8  #: highest order this build supports (CAPS.max_order)
MISS_W: int = 4  #: MODE.miss_limit and the per-receiver miss counter (saturating)
REINIT_W: int = 8  #: MODE.reinit_every (tracking-pulse counter saturates at 2**REINIT_W - 1)
TV_W: int = 16  #: WINDOW.t_v, WINDOW.t_n
DEAD_W: int = 19  #: T_DEAD, T_XTALK (10.9 ms; 19 bits keep the scheduler's BLK words at 36 bits)
TOF_W: int = 24  #: MAX_TOF, T_E, time of flight in events, pulse period, phase
#: phasing delay per (sensor, element): the RTL keeps the low DELAY_W bits of each 32-bit word of
#: the DELAY memory (rtl/ms_sonar_core.sv DELAY_W; the register map's memwidth is the bus word);
#: larger delays are refused here (ScheduleError) and by SimDevice at START (CfgError.DELAY).
#: tests/test_device.py checks this value against the RTL parameter.
DELAY_W: int = 16
VMAX_W: int = 16  #: velocity clamp, ticks per pulse
XT_NB_W: int = 2  #: crosstalk neighbours each side (0..3)
SEQ_W: int = 8  #: pulse sequence number (wraps)
TIMESTAMP_W: int = 32  #: free-running tick counter (wraps; all compared spans < 2**31)
WIN_SLOTS: int = 16  #: window-reservation slots per element
GLITCH_W: int = 8  #: RX_FILTER.glitch_min
DEFAULT_GLITCH_MIN: int = 24  #: RX_FILTER.glitch_min reset value, ticks

DEFAULT_T_V_S = 0.5e-3
DEFAULT_T_N_S = 0.5e-3
DEFAULT_MAX_RANGE_M = 4.3
DEFAULT_BURST_CYCLES = 8


class ScheduleError(ValueError):
    """A schedule that the RTL cannot run; the message names the sensor and the constraint."""


class Mode(str, Enum):
    TRACK = "track"  #: fast firing: windowing + interlacing after an initialisation ping
    INIT_ONLY = "init"  #: initialisation pings only (standard firing with an open window)


#: MODE.mode encoding (0 is "off")
MODE_CODE = {Mode.TRACK: 1, Mode.INIT_ONLY: 2}

TimeArg = int | float


def _ticks(v: TimeArg) -> int:
    if isinstance(v, (bool, np.bool_)):
        raise TypeError("a time must be int ticks or float seconds, not bool")
    if isinstance(v, (int, np.integer)):
        return int(v)
    return seconds_to_ticks(float(v))


@dataclass(frozen=True)
class VirtualSensor:
    """One virtual sensor (user-facing; times as int ticks or float seconds)."""

    name: str
    tx: Sequence[int]
    rx: Sequence[int]
    order: int = 1
    t_v: TimeArg = DEFAULT_T_V_S
    t_n: TimeArg = DEFAULT_T_N_S
    t_dead: TimeArg | None = None  #: default: layout.transducer.ring_down_s
    t_xtalk: TimeArg | None = None  #: crosstalk blanking of tx neighbours; default = t_dead
    xtalk_neighbours: int = 1
    miss_limit: int = 3
    max_range_m: float = DEFAULT_MAX_RANGE_M
    mode: Mode | str = Mode.TRACK
    burst_cycles: int = DEFAULT_BURST_CYCLES
    source: tuple[float, float] = (0.0, 0.0)
    vmax: TimeArg | None = None  #: |T_E change| clamp per pulse; default min(T_V, T_N)
    phase: TimeArg = 0  #: first pulse due this long after the model starts
    nominal_range_m: float | None = None  #: for the static plan check in validate()
    #: forced re-initialisation M (MODE.reinit_every, 0 = off): after M tracking pulses since its
    #: last init ping the sensor cancels its windows and sends an init ping, which bounds how long
    #: an obstacle can hide behind another pulse's echo; M <= order + miss_limit + 1 guarantees
    #: the safety bound (docs/fast_firing.md section 4.4) at the cost of tracking samples
    reinit_every: int = 0


@dataclass(frozen=True)
class ResolvedSensor:
    """A sensor with every quantity in integer ticks (what the RTL table holds)."""

    id: int
    name: str
    tx: np.ndarray  # int, sorted along the ring (first = lowest position in the run)
    rx: np.ndarray  # int, ascending
    delays: np.ndarray  # int ticks, one per tx element
    order: int
    t_v: int
    t_n: int
    t_dead: int
    t_xtalk: int
    xtalk_neighbours: int
    xtalk_elements: np.ndarray  # neighbours blanked by crosstalk (not in tx), ascending
    xtalk_delays: np.ndarray  # (m, 2): first and last trigger offset of the tx neighbours of each
    blank: int  # D = max(t_dead, t_xtalk) + max(delays): earliest window start
    max_tof: int  # R: end of the open window
    miss_limit: int
    mode: Mode
    burst_cycles: int
    burst_ticks: int
    vmax: int
    phase: int
    nominal_tof: int | None
    source: tuple[float, float]
    reinit_every: int = 0  #: MODE.reinit_every (0 off)

    def blank_intervals(self) -> list[tuple[int, int, int]]:
        """(element, start, end) offsets from t0: dead zones of the tx elements (in tx order),
        then crosstalk blanking of their neighbours."""
        out = [(int(e), int(d), int(d) + self.t_dead) for e, d in zip(self.tx, self.delays)]
        out += [(int(e), int(a), int(b) + self.t_xtalk) for e, (a, b) in zip(self.xtalk_elements, self.xtalk_delays)]
        return out

    def te_limits(self) -> tuple[int, int]:
        """Clamp range of a predicted T_E: windows stay inside [blank, max_tof)."""
        return self.blank + self.t_v, self.max_tof - self.t_n


# --------------------------------------------------------------------------------------
# Integer formulas shared by the validator, the model and the benchmark
# --------------------------------------------------------------------------------------

def phasing_delays(layout: Layout, tx: Sequence[int], source: Sequence[float], c: float) -> np.ndarray:
    """delay_i = round((|c_i - s| - min_j |c_j - s|) / c * TICK_HZ) ticks (one clock)."""
    p = layout.positions[np.asarray(tx, dtype=int)]
    d = np.linalg.norm(p - np.asarray(source, dtype=float)[None, :], axis=1)
    return np.rint((d - d.min()) / c * TICK_HZ).astype(np.int64)


def order_feasible(n: int, te_min: int, te_max: int, t_v: int, t_n: int, blank: int) -> bool:
    """Integer test of order n: pulse k+n's blanking ends before window k opens, and window k
    closes before pulse k+n+1 (with T_s = floor((te_min - T_V - D) / n))."""
    if n == 0:
        return True
    ts = (te_min - t_v - blank) // n
    return ts > 0 and (n + 1) * ts >= te_max + t_n


def effective_order(order: int, te_min: int, te_max: int, t_v: int, t_n: int, blank: int) -> int:
    """Largest n <= order that is feasible (RTL: try n = order, order-1, ..., 0)."""
    for n in range(order, 0, -1):
        if order_feasible(n, te_min, te_max, t_v, t_n, blank):
            return n
    return 0


def pulse_period(n: int, te_min: int, te_max: int, t_v: int, t_n: int, blank: int) -> int:
    """T_s in ticks for effective order n: Eq. (2) generalised, T_s = floor((T_E - T_V - D)/n);
    order 0 (no interlacing): the next pulse goes when the window closes, T_E + T_N."""
    if n == 0:
        return te_max + t_n
    return (te_min - t_v - blank) // n


def pause_ticks(n: int, te: int, t_v: int, t_n: int, blank: int) -> int:
    """Eq. (1) generalised (times n): n*T_pause = T_E - (n+1)(D + T_V) - n*T_N (>= 0 iff feasible
    up to the floor of the division)."""
    return te - (n + 1) * (blank + t_v) - n * t_n


def min_tof_for_order(n: int, t_v: int, t_n: int, blank: int) -> int:
    """Shortest T_E at which order n is feasible (exact integer search on top of the bound)."""
    te = (n + 1) * (blank + t_v) + n * t_n
    while not order_feasible(n, te, te, t_v, t_n, blank):
        te += 1
    return te


def analytic_period_s(distance_m: float, order: int, *, t_dead_s: float = 1.5e-3, t_v_s: float = 0.5e-3,
                      t_n_s: float = 0.5e-3, c: float | None = None) -> float:
    """Continuous form for plots: T_E = 2d/c; T_s = (T_E - T_dead - T_V)/n at the highest
    feasible n <= order (Eq. (2) for n = 1), T_E + T_N if none is."""
    c = speed_of_sound() if c is None else c
    te = 2.0 * distance_m / c
    for n in range(order, 0, -1):
        if te >= (n + 1) * (t_dead_s + t_v_s) + n * t_n_s:
            return (te - t_dead_s - t_v_s) / n
    return te + t_n_s


def interlace_limit_s(*, t_dead_s: float = 1.5e-3, t_v_s: float = 0.5e-3, t_n_s: float = 0.5e-3) -> float:
    """Shortest possible period at any order: one element can hold per period only one dead
    zone and one window, so T_s >= T_dead + T_V + T_N (the order -> infinity limit)."""
    return t_dead_s + t_v_s + t_n_s


# --------------------------------------------------------------------------------------
# Schedule
# --------------------------------------------------------------------------------------

@dataclass
class Schedule:
    """Sensors bound to a layout and an air temperature."""

    layout: Layout
    sensors: Sequence[VirtualSensor]
    temperature_c: float = 20.0
    plan_horizon: TimeArg = 0.2  #: span of the static steady-state plan check
    check_plan: bool = True  #: run the static plan check (the online scheduler never needs it)
    _resolved: list[ResolvedSensor] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self.sensors = list(self.sensors)
        self.c = speed_of_sound(self.temperature_c)

    # -- validation -----------------------------------------------------------------
    @property
    def resolved(self) -> list[ResolvedSensor]:
        if self._resolved is None:
            self.validate()
        assert self._resolved is not None
        return self._resolved

    def validate(self) -> list[ResolvedSensor]:
        """Check every constraint; raise ScheduleError naming the sensor and the constraint."""
        if not self.sensors:
            raise ScheduleError("schedule has no virtual sensors")
        if len(self.sensors) > NUM_VS:
            raise ScheduleError(f"{len(self.sensors)} virtual sensors: the RTL table holds {NUM_VS}")
        names = [s.name for s in self.sensors]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ScheduleError(f"duplicate virtual sensor name(s) {dup}")
        res = [self._resolve(i, s) for i, s in enumerate(self.sensors)]
        if self.check_plan:
            self._check_plan(res)
        self._resolved = res
        return res

    def _resolve(self, idx: int, s: VirtualSensor) -> ResolvedSensor:
        n_el = self.layout.n

        def err(msg: str) -> ScheduleError:
            return ScheduleError(f"virtual sensor {s.name!r}: {msg}")

        try:
            mode = Mode(s.mode)
        except ValueError:
            raise err(f"unknown mode {s.mode!r}; use 'track' or 'init'") from None
        for what, group in (("tx", s.tx), ("rx", s.rx)):
            g = list(group)
            if not g:
                raise err(f"empty {what} group")
            bad = [e for e in g if not isinstance(e, (int, np.integer)) or not 0 <= int(e) < n_el]
            if bad:
                raise err(f"unknown element(s) {bad} in {what} group: layout {self.layout.name!r} "
                          f"has elements 0..{n_el - 1}")
            if len(set(int(e) for e in g)) != len(g):
                raise err(f"{what} group {g} lists an element twice")
        tx = _adjacent_run(sorted(int(e) for e in s.tx), n_el)
        if tx is None:
            raise err(f"tx group {sorted(int(e) for e in s.tx)} is not a run of adjacent elements around the ring")
        rx = np.array(sorted(int(e) for e in s.rx), dtype=np.int64)
        if not 0 <= s.order <= MAX_ORDER:
            raise err(f"order {s.order} outside 0..{MAX_ORDER} (CAPS.max_order; field width {ORDER_W} bits)")
        if not 1 <= s.miss_limit < 2**MISS_W:
            raise err(f"miss limit K={s.miss_limit} outside 1..{2**MISS_W - 1} ({MISS_W}-bit counter)")
        if not 0 <= s.reinit_every < 2**REINIT_W:
            raise err(f"reinit_every M={s.reinit_every} outside 0..{2**REINIT_W - 1} pulses ({REINIT_W}-bit MODE field, 0 = off)")
        if not 0 <= s.xtalk_neighbours < 2**XT_NB_W:
            raise err(f"xtalk_neighbours {s.xtalk_neighbours} outside 0..{2**XT_NB_W - 1}")
        if not 1 <= s.burst_cycles < 256:
            raise err(f"burst_cycles {s.burst_cycles} outside 1..255")
        if not (math.isfinite(s.max_range_m) and s.max_range_m > 0):
            raise err(f"max range {s.max_range_m!r} m is not positive")
        t_v, t_n = _ticks(s.t_v), _ticks(s.t_n)
        t_dead = _ticks(self.layout.transducer.ring_down_s if s.t_dead is None else s.t_dead)
        t_xt = t_dead if s.t_xtalk is None else _ticks(s.t_xtalk)
        for nm, v, w in (("T_V", t_v, TV_W), ("T_N", t_n, TV_W), ("T_dead", t_dead, DEAD_W), ("T_xtalk", t_xt, DEAD_W)):
            if not 0 < v < 2**w:
                raise err(f"{nm} = {v} ticks outside 1..{2**w - 1} ({w}-bit field)")
        burst_ticks = int(round(s.burst_cycles * TICK_HZ / self.layout.transducer.frequency_hz))
        if t_dead < burst_ticks:
            raise err(f"dead zone T_dead = {t_dead} ticks is shorter than the burst ({burst_ticks} ticks): "
                      "the element would listen while it drives")
        delays = phasing_delays(self.layout, tx, s.source, self.c)
        if delays.max() >= 2**DELAY_W:
            i = int(np.argmax(delays))
            raise err(f"phasing delay {int(delays[i])} ticks of tx element {int(tx[i])} out of range "
                      f"(delay field is {DELAY_W} bits, max {2**DELAY_W - 1}): virtual source {s.source} too far off")
        xt_el, xt_d = _xtalk(tx, delays, s.xtalk_neighbours, n_el)
        blank = max(t_dead, t_xt) + int(delays.max())
        max_tof = seconds_to_ticks(2.0 * s.max_range_m / self.c)
        if max_tof >= 2**TOF_W:
            raise err(f"max range {s.max_range_m} m = {max_tof} ticks exceeds the {TOF_W}-bit MAX_TOF field")
        if max_tof - t_n < blank + t_v:
            raise err(f"window inside dead zone: max range {s.max_range_m} m ({max_tof} ticks) leaves no "
                      f"window [T_E - T_V, T_E + T_N) after the blanking D = {blank} ticks")
        if blank <= DEVICE_DECISION_LEAD:
            raise err(f"blanking D = {blank} ticks is not longer than the device's decision lead "
                      f"({DEVICE_DECISION_LEAD} ticks): lengthen T_dead (device cfg_error LEAD)")
        if t_v + t_n <= DEVICE_DECISION_LEAD // 2:
            raise err(f"window T_V + T_N = {t_v + t_n} ticks is not longer than half the device's decision "
                      f"lead ({DEVICE_DECISION_LEAD // 2} ticks): widen the window (device cfg_error WINDOW_SHORT)")
        vmax = min(t_v, t_n) if s.vmax is None else _ticks(s.vmax)
        if not 0 <= vmax < 2**VMAX_W:
            raise err(f"vmax {vmax} ticks outside 0..{2**VMAX_W - 1}")
        phase = _ticks(s.phase)
        if not 0 <= phase < 2**TOF_W:
            raise err(f"phase {phase} ticks outside 0..{2**TOF_W - 1}")
        nominal = None
        if s.nominal_range_m is not None:
            nominal = seconds_to_ticks(2.0 * s.nominal_range_m / self.c)
            if nominal - t_v < blank:
                raise err(f"window inside dead zone: nominal range {s.nominal_range_m} m gives window start "
                          f"T_E - T_V = {nominal - t_v} ticks < blanking D = {blank} ticks")
            if nominal + t_n > max_tof:
                raise err(f"nominal range {s.nominal_range_m} m is beyond the max range {s.max_range_m} m")
        te_check = nominal if nominal is not None else max_tof - t_n
        where = f"nominal range {s.nominal_range_m} m" if nominal is not None else f"max range {s.max_range_m} m"
        if mode is Mode.TRACK and s.order > 0 and not order_feasible(s.order, te_check, te_check, t_v, t_n, blank):
            p = pause_ticks(s.order, te_check, t_v, t_n, blank)
            raise err(f"order {s.order} too high for the range: at {where} (T_E = {te_check} ticks) the "
                      f"generalised Eq. (1) pause n*T_pause = T_E - (n+1)(D+T_V) - n*T_N = {p} ticks < 0; "
                      f"order {s.order} needs T_E >= {min_tof_for_order(s.order, t_v, t_n, blank)} ticks")
        return ResolvedSensor(
            id=idx, name=s.name, tx=tx, rx=rx, delays=delays, order=int(s.order), t_v=t_v, t_n=t_n,
            t_dead=t_dead, t_xtalk=t_xt, xtalk_neighbours=int(s.xtalk_neighbours), xtalk_elements=xt_el,
            xtalk_delays=xt_d, blank=blank, max_tof=max_tof, miss_limit=int(s.miss_limit), mode=mode,
            burst_cycles=int(s.burst_cycles), burst_ticks=burst_ticks, vmax=vmax, phase=phase,
            nominal_tof=nominal, source=(float(s.source[0]), float(s.source[1])), reinit_every=int(s.reinit_every))

    # -- static steady-state plan ---------------------------------------------------
    def plan(self, resolved: list[ResolvedSensor] | None = None, horizon: int | None = None
             ) -> dict[int, list[tuple[int, int, str, int, int]]]:
        """Nominal steady-state intervals per element: (start, end, kind, sensor id, pulse),
        kind 'window' or 'blank', for sensors whose range is known (nominal_range_m, or
        init-only sensors). Pulses at phase + k*T_s; the online scheduler corrects deviations."""
        res = self.resolved if resolved is None else resolved
        horizon = _ticks(self.plan_horizon) if horizon is None else horizon
        out: dict[int, list[tuple[int, int, str, int, int]]] = {}
        for r in res:
            if r.mode is Mode.INIT_ONLY:
                ts, wins = r.max_tof, [(int(e), r.blank, r.max_tof) for e in r.rx]
            elif r.nominal_tof is not None:
                te = min(max(r.nominal_tof, r.te_limits()[0]), r.te_limits()[1])
                n = effective_order(r.order, te, te, r.t_v, r.t_n, r.blank)
                ts = pulse_period(n, te, te, r.t_v, r.t_n, r.blank)
                wins = [(int(e), te - r.t_v, te + r.t_n) for e in r.rx]
            else:
                continue
            blanks = [(e, a, b) for e, a, b in r.blank_intervals()[:len(r.tx)]]
            blanks += [(e, a, b) for e, a, b in r.blank_intervals()[len(r.tx):]]
            k, t0 = 0, r.phase
            while t0 < horizon:
                for e, a, b in wins:
                    out.setdefault(e, []).append((t0 + a, t0 + b, "window", r.id, k))
                for e, a, b in blanks:
                    out.setdefault(e, []).append((t0 + a, t0 + b, "blank", r.id, k))
                k, t0 = k + 1, t0 + ts
        return out

    def _check_plan(self, res: list[ResolvedSensor]) -> None:
        names = {r.id: r.name for r in res}
        for e, ivs in sorted(self.plan(res).items()):
            ivs.sort()
            active: list[tuple[int, int, str, int, int]] = []
            for iv in ivs:
                active = [a for a in active if a[1] > iv[0]]
                for a in active:
                    if a[3] == iv[3] or (a[2] == "blank" and iv[2] == "blank"):
                        continue
                    first, second = (a, iv)
                    if first[2] == "window" and second[2] == "window":
                        raise ScheduleError(
                            f"virtual sensors {names[first[3]]!r} and {names[second[3]]!r}: windows overlap on "
                            f"element {e} (pulse {first[4]} [{first[0]}, {first[1]}) vs pulse {second[4]} "
                            f"[{second[0]}, {second[1]}) ticks); change phase or range")
                    b, w = (first, second) if first[2] == "blank" else (second, first)
                    kind = "dead zone" if e in set(int(x) for x in res[b[3]].tx) else "crosstalk blanking"
                    raise ScheduleError(
                        f"virtual sensor {names[b[3]]!r}: transmit {kind} on element {e} (pulse {b[4]} "
                        f"[{b[0]}, {b[1]}) ticks) overlaps the window of virtual sensor {names[w[3]]!r} "
                        f"(pulse {w[4]} [{w[0]}, {w[1]}))")
                active.append(iv)

    # -- registers --------------------------------------------------------------------
    def to_registers(self) -> dict[str, Any]:
        """Integer CSR contents: {'globals': {...}, 'sensors': [{field: int}], 'delay_mem': {addr: int}}.
        Field widths: :data:`REGISTER_FIELDS`."""
        res = self.resolved
        sensors = []
        delay_mem: dict[int, int] = {}
        for r in res:
            f = {
                "id": r.id, "tx_mask": _mask(r.tx), "rx_mask": _mask(r.rx), "mode": MODE_CODE[r.mode],
                "order": r.order, "miss_limit": r.miss_limit, "t_v": r.t_v, "t_n": r.t_n, "t_dead": r.t_dead,
                "t_xtalk": r.t_xtalk, "xtalk_nb": r.xtalk_neighbours, "max_tof": r.max_tof, "vmax": r.vmax,
                "phase": r.phase, "burst_cycles": r.burst_cycles, "blank": r.blank, "reinit_every": r.reinit_every,
            }
            for name, v in f.items():
                w = REGISTER_FIELDS[name][0]
                assert 0 <= v < 2**w, (name, v, w)
            sensors.append(f)
            for e, d in zip(r.tx, r.delays):
                assert 0 <= int(d) < 2**DELAY_W, ("delay", int(d), DELAY_W)
                delay_mem[r.id * 32 + int(e)] = int(d)
        return {
            "globals": {"tick_hz": TICK_HZ, "burst_half_period": int(round(TICK_HZ / self.layout.transducer.frequency_hz / 2)),
                        "glitch_min": DEFAULT_GLITCH_MIN, "num_vs": NUM_VS, "max_order": MAX_ORDER},
            "sensors": sensors,
            "delay_mem": delay_mem,
        }


#: Per-sensor CSR fields: name -> (width bits, description). 'blank' is derived (the firmware
#: computes it when it loads the table: max(t_dead, t_xtalk) + max phasing delay) and listed
#: for checking.
REGISTER_FIELDS: dict[str, tuple[int, str]] = {
    "id": (VS_ID_W, "table index = sensor id in events"),
    "tx_mask": (24, "TX_MASK: adjacent transmit elements"),
    "rx_mask": (24, "RX_MASK: receive elements"),
    "mode": (2, "MODE.mode: 0 off, 1 track, 2 init-only"),
    "order": (ORDER_W, "MODE.order: highest fast-firing order n (pulses interlaced)"),
    "miss_limit": (MISS_W, "MODE.miss_limit: K empty windows in a row -> init ping"),
    "reinit_every": (REINIT_W, "MODE.reinit_every: forced init ping after M tracking pulses (0 off)"),
    "t_v": (TV_W, "WINDOW.t_v ticks"),
    "t_n": (TV_W, "WINDOW.t_n ticks"),
    "t_dead": (DEAD_W, "T_DEAD ticks: blanking of a transmitting element from its trigger"),
    "t_xtalk": (DEAD_W, "T_XTALK ticks (new): blanking of the tx group's neighbours from the trigger"),
    "xtalk_nb": (XT_NB_W, "XTALK.nb (new): neighbours blanked on each side of each tx element"),
    "max_tof": (TOF_W, "MAX_TOF ticks: end of the open window, clamp of T_E + T_N"),
    "vmax": (VMAX_W, "VMAX ticks per pulse (new): clamp of the predicted T_E change"),
    "phase": (TOF_W, "PHASE ticks (new): first pulse due after enable"),
    "burst_cycles": (8, "burst cycles (global BURST.cycles in the foundation map)"),
    "blank": (TOF_W, "derived D = max(t_dead, t_xtalk) + max delay: earliest window start"),
}


def _mask(elements: np.ndarray) -> int:
    m = 0
    for e in elements:
        m |= 1 << int(e)
    return m


def _adjacent_run(sorted_el: list[int], n: int) -> np.ndarray | None:
    """The elements as one cyclic run in ring order, or None if they are not adjacent."""
    k = len(sorted_el)
    if k == n:
        return np.arange(n, dtype=np.int64)
    s = set(sorted_el)
    starts = [e for e in sorted_el if (e - 1) % n not in s]
    if len(starts) != 1:
        return None
    return np.array([(starts[0] + i) % n for i in range(k)], dtype=np.int64)


def _xtalk(tx: np.ndarray, delays: np.ndarray, nb: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Neighbour elements blanked by crosstalk, and (first, last) trigger offset of the tx
    elements within ``nb`` of each: the blanking is [first, last + T_xtalk)."""
    txs = set(int(e) for e in tx)
    span: dict[int, tuple[int, int]] = {}
    for e, d in zip(tx, delays):
        for k in range(1, nb + 1):
            for j in ((int(e) + k) % n, (int(e) - k) % n):
                if j not in txs:
                    a, b = span.get(j, (int(d), int(d)))
                    span[j] = (min(a, int(d)), max(b, int(d)))
    el = np.array(sorted(span), dtype=np.int64)
    return el, np.array([span[j] for j in el], dtype=np.int64).reshape(-1, 2)
