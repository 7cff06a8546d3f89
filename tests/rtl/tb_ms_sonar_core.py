"""cocotb test of the whole sonar core through its register bus and its pins.

Configuration goes over the bus exactly as the host and firmware write it
(multisonar.regmap.schedule_writes; the firmware's load image, multisonar.regmap.load_writes),
echoes go in on echo_i, triggers are read off drive_o, and events come out through EVT_LO /
EVT_HI. Everything is compared with the golden model (FastFiringModel with the same decision
lead) driven by an identically seeded echo source.
Python wakes per pulse, per echo edge and per drive edge, never per clock; the clock runs in
the model (tests/rtl/ms_sonar_core_tb.sv, the core's wrapper).
"""

from __future__ import annotations

import numpy as np
import cocotb
from cocotb.triggers import ReadOnly, RisingEdge, Timer, ValueChange
from cocotb.utils import get_sim_time

from multisonar.constants import DEVICE_DECISION_LEAD
from multisonar.fastfiring import FastFiringModel, SceneEchoSource, SyntheticEchoSource, _rows, unpack_word
from multisonar.generated import sonar_regs as R
from multisonar.layout import load_layout
from multisonar.regmap import load_writes, schedule_writes
from multisonar.schedule import Schedule, VirtualSensor
from echo_driver import EchoDriver
from passthrough_bfm import PassthroughMaster
from tbutil import CLK_PERIOD_PS, reset

LEAD = DEVICE_DECISION_LEAD  # ms_scheduler's LEAD parameter default
MS = 48_000
LAYOUT = load_layout()


_CLOCK_ORIGIN_PS = [0]


def tick_now() -> int:
    """Tick of the current clock cycle, counted from the rising edge where this test's bench
    started (the cocotb tests of this module run one after the other on one free-running clock)."""
    return (int(get_sim_time("ps")) - _CLOCK_ORIGIN_PS[0]) // CLK_PERIOD_PS


def in_rtl_ticks(words: list[int], offset: int) -> list[int]:
    """The model's words with the records' ticks (bits 31:0 of a record, bit 62) on the RTL's
    tick counter, which runs ``offset`` ticks behind this bench's tick_now()."""
    rec = 1 << 62
    return [(w & ~0xFFFFFFFF) | ((w - offset) & 0xFFFFFFFF) if w & rec else w for w in words]


class CoreBench:
    def __init__(self, dut, sensor: VirtualSensor, source_factory, miss_gate: int | None = None):
        self.dut, self.sensor = dut, sensor
        self.miss_gate = miss_gate  # RX_FILTER.miss_gate to write (None: keep the reset value)
        self.gate = -1  # RX_FILTER.miss_gate as read back before the enable (the model's miss_gate)
        self.sched = Schedule(LAYOUT, [sensor])
        self.cfg = self.sched.validate()[0]
        self.source = source_factory()
        self.factory = source_factory
        self.fires: list[int] = []
        self.pin_rises: dict[int, list[int]] = {}
        self.echo = EchoDriver(dut.echo_i, LAYOUT.n, lambda tick: _CLOCK_ORIGIN_PS[0] + tick * CLK_PERIOD_PS)
        self.tasks = []
        self.words: list[int] = []
        self.tick_offset = 0  # tick_now() - the RTL's tick counter (tick_q)

    async def start(self) -> None:
        dut = self.dut
        await RisingEdge(dut.clk_i)
        _CLOCK_ORIGIN_PS[0] = int(get_sim_time("ps"))
        dut.echo_i.value = 0
        self.bus = PassthroughMaster(dut, dut.clk_i)
        await reset(dut.clk_i, dut.rst_i)
        for addr, value in schedule_writes(self.sched):
            await self.bus.write(addr, value)
        gate = R.REGISTERS["RX_FILTER"].fields["MISS_GATE"]
        if self.miss_gate is not None:
            await self.bus.write(R.RX_FILTER_ADDR, gate.put(await self.bus.read(R.RX_FILTER_ADDR), self.miss_gate))
        rx_filter = await self.bus.read(R.RX_FILTER_ADDR)
        self.gate = gate.get(rx_filter)
        self.hold = bool(R.REGISTERS["RX_FILTER"].fields["MISS_HOLD"].get(rx_filter))
        # the firmware's START: the load image through LOAD_ADDR / LOAD_DATA, then enable and start
        glitch = R.REGISTERS["RX_FILTER"].fields["GLITCH_MIN"].get(rx_filter)
        for addr, value in load_writes(self.sched, glitch_min=glitch, miss_gate=self.gate, lead=LEAD,
                                       miss_hold=self.hold):
            await self.bus.write(addr, value)
        self.tasks += [cocotb.start_soon(self._fire_loop()), cocotb.start_soon(self._pins())]
        ctrl = R.REGISTERS["CTRL"].fields
        await self.bus.write(R.CTRL_ADDR, ctrl["ENABLE"].mask | ctrl["START"].mask)

    async def _fire_loop(self) -> None:
        """One wake per pulse: the scheduler's decision strobe carries t0 (P ticks ahead)."""
        dut, tx = self.dut, [int(e) for e in self.cfg.tx]
        sched, core = dut.u_core.u_sched, dut.u_core
        while True:
            await RisingEdge(sched.pulse_o)
            await ReadOnly()
            t0 = tick_now() + ((int(sched.pulse_t0_o.value) - int(core.tick_q.value)) & 0xFFFFFFFF)
            self.tick_offset = (tick_now() - int(core.tick_q.value)) & 0xFFFFFFFF
            self.fires.append(t0)
            for rx, st, w in _rows(self.source.fire(t0, np.array(tx), self.cfg.delays.copy())):
                self.echo.drive(int(rx), max(int(st), t0), int(w))
            await RisingEdge(dut.clk_i)

    async def _pins(self) -> None:
        prev = 0
        while True:
            await ValueChange(self.dut.drive_o)
            now, cur = tick_now(), int(self.dut.drive_o.value)
            rising = cur & ~prev
            for e in range(LAYOUT.n):
                if rising >> e & 1:
                    self.pin_rises.setdefault(e, []).append(now)
            prev = cur

    async def drain_every(self, period_ticks: int) -> None:
        """Read the event FIFO empty every period (a host or firmware polling it)."""
        while True:
            await Timer(period_ticks * CLK_PERIOD_PS, unit="ps")
            self.words += await self.read_events()

    async def read_events(self) -> list[int]:
        hi = R.REGISTERS["EVT_HI"].fields
        words = []
        while True:
            lo = await self.bus.read(R.EVT_LO_ADDR)
            h = await self.bus.read(R.EVT_HI_ADDR)
            if not hi["VALID"].get(h):
                return words
            words.append((hi["DATA"].get(h) << 32) | lo)

    async def finish(self) -> None:
        """Stop taking pulses (the fire list is final); their triggers fire up to P later and
        their echoes still arrive: P + 4000 ticks later, stop."""
        self.tasks[0].cancel()   # _fire_loop
        await Timer((LEAD + 4000) * CLK_PERIOD_PS, unit="ps")
        self.stop()

    def stop(self) -> None:
        for t in self.tasks:
            if not t.done():
                t.cancel()
        self.echo.stop()


def burst_starts(rises: list[int], gap: int) -> list[int]:
    """First rising edge of each burst (edges closer than `gap` belong to the same burst)."""
    out, last = [], None
    for t in rises:
        if last is None or t - last > gap:
            out.append(t)
        last = t
    return out


async def core_scoreboard(dut, what: str, sensor: VirtualSensor, factory, dur_ticks: int,
                          miss_gate: int | None = None) -> dict:
    b = CoreBench(dut, sensor, factory, miss_gate)
    await b.start()
    b.tasks.append(cocotb.start_soon(b.drain_every(5 * MS)))
    await Timer(dur_ticks * CLK_PERIOD_PS, unit="ps")
    await b.finish()
    assert b.fires, f"{what}: the core never fired"
    # The model starts where the RTL took the table: its first pulse is due max(phase, P) later.
    e0 = b.fires[0] - max(b.cfg.phase, LEAD)
    model = FastFiringModel(b.sched, factory(), start_tick=e0, decision_lead=LEAD, miss_gate=b.gate,
                            miss_hold=b.hold)
    res = model.run(b.fires[-1] - e0 + 1)
    m_fires = [p.t0 for p in res.pulses]
    assert b.fires == m_fires[:len(b.fires)] and len(m_fires) >= len(b.fires), f"{what}: pulse ticks differ"
    # pins: every element of the group starts its burst at t0 + d_i, visible one clock later
    gap = 2 * 600 + 1
    for e, d in zip(b.cfg.tx, b.cfg.delays):
        expect = [t0 + int(d) + 1 for t0 in b.fires]
        got = burst_starts(b.pin_rises.get(int(e), []), gap)
        assert got[:len(expect)] == expect, f"{what}: element {e} bursts start at {got[:4]}..., expected {expect[:4]}..."
    for e in range(LAYOUT.n):
        if e not in b.cfg.tx:
            assert e not in b.pin_rises, f"{what}: element {e} drove but is not in the group"
    words = b.words + await b.read_events()
    # events of pulses the model also completed (the RTL ran a little past the last fire)
    m_words = in_rtl_ticks(res.words, b.tick_offset)  # ToF events and records, in FIFO order
    n = min(len(words), len(m_words))
    assert n >= len(b.fires), f"{what}: only {n} events"
    for i in range(n):
        assert words[i] == m_words[i], (f"{what}: word {i}: rtl {unpack_word(words[i])} "
                                       f"model {unpack_word(m_words[i])}")
    pulses = await b.bus.read(R.PULSES_ADDR)
    events = await b.bus.read(R.EVENTS_ADDR)
    overflows = await b.bus.read(R.OVERFLOWS_ADDR)
    status = await b.bus.read(R.STATUS_ADDR)
    st = R.REGISTERS["STATUS"].fields
    assert pulses == len(b.fires) and events == len(words) and overflows == 0
    assert st["RUNNING"].get(status) == 1 and st["SCHED_OVERRUN"].get(status) == 0
    dut._log.info("%s: %d pulses, %d events, all equal to the golden model", what, len(b.fires), len(words))
    return {"pulses": len(b.fires), "events": len(words), "gate": b.gate,
            "inits": sum(p.init for p in res.pulses if p.t0 <= b.fires[-1])}


@cocotb.test(timeout_time=2, timeout_unit="sec")
async def phased_group_static_ranges(dut):
    """3-element phased group (virtual source off-centre), 5 receivers, order 2."""
    ranges = {22: 2.5, 23: 2.3, 0: 2.2, 1: 2.25, 2: 2.6}
    await core_scoreboard(dut, "phased order 2",
                          VirtualSensor("front", tx=[23, 0, 1], rx=[22, 23, 0, 1, 2], order=2, source=(0.05, 0.0)),
                          lambda: SyntheticEchoSource(ranges, ringdown_ticks=60000), 80 * MS)


def _gate_step_case():
    """A tracked reflector (order 2, K = 2) whose ToF jumps by 5000 ticks at 60 ms (inside the
    window: like an alias echo of another pulse)."""
    from multisonar.constants import speed_of_sound
    r0 = 1.2
    r1 = r0 + 5000 / 48e6 * speed_of_sound(20.0) / 2
    sensor = VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=2, miss_limit=2)
    return sensor, lambda: SyntheticEchoSource(r0, step_ranges_m=r1, step_tick=60 * MS)


@cocotb.test(timeout_time=2, timeout_unit="sec")
async def miss_gate_register_reset_value(dut):
    """RX_FILTER.miss_gate at its reset value (600 ticks): the jumped echoes count as misses
    and K = 2 of them send an init ping; equal to the model with the gate read back."""
    from multisonar.fastfiring import DEFAULT_MISS_GATE
    sensor, factory = _gate_step_case()
    st = await core_scoreboard(dut, "miss gate reset value", sensor, factory, 110 * MS)
    assert st["gate"] == DEFAULT_MISS_GATE and st["inits"] == 2, st


@cocotb.test(timeout_time=2, timeout_unit="sec")
async def miss_gate_register_off(dut):
    """RX_FILTER.miss_gate written to 0 over the bus (off): the jump is tracked, no init ping."""
    sensor, factory = _gate_step_case()
    st = await core_scoreboard(dut, "miss gate off", sensor, factory, 110 * MS, miss_gate=0)
    assert st["gate"] == 0 and st["inits"] == 1, st


class EchoesOnly:
    """An echo source without its spurious-pulse stream (the scheduler test covers spurious
    pulses; here the model and the RTL bench must draw the same random numbers per pulse)."""

    def __init__(self, source):
        self.fire = source.fire


@cocotb.test(timeout_time=2, timeout_unit="sec")
async def wall_1m_scene_through_registers(dut):
    """The acoustic simulator's wall_1m scene (jitter, widths, crosstalk), order 1, events read
    over the bus."""
    await core_scoreboard(dut, "wall_1m", VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=1),
                          lambda: EchoesOnly(SceneEchoSource("wall_1m", rng=np.random.default_rng(11))), 60 * MS)


@cocotb.test(timeout_time=2, timeout_unit="sec")
async def event_fifo_full_counted_and_flagged(dut):
    """Nobody reads the (32-word) event FIFO until 48 events were produced: the core keeps scheduling exactly as the
    model, drops are counted in OVERFLOWS, the first word stored after the gap carries bit 44,
    and every stored word is the model's event at the right index (nothing lost silently)."""
    sensor = VirtualSensor("front", tx=[0], rx=[22, 23, 0, 1, 2], order=2)
    ranges = {22: 2.0, 23: 1.9, 0: 1.8, 1: 1.95, 2: 2.05}
    b = CoreBench(dut, sensor, lambda: SyntheticEchoSource(ranges))
    await b.start()
    for _ in range(40):  # until well past full (EVENTS counts every event produced)
        await Timer(5 * MS * CLK_PERIOD_PS, unit="ps")
        if await b.bus.read(R.EVENTS_ADDR) > 48:
            break
    first = await b.read_events()  # the 32 oldest events
    dropped = await b.bus.read(R.OVERFLOWS_ADDR)
    await Timer(20 * MS * CLK_PERIOD_PS, unit="ps")
    await b.finish()
    rest = await b.read_events()
    dropped = await b.bus.read(R.OVERFLOWS_ADDR)
    produced = await b.bus.read(R.EVENTS_ADDR)
    e0 = b.fires[0] - max(b.cfg.phase, LEAD)
    model = FastFiringModel(b.sched, SyntheticEchoSource(ranges), start_tick=e0, decision_lead=LEAD, miss_gate=b.gate,
                            miss_hold=b.hold)
    res = model.run(b.fires[-1] - e0 + 1)
    assert [p.t0 for p in res.pulses][:len(b.fires)] == b.fires, "scheduling must not depend on the FIFO"
    m = in_rtl_ticks(res.words, b.tick_offset)
    flag = 1 << 44
    got = first + rest
    flagged = [i for i, w in enumerate(got) if w & flag]
    assert len(first) >= 32 and dropped > 0, (len(first), dropped)
    assert len(flagged) == 1, f"exactly one word must carry the overflow flag, got {flagged}"
    k = flagged[0]
    assert got[:k] == m[:k], "the FIFO keeps the oldest events"
    tail, want = [w & ~flag for w in got[k:]], m[k + dropped:]   # the RTL ran past the model's end
    assert len(tail) >= len(want) and tail[:len(want)] == want, \
        "after the gap every stored word is the model's event at its index"
    assert produced == len(got) + dropped, (produced, dropped, len(got))
    st = R.REGISTERS["STATUS"].fields
    assert st["SCHED_OVERRUN"].get(await b.bus.read(R.STATUS_ADDR)) == 0
    dut._log.info("FIFO full: %d events produced, %d kept before the gap, %d dropped and counted, %d after "
                  "(first flagged), all at the model's indices", produced, k, dropped, len(got) - k)
