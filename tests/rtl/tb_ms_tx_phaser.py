"""cocotb tests of ms_tx_phaser against an event-based, tick-exact Python model.

Python never wakes per clock: fires are placed with Timers plus one RisingEdge, every
change of drive_o / collision_o is recorded by awaiting the vector's own value changes
(a few per half period), and after a Timer covering the whole scenario the recorded edge
ticks are compared with the model's, element by element. The model states the module's
contract (rtl/tx/ms_tx_phaser.sv header):

  - fire in cycle t0: element i of the mask triggers at tick t = t0 + d_i, i.e. drive_o[i]
    changes at the clock edge that ends cycle t (first high in cycle t + 1);
  - a burst is `cycles` periods of 2*H ticks, high first (H = max(half_period, 1));
  - half_period is sampled in every cycle in which no element is busy (busy_o all low), the
    fire's own cycle included: a fire that finds all elements idle sets H for every burst
    until they are all idle again, and the half_period of fires in between is ignored;
  - a fire replaces a trigger that is still pending (tick >= t0): collision; a trigger cuts
    a running burst and restarts it; cycles = 0 drives nothing from the trigger on;
  - burst cycles are latched at fire (the testbench garbles the inputs after each fire; a
    garbled half_period while all are idle is overwritten by the next fire's);
  - busy_o[i] is high from the fire tick while a trigger is pending and from the trigger
    tick while a burst runs (registered: changes at edges like drive_o).

Tick numbering in the testbench: edge k is the k-th rising clock edge after a reference
edge; edge k ends cycle k. A fire driven after edge e is high in cycle t0 = e + 1.
"""

from __future__ import annotations

import os
import random
import time
from dataclasses import dataclass, field

import cocotb
from cocotb.triggers import RisingEdge, Timer
from cocotb.utils import get_sim_time

from multisonar import load_layout
from multisonar.constants import speed_of_sound
from multisonar.schedule import phasing_delays
from tbutil import CLK_PERIOD_PS, reset, start_clock

HALF_40K = 600  # 48 MHz / 40 kHz / 2
HALF_49K4 = 486  # 48 MHz / 49.4 kHz / 2 (rounded)
DELAY_MAX = 0xFFFF


@dataclass
class Fire:
    t0: int
    delays: dict[int, int]  # element -> delay (the mask is the key set)
    cycles: int
    half: int


@dataclass
class Expect:
    edges: list[list[tuple[int, int]]]  # per element: (edge tick, new level)
    busy: list[list[tuple[int, int]]]  # per element: busy_o (edge tick, new level)
    collisions: int  # collision_o high cycles (one per colliding fire)
    end: int  # tick after which every element is idle


def _merge(intervals: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """[a, b) tick intervals (empty ones dropped) as (tick, level) edges of their union."""
    out: list[list[int]] = []
    for a, b in sorted(iv for iv in intervals if iv[0] < iv[1]):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(x, lvl) for a, b in out for x, lvl in ((a, 1), (b, 0))]


def _busy_in(triggers: list[list[tuple[int, int, int]]], pending: list[list[tuple[int, int]]], c: int) -> bool:
    """Some element busy in cycle c (busy_o high in cycle c: an interval (a, b) of edge ticks
    covers the cycles a + 1 .. b), from the triggers and pending spans known so far."""
    for tr, pe in zip(triggers, pending):
        if any(a < c <= b for a, b in pe):
            return True
        for k, (t, h, cyc) in enumerate(tr):
            b = t + 2 * h * cyc
            if k + 1 < len(tr):
                b = min(b, tr[k + 1][0])
            if t < c <= b:
                return True
    return False


def model(fires: list[Fire], num_ch: int) -> Expect:
    """The contract as events: triggers per element, then bursts cut by the next trigger."""
    triggers: list[list[tuple[int, int, int]]] = [[] for _ in range(num_ch)]
    # busy_o: pending from the fire tick to the trigger tick (or to the next fire on the element)
    pending: list[list[tuple[int, int]]] = [[] for _ in range(num_ch)]
    collisions = 0
    end = 0
    half = 1  # H of the current busy stretch
    for f in sorted(fires, key=lambda f: f.t0):
        # fires come in time order and only shorten what is already known from f.t0 on, so
        # whether cycle f.t0 is busy follows from the earlier fires
        if not _busy_in(triggers, pending, f.t0):
            half = max(f.half, 1)
        hit = False
        for e, d in f.delays.items():
            tr = triggers[e]
            while tr and tr[-1][0] >= f.t0:  # pending trigger: replaced
                tr.pop()
                hit = True
            tr.append((f.t0 + d, half, f.cycles))
            pe = pending[e]
            if pe and pe[-1][1] > f.t0:  # the element's previous pending trigger, replaced
                pe[-1] = (pe[-1][0], f.t0)
            pe.append((f.t0, f.t0 + d))
        collisions += hit
    edges = []
    busy = []
    for i, tr in enumerate(triggers):
        intervals: list[list[int]] = []
        busy_iv = list(pending[i])
        for k, (t, h, cyc) in enumerate(tr):
            stop = tr[k + 1][0] if k + 1 < len(tr) else None
            busy_iv.append((t, t + 2 * h * cyc if stop is None else min(t + 2 * h * cyc, stop)))
            for j in range(cyc):
                a, b = t + 2 * j * h, t + 2 * j * h + h
                if stop is not None:
                    if a >= stop:
                        break
                    b = min(b, stop)
                if intervals and intervals[-1][1] == a:
                    intervals[-1][1] = b  # old high half runs into the restarted one
                else:
                    intervals.append([a, b])
            end = max(end, t + 2 * h * cyc)
        edges.append([(x, lvl) for a, b in intervals for x, lvl in ((a, 1), (b, 0))])
        busy.append(_merge(busy_iv))
    return Expect(edges, busy, collisions, end)


class Bench:
    """Drives fires on chosen ticks and records every output change with its tick."""

    def __init__(self, dut):
        self.dut = dut
        self.num_ch = len(dut.drive_o)
        self.rng = random.Random(0)
        self.drive_log: list[tuple[int, int]] = []
        self.busy_log: list[tuple[int, int]] = []
        self.coll_log: list[tuple[int, int]] = []
        self.ref_ps = 0
        self.now = 0  # edge index Python last woke on
        self.fires: list[Fire] = []

    async def start(self) -> None:
        dut = self.dut
        start_clock(dut.clk_i)
        dut.fire_i.value = 0
        dut.mask_i.value = 0
        dut.delay_i.value = 0
        dut.burst_cycles_i.value = 0
        dut.half_period_i.value = 0
        await reset(dut.clk_i, dut.rst_i)
        await RisingEdge(dut.clk_i)
        self.ref_ps = round(get_sim_time("ps"))
        self.now = 0
        cocotb.start_soon(self._record(dut.drive_o, self.drive_log))
        cocotb.start_soon(self._record_settled(dut.busy_o, self.busy_log))
        cocotb.start_soon(self._record(dut.collision_o, self.coll_log))

    def tick_now(self) -> int:
        dt = round(get_sim_time("ps")) - self.ref_ps
        assert dt % CLK_PERIOD_PS == 0, f"output changed {dt % CLK_PERIOD_PS} ps after a clock edge"
        return dt // CLK_PERIOD_PS

    async def _record(self, sig, log) -> None:
        while True:
            await sig.value_change
            log.append((self.tick_now(), int(sig.value)))

    async def _record_settled(self, sig, log) -> None:
        """_record for an OR of flops (busy_o): a simulator may show a zero-time glitch while
        the flops of one edge update one by one (Icarus), so only a tick's last value counts."""
        while True:
            await sig.value_change
            t, v = self.tick_now(), int(sig.value)
            if log and log[-1][0] == t:
                log.pop()
            if (log[-1][1] if log else 0) != v:
                log.append((t, v))

    async def goto_edge(self, k: int) -> None:
        """Wake right after rising edge k (k >= now)."""
        assert k >= self.now, (k, self.now)
        if k - self.now >= 2:
            await Timer((k - self.now - 1) * CLK_PERIOD_PS + CLK_PERIOD_PS // 2, unit="ps")
        if k > self.now:
            await RisingEdge(self.dut.clk_i)
        self.now = self.tick_now()
        assert self.now == k, (self.now, k)

    def garble(self) -> None:
        """Change every fire-time input while fire_i is low: must have no effect."""
        dut = self.dut
        dut.fire_i.value = 0
        dut.mask_i.value = self.rng.getrandbits(self.num_ch)
        dut.delay_i.value = self.rng.getrandbits(16 * self.num_ch)
        dut.burst_cycles_i.value = self.rng.getrandbits(8 * self.num_ch)
        dut.half_period_i.value = self.rng.getrandbits(16)

    async def fire(self, t0: int, delays: dict[int, int], cycles: int, half: int) -> None:
        """fire_i high in cycle t0 with these elements/delays (other delay lanes random)."""
        await self.goto_edge(t0 - 1)
        lanes = [self.rng.getrandbits(16) for _ in range(self.num_ch)]
        mask = 0
        for e, d in delays.items():
            assert 0 <= d <= DELAY_MAX, d
            lanes[e] = d
            mask |= 1 << e
        dut = self.dut
        dut.fire_i.value = 1
        dut.mask_i.value = mask
        dut.delay_i.value = sum(v << (16 * i) for i, v in enumerate(lanes))
        # burst cycles are per element: the fired lanes carry this fire's, the others random
        cyc = [self.rng.getrandbits(8) for _ in range(self.num_ch)]
        for e in delays:
            cyc[e] = cycles
        dut.burst_cycles_i.value = sum(v << (8 * i) for i, v in enumerate(cyc))
        dut.half_period_i.value = half
        self.fires.append(Fire(t0, dict(delays), cycles, half))
        await self.goto_edge(t0)
        self.garble()

    def _edges(self, log: list[tuple[int, int]]) -> list[list[tuple[int, int]]]:
        """A recorded vector's changes, split per element."""
        edges: list[list[tuple[int, int]]] = [[] for _ in range(self.num_ch)]
        prev = 0
        for t, v in log:
            ch = v ^ prev
            for i in range(self.num_ch):
                if ch >> i & 1:
                    edges[i].append((t, v >> i & 1))
            prev = v
        return edges

    def observed(self) -> tuple[list[list[tuple[int, int]]], int]:
        edges = self._edges(self.drive_log)
        high = 0
        rise = None
        for t, v in self.coll_log:
            if v:
                rise = t
            else:
                high += t - rise
        return edges, high

    async def finish(self, what: str, expect_collisions: int | None = None) -> Expect:
        """Wait until the model says all is idle, then compare everything recorded so far."""
        exp = model(self.fires, self.num_ch)
        await self.goto_edge(max(self.now, exp.end) + 4)
        got, coll = self.observed()
        for i in range(self.num_ch):
            if got[i] != exp.edges[i]:
                diff = next(((a, b) for a, b in zip(got[i] + [None], exp.edges[i] + [None]) if a != b))
                raise AssertionError(f"{what}: element {i}: {len(got[i])} drive edges, model "
                                     f"{len(exp.edges[i])}; first difference (tick, level) got/model {diff}")
        busy = self._edges(self.busy_log)
        for i in range(self.num_ch):
            if busy[i] != exp.busy[i]:
                diff = next(((a, b) for a, b in zip(busy[i] + [None], exp.busy[i] + [None]) if a != b))
                raise AssertionError(f"{what}: element {i}: busy_o first difference (tick, level) got/model {diff}")
        assert coll == exp.collisions, f"{what}: collision_o high {coll} cycles, model {exp.collisions}"
        if expect_collisions is not None:
            assert coll == expect_collisions, f"{what}: {coll} collisions, scenario has {expect_collisions}"
        assert int(self.dut.busy_o.value) == 0, f"{what}: busy_o {int(self.dut.busy_o.value):#x} after the end"
        assert int(self.dut.drive_o.value) == 0
        return exp


def speed(dut, what: str, ticks: int, wall0: float) -> None:
    wall = time.perf_counter() - wall0
    dut._log.info("%s: %d ticks in %.2f s wall = %.0f cycles/s", what, ticks, wall, ticks / wall)


def group_rounds(size: int, n: int) -> list[list[list[int]]]:
    """All n adjacent groups of `size` around the ring, packed greedily into rounds of
    element-disjoint groups."""
    step = n // (n // size)  # groups spread evenly: n // size of them per round
    starts = sorted(range(n), key=lambda s: (s % step, s))
    todo = [[(s + j) % n for j in range(size)] for s in starts]
    rounds = []
    while todo:
        used: set[int] = set()
        rnd, rest = [], []
        for g in todo:
            if used.isdisjoint(g):
                rnd.append(g)
                used.update(g)
            else:
                rest.append(g)
        rounds.append(rnd)
        todo = rest
    return rounds


SOURCES = [(0.0, 0.0), (0.12, 0.05), (-0.2, 0.1), (0.05, -0.25)]


@cocotb.test()
async def phased_groups(dut):
    """(1) every adjacent 1/2/3/5-element group, several virtual sources, phasing_delays:
    every element's edges exactly on t0 + d_i (+ k*H), 40 and 49.4 kHz, 1..16 cycles.
    The groups of one round run concurrently, each its own fire a few ticks apart."""
    b = Bench(dut)
    await b.start()
    layout = load_layout()
    c = speed_of_sound()
    n = b.num_ch
    n_src = int(os.environ.get("TX_SOURCES", str(len(SOURCES))))
    wall0 = time.perf_counter()
    k = 0
    t = b.now + 2
    nfires = 0
    for src in SOURCES[:n_src]:
        for size in (1, 2, 3, 5):
            for rnd in group_rounds(size, n):
                for g in rnd:
                    d = phasing_delays(layout, g, src, c)
                    assert d.min() == 0 and d.max() <= DELAY_MAX
                    cycles, half = 1 + k % 16, (HALF_40K, HALF_49K4)[(k // 16) % 2]
                    k += 1
                    await b.fire(t, {e: int(x) for e, x in zip(g, d)}, cycles, half)
                    t += b.rng.randint(1, 6)
                    nfires += 1
                t = model(b.fires, n).end + b.rng.randint(2, 20)
    exp = await b.finish("phased groups", expect_collisions=0)
    pulses = sum(len(e) for e in exp.edges) // 2
    speed(dut, f"phased groups ({n_src} sources, {nfires} fires, {pulses} pulses)", b.now, wall0)


@cocotb.test()
async def unmasked_stay_low(dut):
    """(2) elements outside mask_i never move, whatever their delay lanes hold; an empty mask
    does nothing."""
    b = Bench(dut)
    await b.start()
    await b.fire(5, {}, 4, HALF_40K)
    await b.fire(9, {7: 0, 8: 40, 9: 3}, 3, HALF_49K4)
    await b.fire(12, {20: 100}, 1, 7)
    exp = await b.finish("unmasked")
    moved = [i for i in range(b.num_ch) if exp.edges[i]]
    assert moved == [7, 8, 9, 20], moved


@cocotb.test()
async def two_groups_close(dut):
    """(3) two groups on disjoint elements fired 1 and 3 ticks apart, different bursts."""
    b = Bench(dut)
    await b.start()
    layout, c = load_layout(), speed_of_sound()
    for gap in (1, 3):
        g1, g2 = [0, 1, 2], [10, 11, 12, 13, 14]
        d1 = phasing_delays(layout, g1, (0.1, 0.0), c)
        d2 = phasing_delays(layout, g2, (-0.15, 0.05), c)
        t0 = b.now + 3
        await b.fire(t0, dict(zip(g1, map(int, d1))), 5, HALF_40K)
        await b.fire(t0 + gap, dict(zip(g2, map(int, d2))), 8, HALF_49K4)
        await b.finish(f"two groups {gap} ticks apart", expect_collisions=0)


@cocotb.test()
async def collisions(dut):
    """(4) overrides of pending triggers are counted; bursts restart at a new trigger."""
    b = Bench(dut)
    await b.start()
    t = 10
    # pending delay of element 2 overridden by a second group: 1 collision
    await b.fire(t, {0: 1000, 1: 2000, 2: 3000}, 2, HALF_40K)
    await b.fire(t + 500, {2: 10, 3: 20}, 2, HALF_49K4)
    # fire in the very tick the pending trigger is due: still pending, replaced: 1
    await b.fire(t + 6000, {5: 100}, 1, 50)
    await b.fire(t + 6100, {5: 50}, 1, 50)
    # one tick later the trigger has happened: no collision, a burst restart instead
    await b.fire(t + 6300, {6: 100}, 3, 50)
    await b.fire(t + 6401, {6: 30}, 2, 50)
    # back-to-back colliding fires: collision_o high two cycles = 2
    await b.fire(t + 7000, {8: 500, 9: 500}, 1, 20)
    await b.fire(t + 7001, {9: 400}, 1, 20)
    await b.fire(t + 7002, {8: 300}, 1, 20)
    # a fire during a running burst (no pending trigger): restart, no collision; delay 0
    # restart inside a high half keeps the drive high
    await b.fire(t + 8000, {12: 0}, 4, 100)
    await b.fire(t + 8050, {12: 0}, 2, 100)
    await b.fire(t + 8400, {12: 10}, 1, 100)
    # burst_cycles 0 on a running burst: silent from its trigger on, not a collision
    await b.fire(t + 9000, {14: 0}, 4, 100)
    await b.fire(t + 9130, {14: 20}, 0, 100)
    # burst_cycles 0 pending, overridden: a collision like any other
    await b.fire(t + 10000, {15: 200}, 0, 100)
    await b.fire(t + 10100, {15: 5}, 1, 100)
    await b.finish("collision scenarios", expect_collisions=5)
    dut._log.info("collision scenarios: 5 collisions counted, all drives on the model's ticks")


@cocotb.test()
async def random_overlap(dut):
    """Dense random fires (short bursts, overlapping masks): collisions, restarts and
    back-to-back fires everywhere, against the model."""
    b = Bench(dut)
    await b.start()
    rng = random.Random(7)
    wall0 = time.perf_counter()
    t = 5
    for _ in range(int(os.environ.get("TX_RANDOM_FIRES", "300"))):
        elems = rng.sample(range(b.num_ch), rng.randint(0, 6))
        delays = {e: rng.choice([0, 1, rng.randint(0, 40), rng.randint(0, 400)]) for e in elems}
        await b.fire(t, delays, rng.choice([0, 1, 2, 3, rng.randint(1, 12)]), rng.choice([0, 1, 2, rng.randint(1, 30)]))
        t += rng.choice([1, 1, 2, rng.randint(1, 60), rng.randint(1, 400)])
    exp = await b.finish("random overlap")
    assert exp.collisions > 20, "stimulus produced too few collisions to be a test"
    speed(dut, f"random overlap ({exp.collisions} collisions)", b.now, wall0)


@cocotb.test()
async def max_delay(dut):
    """(5) delays up to 2^16 - 1 on one fire, CSR inputs garbled during the wait."""
    b = Bench(dut)
    await b.start()
    await b.fire(3, {0: DELAY_MAX, 1: DELAY_MAX - 1, 2: 0, 3: 1, 4: 0x8000, 23: 0x7FFF}, 2, HALF_40K)
    exp = await b.finish("max delay", expect_collisions=0)
    assert exp.edges[0][0] == (3 + DELAY_MAX, 1)


@cocotb.test()
async def burst_corners(dut):
    """Half period 1 and 0 (= 1), 0 cycles (no drive), 255 cycles (9-bit half counter)."""
    b = Bench(dut)
    await b.start()
    await b.fire(3, {0: 0, 1: 2}, 3, 1)
    await b.fire(4, {2: 1}, 2, 0)
    await b.fire(5, {3: 0, 4: 9}, 0, HALF_40K)
    await b.fire(6, {5: 3}, 255, 2)
    await b.fire(7, {6: 0}, 1, 0xFFFF >> 4)
    exp = await b.finish("burst corners", expect_collisions=0)
    assert exp.edges[3] == [] and exp.edges[4] == []
    assert len(exp.edges[5]) == 2 * 255
