"""The world around the engine for a whole-program run: what the sonar core's hardware gives
the scheduler: the receive path (EchoPath) and, for the main loop, the whole scheduler
(EngineSystem: tick counter, work queue, close detector, WIN read port, outputs).

:class:`EchoPath`: the echoes of fired pulses and the acoustic noise on each receiver's
comparator line, filtered as the receive conditioner does (``_Line.rises``, the golden
model's own filter), giving the edges the scheduler sees: receiver r rises at tick n + L
(L = 1 + max(glitch_min, 1)) for a run starting at n.
"""

from __future__ import annotations

import heapq
from collections import deque
from dataclasses import dataclass
from typing import Any

from ...fastfiring import _Line, _rows, share_matrix
from ..sched_ucode import MASK32
from .layout import (BLK, EVT_HI, HD_EL, LAG_CUR, LD_BURST, LD_RXANY, LD_TXM, LD_WLEN, MAIN, M_ACT,
                     M_ARMED, M_GATE, M_L, M_MHOLD, M_P, M_START, M_TD, NUM_RX, NUM_VS, ONEHOT, Q_C,
                     Q_E, Q_POP, Q_STAT, Q_T, SENS, SENS_STRIDE, STOP_AT, STOP_REQ, S_BLK, S_D, S_HI,
                     S_K, S_LO, S_MODE, S_NRX, S_ORDER, S_PHASE, S_QOFF, S_REINIT, S_RMAX, S_RX,
                     S_SHARE, S_TN, S_TV, S_TX, S_VMAX, SU_FLAGS, TICK, TRIG_EL, T_DONE, UCODE_WORDS,
                     WIN_META, WIN_RA, WIN_T0, WIN_WE, W_ADDR)
from .units import EngineWithUnits, Slot


def edge_latency(glitch_min: int) -> int:
    """L = 1 + max(glitch_min, 1): an edge's timestamp is its detection tick - L (RX_FILTER's
    glitch_min, ms_rx_conditioner)."""
    return 1 + max(int(glitch_min), 1)


class EchoPath:
    """Comparator lines of ``n_el`` receivers fed by ``source`` (an EchoSource)."""

    def __init__(self, n_el: int, source: Any, glitch_min: int) -> None:
        self.source = source
        self.g = max(int(glitch_min), 1)
        self.latency = edge_latency(glitch_min)
        self.lines = [_Line() for _ in range(n_el)]
        self._pending: list[tuple[int, int, int]] = []   # (detection tick, receiver, run start)

    def _add(self, rx: int, start: int, width: int) -> None:
        if width <= 0 or not 0 <= rx < len(self.lines):
            return
        self.lines[rx].insert(start, start + width)
        heapq.heappush(self._pending, (start + self.latency, rx, start))

    def noise(self, t_start: int, t_end: int) -> None:
        """The source's noise pulses of [t_start, t_end) on the lines."""
        noise = getattr(self.source, "noise", None)
        if callable(noise):
            for rx, st, w in _rows(noise(t_start, t_end)):
                self._add(int(rx), max(int(st), t_start), int(w))

    def fire(self, t0: int, elements: Any, delays: Any) -> None:
        """A pulse fired at t0 (its tx elements, their phasing delays): its echoes on the lines."""
        for rx, st, w in _rows(self.source.fire(t0, elements, delays)):
            self._add(int(rx), max(int(st), t0), int(w))

    def rises(self, tick: int) -> list[tuple[int, int]]:
        """The (receiver, run start n) that rise at ``tick``, receivers ascending; every earlier
        tick must have been asked for first."""
        out = []
        while self._pending and self._pending[0][0] <= tick:
            t, rx, n = heapq.heappop(self._pending)
            if t < tick:
                raise ValueError(f"EchoPath: tick {t} was skipped (asked for {tick})")
            if self.lines[rx].rises(n, self.g):
                out.append((rx, n))
        return out

    def next_tick(self) -> int | None:
        """The next tick with a pending run, or None."""
        return self._pending[0][0] if self._pending else None


# ------------------------------------------------------------------ the whole scheduler
@dataclass
class EngineRun:
    """What a whole-program run gave for the logical ticks it covered: event words in FIFO
    order, triggers (tick, element) sorted, and the engine's lateness: ``lag_max`` the largest
    (tick counter - logical tick) at the end of a logical tick's work, ``lag_ticks`` the
    logical ticks it measured. ``late`` lists what broke the timing contract (a trigger or a
    head written after its tick, a queue overflow, a dispatch P / 2 late)."""
    words: list[int]
    triggers: list[tuple[int, int]]
    lag_max: int
    lag_ticks: int
    clocks: int
    late: list[str]


def sensor_words(c: Any, shares: int, reinit_every: int | None = None) -> dict[int, int]:
    """The load image's words of resolved sensor ``c`` (its table entry, sched_program's layout)."""
    mask = lambda es: sum(1 << int(e) for e in es)  # noqa: E731
    base = SENS + SENS_STRIDE * c.id
    lo, hi = c.te_limits()
    blanks = c.blank_intervals()
    m = reinit_every if reinit_every is not None else c.reinit_every
    words = {S_TX: mask(c.tx), S_RX: mask(c.rx), S_BLK: mask(e for e, _, _ in blanks),
             S_ORDER: c.order, S_TV: c.t_v, S_TN: c.t_n, S_D: c.blank, S_RMAX: c.max_tof,
             S_LO: lo, S_HI: hi, S_VMAX: c.vmax, S_QOFF: window_length(c, True), S_PHASE: c.phase,
             S_NRX: len(c.rx), S_K: c.miss_limit, S_MODE: 1 if c.mode.value == "track" else 2,
             S_REINIT: int(m or 0), S_SHARE: shares}
    out = {base + k: v & MASK32 for k, v in words.items()}
    for e, a, b in blanks:
        out[BLK + 64 * c.id + e], out[BLK + 64 * c.id + 32 + e] = a, b
    return out


def load_image(cfg: Any, *, lead: int, glitch_min: int, miss_gate: int | None,
               reinit_every: int | None = None, miss_hold: bool = True) -> dict[int, int]:
    """What a configuration load writes on the engine's bus, {address: word}, for the resolved
    table ``cfg``: every enabled sensor's words and blank offsets (sensor_words), its share
    word, and the main loop's constants (decision lead P, edge latency L = 1 + max(glitch_min,
    1) from RX_FILTER.glitch_min, miss gate, miss hold, enabled sensors); not the start tick, which the
    start writes. The firmware's load
    (firmware/app/sonar/sched_table.c) writes the same words. Besides the engine's bus (data
    memory, blank offsets) the load port takes the hardware's own tables at LD_* (window
    lengths, burst cycles, tx and rx masks)."""
    mem = {MAIN + M_P: int(lead), MAIN + M_L: edge_latency(glitch_min),
           MAIN + M_GATE: int(miss_gate or 0), MAIN + M_MHOLD: int(bool(miss_hold)),
           MAIN + M_ACT: sum(1 << c.id for c in cfg)}
    share = share_matrix(cfg)
    for i, c in enumerate(cfg):
        shares = sum(1 << o.id for j, o in enumerate(cfg) if j != i and share[i][j])
        mem.update(sensor_words(c, shares, reinit_every))
        mem[LD_WLEN + 2 * c.id] = window_length(c, False)
        mem[LD_WLEN + 2 * c.id + 1] = window_length(c, True)
        mem[LD_BURST + c.id] = c.burst_cycles
        mem[LD_TXM + c.id] = sum(1 << int(e) for e in c.tx)
    mem[LD_RXANY] = sum(1 << int(e) for e in {int(e) for c in cfg for e in c.rx})
    return mem


def load_sequence(image: dict[int, int]) -> list[tuple[int, int]]:
    """``image``'s words in an order the load port takes: by address, except that each blank
    offset a (BLK + 64 s + e) goes right before its b (+ 32), which commits the pair."""
    order = [a for a in sorted(image) if a < BLK]
    order += [x for a in sorted(image) if a >= BLK and not a & 32 for x in (a, a + 32)]
    if sorted(order) != sorted(image):
        raise ValueError("load image: a blank offset b without its a")
    return [(a, image[a]) for a in order]


def window_length(c: Any, init: bool) -> int:
    """The length of every window of resolved sensor ``c`` (the hardware's table, by sensor and
    init bit; WIN keeps no start): an init ping's [D, R), a tracking window's [te - T_V, te +
    T_N)."""
    return c.max_tof - c.blank if init else c.t_v + c.t_n


class _Bus(EngineWithUnits):
    """The engine's model on the scheduler's bus: data memory, the units, and the hardware
    of :class:`EngineSystem` (tick counter, work queue, WIN read port, heads, outputs)."""

    def __init__(self, words: list[int], mem: dict[int, int], system: "EngineSystem") -> None:
        super().__init__(words, mem)
        self.sys = system

    def read(self, addr: int) -> int:
        at = self.cycle + 1
        if addr == TICK:
            return self.sys.tick_at(at) & MASK32
        if addr in (STOP_REQ, STOP_AT):
            return 0                         # the harness never stops the program
        if addr in (Q_STAT, Q_T, Q_E, Q_C):
            return self.sys.queue_read(addr, self.sys.tick_at(at))
        if addr in (WIN_T0, WIN_WE, WIN_META):
            return self.sys.win_read(addr, at)
        if addr >= BLK:
            # the blank offsets share WIN's block RAM and read port, which the slot unit's
            # scan takes first: read while it is busy, the data is not the offset
            self.sys.blk_at = at
            if self.su.read(at, SU_FLAGS) & 0x80:
                return 0xDEAD_BEEF
            return self.mem.get(addr, 0)
        return super().read(addr)

    def write(self, addr: int, data: int) -> None:
        at = self.cycle + 1
        s = self.sys
        if addr == Q_POP:
            s.queue.popleft()
        elif addr == WIN_RA:
            s.win_ra, s.win_at = data, at
        elif addr >= BLK:
            self.mem[addr] = data
        elif addr == HD_EL:
            s.advance(s.tick_at(at))
            super().write(addr, data)
            e, slot, close = self.out.heads[-1]
            s.heads[e] = close
            if close is not None and close <= s.tick_at(at):
                s.late.append(f"head of element {e} closing at {close} written at {s.tick_at(at)}")
        else:
            if addr == W_ADDR:
                super().write(addr, data)
                t0, we, meta = self.out.slots[data]
                sensor, init = meta >> 16 & 0x7, meta >> 8 & 1
                self.su.slots[data] = Slot(t0 + we - s.win_len[sensor, init], t0 + we,
                                           t0 + we - 1 + s.latency, sensor)
                return
            super().write(addr, data)
            if addr == TRIG_EL:
                s.on_trigger(self.out.triggers[-1], at)
            elif addr == EVT_HI:
                s.on_event(self.out.events[-1])
            elif addr == T_DONE:
                s.on_tick_done(data, at)
            elif addr == LAG_CUR:
                s.cur = data


class EngineSystem:
    """The scheduler as the engine runs it: the main loop (mainloop.main_program) on the
    engine's model, with the sonar core's hardware around it modelled here: the tick counter
    (one tick per clock), the receive path (EchoPath), the work queue (a word {tick, edges,
    closes} per tick with work, visible two clocks after its tick, ``qdepth`` deep), the close
    detector (each element's head close tick against the tick counter), the WIN read port and
    the outputs (window slots, triggers, event words; a pulse record fires its pulse's echoes).
    ``run`` covers the same logical ticks as FastFiringModel.run and gives what they produced
    (EngineRun), so the two compare word for word."""

    def __init__(self, schedule: Any, source: Any, *, decision_lead: int, glitch_min: int,
                 miss_gate: int | None, reinit_every: int | None = None, start_tick: int = 0,
                 qdepth: int = 32, miss_hold: bool = True) -> None:
        from .mainloop import POLL, main_program   # mainloop imports this package's kernels
        self.cfg = schedule.validate()
        n_el = schedule.layout.n
        if n_el != NUM_RX or len(self.cfg) > NUM_VS:
            raise ValueError(f"the engine's program is built for {NUM_RX} elements and up to "
                             f"{NUM_VS} sensors, not {n_el} / {len(self.cfg)}")
        self.image = main_program().assemble(depth=UCODE_WORDS)
        self.poll = self.image.labels[POLL]
        self.echo = EchoPath(n_el, source, glitch_min)
        self.latency = self.echo.latency
        self.lead, self.start, self.qdepth = int(decision_lead), int(start_tick), qdepth
        mem: dict[int, int] = {ONEHOT + k: 1 << k for k in range(32)}
        mem.update({a: w for a, w in load_image(self.cfg, lead=self.lead, glitch_min=glitch_min,
                                                 miss_gate=miss_gate, reinit_every=reinit_every,
                                                 miss_hold=miss_hold).items()
                    if not LD_WLEN <= a <= LD_RXANY})    # the hardware's tables: win_len below
        mem[MAIN + M_START] = self.start
        self.win_len = {(c.id, init): window_length(c, bool(init)) for c in self.cfg for init in (0, 1)}
        self.m = _Bus(self.image.words, mem, self)
        self.heads: dict[int, int | None] = {}
        self.queue: deque[tuple[int, int, int]] = deque()
        self.adv = self.start - 1          # the hardware has handled every tick <= adv
        self.win_ra, self.win_at = 0, -1
        self.blk_at = -2                             # the clock of the last blank-offset read
        self.cur = 0                                 # the logical tick of the dispatch
        self.words: list[tuple[int, int]] = []      # (logical tick, word)
        self.triggers: list[tuple[int, int, int]] = []
        self.lags: list[tuple[int, int]] = []        # (logical tick, lateness at its end)
        self.late: list[str] = []

    # ---- the hardware
    def tick_at(self, cycle: int) -> int:
        return self.start + cycle

    def _next_event(self) -> int | None:
        """The next tick after ``adv`` with a rise or a head closing, or None."""
        ticks = [c for c in self.heads.values() if c is not None and c > self.adv]
        rise = self.echo.next_tick()
        return min(ticks + ([rise] if rise is not None else []), default=None)

    def advance(self, tick: int) -> None:
        """The rises and closes of every tick up to ``tick`` into the work queue."""
        while True:
            t = self._next_event()
            if t is None or t > tick:
                break
            edges = sum(1 << rx for rx, _ in self.echo.rises(t)) if self.echo.next_tick() == t else 0
            closes = sum(1 << e for e, c in self.heads.items() if c == t)
            if edges or closes:
                if len(self.queue) >= self.qdepth:
                    self.late.append(f"work queue full at tick {t}")
                else:
                    self.queue.append((t, edges, closes))
            self.adv = t
        self.adv = max(self.adv, tick)

    def queue_read(self, addr: int, tick: int) -> int:
        self.advance(tick)
        head = self.queue[0] if self.queue and self.queue[0][0] <= tick - 2 else None
        if addr == Q_STAT:
            return int(head is not None)
        if head is None:
            return 0xDEAD_BEEF
        return {Q_T: head[0] & MASK32, Q_E: head[1], Q_C: head[2]}[addr]

    def win_read(self, addr: int, cycle: int) -> int:
        if cycle < self.win_at + 2 or cycle == self.blk_at + 1:
            return 0xDEAD_BEEF          # the block RAM's registered read is not there yet, or
                                        # it holds the blank-offset row read in the clock before
        t0, we, meta = self.m.out.slots[self.win_ra]
        return {WIN_T0: t0, WIN_WE: we, WIN_META: meta}[addr]

    def on_trigger(self, trig: tuple[int, int], cycle: int) -> None:
        if trig[0] <= self.tick_at(cycle):
            self.late.append(f"trigger of element {trig[1]} at {trig[0]} written at {self.tick_at(cycle)}")
        self.triggers.append((self.cur, trig[0], trig[1]))

    def on_event(self, word: int) -> None:
        self.words.append((self.cur, word))
        if word >> 62 & 1 and not word >> 61 & 1:     # a pulse record: the pulse fires
            c = self.cfg[word >> 37 & 7]
            self.echo.fire(word & MASK32, c.tx.copy(), c.delays.copy())

    def on_tick_done(self, cur: int, cycle: int) -> None:
        lag = self.tick_at(cycle) - cur
        self.lags.append((cur, lag))
        if lag >= self.lead // 2:
            self.late.append(f"logical tick {cur} done {lag} ticks late (P / 2 = {self.lead // 2})")

    # ---- running
    def _skip_idle(self, until: int) -> None:
        """At the poll loop: skip whole turns of it while nothing can become visible (no queue
        word, td not reached), i.e. exactly the clocks the loop would spin."""
        m = self.m
        c0 = m.cycle
        m.run(c0 + 1)
        m.run(c0 + 64, stop={self.poll})
        turn = m.cycle - c0
        if m.pc != self.poll or turn <= 0:
            return
        now = self.tick_at(m.cycle)
        nxt = self._next_event()
        target = (until if nxt is None else nxt) + 2
        if self.queue:
            target = min(target, self.queue[0][0] + 2)
        if m.mem.get(MAIN + M_ARMED, 0):
            target = min(target, m.mem[MAIN + M_TD] + 3)
        target = min(target, until)
        turns = (target - now) // turn - 2
        if turns > 0:
            m.cycle += turns * turn

    def run(self, duration_ticks: int) -> EngineRun:
        """Logical ticks [start, start + duration): the engine runs until it has done them all
        (the tick counter P past their end), noise on the lines as FastFiringModel.run adds it."""
        end = self.start + int(duration_ticks)
        self.echo.noise(self.start, end)
        stop = end + self.lead
        m = self.m
        while self.tick_at(m.cycle) < stop:
            m.run(m.cycle + 1_000_000, stop={self.poll})
            if m.pc == self.poll:
                self._skip_idle(stop)
        lags = [lag for cur, lag in self.lags if cur < end]
        return EngineRun(words=[w for cur, w in self.words if cur < end],
                         triggers=sorted((t, e) for cur, t, e in self.triggers if cur < end),
                         lag_max=max(lags, default=0), lag_ticks=len(lags), clocks=m.cycle,
                         late=list(self.late))
