"""cocotb tests of ms_csr: the PeakRDL register block plus its VS-table and delay-table RAMs
and the scheduler's load port (LOAD_ADDR / LOAD_DATA).

Every expectation comes from the generated Python register map (multisonar.generated.
sonar_regs), so these tests also prove that RTL, C header and host constants agree: all
three are generated from rtl/regs/sonar_regs.rdl.
"""

from __future__ import annotations

import os
import random

import cocotb
from cocotb.triggers import ClockCycles, FallingEdge, Timer

from multisonar import TICK_HZ, load_layout
from multisonar.generated import sonar_regs as R
from passthrough_bfm import BusError, PassthroughMaster
from tbutil import reset, start_clock


async def setup(dut) -> PassthroughMaster:
    start_clock(dut.clk_i)
    for name in ("running_i", "fifo_level_i", "event_i", "overflow_i", "pulse_i", "evt_rvalid_i",
                 "evt_rdata_i", "sched_overrun_i", "tx_collision_i"):
        getattr(dut, name).value = 0
    bus = PassthroughMaster(dut, dut.clk_i)
    await reset(dut.clk_i, dut.rst_i)
    await ClockCycles(dut.clk_i, VS_WORDS + 2)  # the VS table's refill after reset (bus stalled)
    return bus


VS_REGS = ["VS_TX_MASK", "VS_RX_MASK", "VS_MODE", "VS_WINDOW", "VS_T_DEAD", "VS_MAX_TOF", "VS_XTALK",
           "VS_TRACK", "VS_PHASE"]
VS_WORDS = 8 * len(VS_REGS)
# the build's parameters (tests/rtl/test_ms_csr.py passes them to both): entries implemented,
# window slots reported
CSR_NUM_VS = int(os.environ.get("CSR_NUM_VS", "8"))
CSR_WSLOTS = int(os.environ.get("CSR_WSLOTS", "16"))


def all_addresses(reg: R.Register):
    if not reg.dims:
        yield (), reg.address
        return
    (n,) = reg.dims  # the map has only one-dimensional arrays
    for i in range(n):
        yield (i,), reg.addr(i)


@cocotb.test()
async def reset_values_match_register_map(dut):
    """After reset every register reads its generated reset value; identity fields are right."""
    bus = await setup(dut)
    for reg in R.REGISTERS.values():
        for idx, addr in all_addresses(reg):
            got = await bus.read(addr)
            assert got == reg.reset, f"{reg.name}{list(idx)} @0x{addr:X}: read 0x{got:X}, reset is 0x{reg.reset:X}"
    assert await bus.read(R.ID_ADDR) == int.from_bytes(b"MSNR", "big")
    assert await bus.read(R.TICK_HZ_ADDR) == TICK_HZ
    caps = await bus.read(R.CAPS_ADDR)
    assert R.REGISTERS["CAPS"].fields["NUM_CH"].get(caps) == load_layout().n
    assert R.REGISTERS["CAPS"].fields["NUM_VS"].get(caps) == R.REGISTERS["VS_MODE"].dims[0]


def writable_mask(reg: R.Register) -> int:
    m = 0
    for f in reg.fields.values():
        if "w" in f.sw and "r" in f.sw:
            m |= f.mask
    return m


@cocotb.test()
async def read_write_fields_and_outputs(dut):
    """Random values written to every read/write register read back masked to its fields and
    appear on the outputs the core uses."""
    bus = await setup(dut)
    rng = random.Random(1)
    written: dict[tuple[str, tuple[int, ...]], int] = {}
    for reg in R.REGISTERS.values():
        if reg.name == "CTRL":
            continue  # has self-clearing strobes; covered below
        mask = writable_mask(reg)
        if not mask:
            continue
        for idx, addr in all_addresses(reg):
            v = rng.getrandbits(32)
            await bus.write(addr, v)
            written[(reg.name, idx)] = (v & mask) | (reg.reset & ~mask)
    for (name, idx), expect in written.items():
        reg = R.REGISTERS[name]
        got = await bus.read(reg.addr(*idx))
        assert got == expect, f"{name}{list(idx)}: read 0x{got:X}, expected 0x{expect:X}"
    n_ch = R.VS_TX_MASK_MASK_WIDTH
    assert n_ch == load_layout().n
    assert [r for r in R.REGISTERS if r.startswith("VS_")] == VS_REGS
    assert int(dut.ld_addr_o.value) == written[("LOAD_ADDR", ())]
    assert int(dut.ld_data_o.value) == written[("LOAD_DATA", ())]
    burst = written[("BURST", ())]
    assert int(dut.burst_half_period_o.value) == R.REGISTERS["BURST"].fields["HALF_PERIOD"].get(burst)
    assert int(dut.burst_cycles_o.value) == R.REGISTERS["BURST"].fields["CYCLES"].get(burst)
    assert int(dut.glitch_min_o.value) == R.REGISTERS["RX_FILTER"].fields["GLITCH_MIN"].get(written[("RX_FILTER", ())])


async def strobe(dut, signal, n: int) -> None:
    for _ in range(n):
        await FallingEdge(dut.clk_i)
        signal.value = 1
        await FallingEdge(dut.clk_i)
        signal.value = 0


@cocotb.test()
async def counters_status_and_errors(dut):
    """Counters count strobes and clear on CTRL.clear_counters; status follows the core;
    read-only and unmapped addresses answer with an error instead of hanging."""
    bus = await setup(dut)
    await strobe(dut, dut.event_i, 37)
    await strobe(dut, dut.overflow_i, 5)
    await strobe(dut, dut.pulse_i, 11)
    await strobe(dut, dut.tx_collision_i, 2)
    assert await bus.read(R.TX_COLLISIONS_ADDR) == 2
    assert await bus.read(R.EVENTS_ADDR) == 37
    assert await bus.read(R.OVERFLOWS_ADDR) == 5
    assert await bus.read(R.PULSES_ADDR) == 11
    ctrl = R.REGISTERS["CTRL"].fields
    await bus.write(R.CTRL_ADDR, ctrl["CLEAR_COUNTERS"].mask | ctrl["ENABLE"].mask)
    for addr in (R.EVENTS_ADDR, R.OVERFLOWS_ADDR, R.PULSES_ADDR, R.TX_COLLISIONS_ADDR):
        assert await bus.read(addr) == 0
    # singlepulse fields read back as 0; enable stays set and drives enable_o
    assert await bus.read(R.CTRL_ADDR) == ctrl["ENABLE"].mask
    assert int(dut.enable_o.value) == 1

    st = R.REGISTERS["STATUS"].fields
    dut.running_i.value = 1
    dut.sched_overrun_i.value = 1
    dut.fifo_level_i.value = 0x5A5
    await bus.write(R.STATUS_ADDR, st["CFG_ERROR"].put(0, 0xA) | st["CFG_ERROR_VS"].put(0, 3))  # the firmware's
    await ClockCycles(dut.clk_i, 2)
    s = await bus.read(R.STATUS_ADDR)
    assert (st["RUNNING"].get(s), st["CFG_ERROR"].get(s), st["CFG_ERROR_VS"].get(s), st["FIFO_LEVEL"].get(s)) == (1, 0xA, 3, 0x5A5)
    assert st["SCHED_OVERRUN"].get(s) == 1

    r = await bus.write_raw(R.ID_ADDR, 0)
    assert r.error, "write to read-only ID must answer wr_err"
    assert await bus.read(R.ID_ADDR) == R.REGISTERS["ID"].reset
    r = await bus.read_raw(0x3FC)  # between the VS table and the delay memory: unmapped
    assert r.error, "read of an unmapped address must answer rd_err"
    try:
        await bus.read(0x3FC)
    except BusError:
        pass
    else:
        raise AssertionError("BusError expected")


@cocotb.test()
async def delay_table_bus(dut):
    """The phasing-delay memory: every entry written over the bus reads back over the bus, its
    upper bits dropped (16 kept)."""
    bus = await setup(dut)
    mem = R.MEMORIES["DELAY"]
    rng = random.Random(7)
    values = [rng.getrandbits(32) for _ in range(mem.entries)]
    for i, v in enumerate(values):
        await bus.write(mem.address + i * mem.stride, v)
    for i in range(mem.entries):
        assert await bus.read(mem.address + i * mem.stride) == values[i] & 0xFFFF, f"entry {i}"


@cocotb.test()
async def load_port_one_strobe_per_data_write(dut):
    """LOAD_DATA writes reach the scheduler's load port: one ld_we_o strobe per write, a clock
    after it, with the word and LOAD_ADDR as written (the address written once per run of
    words, or before each); no strobe from LOAD_ADDR writes or LOAD_DATA reads."""
    bus = await setup(dut)
    rng = random.Random(11)
    seen = []

    async def monitor():
        while True:
            await FallingEdge(dut.clk_i)
            if int(dut.ld_we_o.value):
                seen.append((int(dut.ld_addr_o.value), int(dut.ld_data_o.value)))

    task = cocotb.start_soon(monitor())
    want = []
    for _ in range(40):
        a, w = rng.getrandbits(12), rng.getrandbits(32)
        await bus.write(R.LOAD_ADDR_ADDR, a)
        await bus.write(R.LOAD_DATA_ADDR, w)
        want.append((a, w))
        if rng.random() < 0.3:
            await bus.read(R.LOAD_DATA_ADDR)
            await bus.write(R.LOAD_ADDR_ADDR, rng.getrandbits(12))
            await bus.write(R.LOAD_ADDR_ADDR, a)
    await ClockCycles(dut.clk_i, 4)
    task.cancel()
    assert seen == want, (len(seen), len(want), seen[:3], want[:3])


@cocotb.test()
async def event_readout_pops_on_high_word(dut):
    """EVT_LO/EVT_HI show the FIFO head; reading EVT_HI pops it exactly once, and an empty
    FIFO reads as valid=0 without popping."""
    bus = await setup(dut)
    rng = random.Random(3)
    queue = [rng.getrandbits(45) for _ in range(20)]  # bits 44:0 as the core writes them
    pops = 0

    async def fifo_model():
        nonlocal pops
        pop_seen = False
        while True:
            await FallingEdge(dut.clk_i)
            if pop_seen:  # a FIFO pops at the clock edge that sampled the strobe
                assert queue, "pop with an empty FIFO"
                queue.pop(0)
                pops += 1
            dut.evt_rvalid_i.value = int(bool(queue))
            dut.evt_rdata_i.value = queue[0] if queue else 0
            await Timer(1, "ns")  # after the bus master's writes of this falling edge settle
            pop_seen = bool(int(dut.evt_pop_o.value))

    cocotb.start_soon(fifo_model())
    await ClockCycles(dut.clk_i, 2)
    hi = R.REGISTERS["EVT_HI"].fields
    expect = list(queue)
    got = []
    for _ in range(25):
        lo = await bus.read(R.EVT_LO_ADDR)
        h = await bus.read(R.EVT_HI_ADDR)
        if not hi["VALID"].get(h):
            assert lo == 0 and h == 0
            continue
        got.append((hi["DATA"].get(h) << 32) | lo)
    assert got == expect and pops == len(expect)
    r = await bus.write_raw(R.EVT_HI_ADDR, 0)
    assert r.error, "EVT_HI is read-only"


@cocotb.test()
async def event_words_belong_to_one_event(dut):
    """An event that arrives between the EVT_LO and the EVT_HI read of an empty FIFO is not
    popped with the empty low word (the firmware saw lo = 0 with the new event's high word:
    the system twin lost a first-echo record and reported a bogus one); the next pair reads it
    whole. EVT_HI alone (the firmware's drain loop) still answers and pops the live head."""
    bus = await setup(dut)
    queue: list[int] = []
    pops = 0

    async def fifo_model():
        nonlocal pops
        pop_seen = False
        while True:
            await FallingEdge(dut.clk_i)
            if pop_seen:
                assert queue, "pop with an empty FIFO"
                queue.pop(0)
                pops += 1
            dut.evt_rvalid_i.value = int(bool(queue))
            dut.evt_rdata_i.value = queue[0] if queue else 0
            await Timer(1, "ns")
            pop_seen = bool(int(dut.evt_pop_o.value))

    cocotb.start_soon(fifo_model())
    await ClockCycles(dut.clk_i, 2)
    hi = R.REGISTERS["EVT_HI"].fields
    rng = random.Random(5)
    for trial in range(6):
        ev = rng.getrandbits(45) | (rng.getrandbits(8) << 24)  # low word never 0
        assert await bus.read(R.EVT_LO_ADDR) == 0, "empty FIFO"
        queue.append(ev)  # the core writes an event between the two reads
        await ClockCycles(dut.clk_i, 1 + trial)
        h = await bus.read(R.EVT_HI_ADDR)
        assert h == 0 and pops == trial, f"EVT_HI answered 0x{h:X} (pops {pops}) for an EVT_LO of an empty FIFO"
        lo = await bus.read(R.EVT_LO_ADDR)
        h = await bus.read(R.EVT_HI_ADDR)
        assert hi["VALID"].get(h) and ((hi["DATA"].get(h) << 32) | lo) == ev
        await ClockCycles(dut.clk_i, 2)
        assert pops == trial + 1 and not queue
    # the drain loop: EVT_HI reads with no EVT_LO before them pop the live head
    queue.extend([rng.getrandbits(45) for _ in range(3)])
    await ClockCycles(dut.clk_i, 2)
    n = 0
    while hi["VALID"].get(await bus.read(R.EVT_HI_ADDR)):
        n += 1
    assert n == 3 and pops == 6 + 3 and not queue


@cocotb.test()
async def vs_table_gaps_do_not_alias(dut):
    """Writes to the unmapped addresses around the VS table (the 0x24..0x3F tail of each
    entry's 0x40 stride, 0x0E0..0x0FC before it, 0x300..0x3FC after it) answer wr_err and
    leave every entry unchanged; a write to one entry changes that entry only. (ms_csr decodes
    the VS entry from the address bits itself, not from the regblock's per-entry range compare.)"""
    bus = await setup(dut)
    n_vs = R.REGISTERS["VS_PHASE"].dims[0]
    phase = R.REGISTERS["VS_PHASE"]
    mask = writable_mask(phase)
    vs_regs = [r for r in R.REGISTERS.values() if r.name.startswith("VS_")]

    async def table() -> list[int]:
        return [await bus.read(r.addr(v)) for r in vs_regs for v in range(n_vs)]

    before = await table()
    vs_base = R.REGISTERS["VS_TX_MASK"].addr(0)
    stride = R.REGISTERS["VS_TX_MASK"].addr(1) - vs_base
    gaps = [vs_base - 4, vs_base + n_vs * stride, 0x3FC]
    gaps += [vs_base + v * stride + off for v in range(n_vs) for off in (0x24, 0x28, 0x3C)]
    for addr in gaps:
        r = await bus.write_raw(addr, 0xFFFF_FFFF)
        assert r.error, f"write to unmapped 0x{addr:X} must answer wr_err"
    assert await table() == before
    for v in range(n_vs):
        await bus.write(phase.addr(v), (0x10101 * (v + 1)) & mask)
    assert [await bus.read(phase.addr(v)) for v in range(n_vs)] == [(0x10101 * (v + 1)) & mask for v in range(n_vs)]


@cocotb.test()
async def back_to_back_requests_keep_order(dut):
    """A read and a write presented in consecutive clocks (the master does not wait for the
    read's answer): the regblock stalls the write (read latency > write latency; the VS
    table is external, so also until the read's answer), the bus slice holds it and stalls
    the master's next request, and all complete in order with the right data: the read
    right after the write sees the written value."""
    bus = await setup(dut)
    reg = R.REGISTERS["VS_WINDOW"]
    addr = reg.addr(3)
    old = await bus.read(addr)
    new = 0x1234_5678 & writable_mask(reg)
    reqs = [(False, addr, 0), (True, addr, new), (False, addr, 0)]
    acks: list[tuple[str, int]] = []

    async def collect():
        while len(acks) < len(reqs):
            await FallingEdge(dut.clk_i)
            if int(dut.bus_rd_ack_o.value):
                acks.append(("r", int(dut.bus_rd_data_o.value)))
            if int(dut.bus_wr_ack_o.value):
                acks.append(("w", 0))
            assert not int(dut.bus_rd_err_o.value) and not int(dut.bus_wr_err_o.value)

    collector = cocotb.start_soon(collect())
    stalled = 0
    for is_wr, a, d in reqs:
        await FallingEdge(dut.clk_i)
        dut.bus_req_i.value = 1
        dut.bus_req_is_wr_i.value = int(is_wr)
        dut.bus_addr_i.value = a
        dut.bus_wr_data_i.value = d
        dut.bus_wr_biten_i.value = 0xFFFF_FFFF
        while int((dut.bus_req_stall_wr_o if is_wr else dut.bus_req_stall_rd_o).value):
            stalled += 1
            await FallingEdge(dut.clk_i)
            assert stalled < 16, "master stalled too long"
    await FallingEdge(dut.clk_i)
    dut.bus_req_i.value = 0
    for _ in range(32):
        if collector.done():
            break
        await FallingEdge(dut.clk_i)
    assert collector.done(), f"answers {acks} of {len(reqs)} requests"
    assert acks == [("r", old), ("w", 0), ("r", new)], acks
    assert stalled >= 1, "the write after a read should have been stalled once"


@cocotb.test()
async def vs_table_refilled_after_reset(dut):
    """A reset refills the VS table with its reset values, one word per clock, with the bus
    stalled meanwhile: a value written before the reset is gone, also for the last word
    refilled (a read issued right after the reset waits for it)."""
    bus = await setup(dut)
    reg = R.REGISTERS["VS_PHASE"]
    last = min(reg.dims[0], CSR_NUM_VS) - 1  # the last entry's PHASE: the last word refilled (71 of 72)
    await bus.write(reg.addr(last), 0x123456)
    assert await bus.read(reg.addr(last)) == 0x123456
    await reset(dut.clk_i, dut.rst_i)
    patient = PassthroughMaster(dut, dut.clk_i, timeout_cycles=2 * VS_WORDS)
    assert await patient.read(reg.addr(last)) == reg.reset


@cocotb.test()
async def caps_and_implemented_entries(dut):
    """CAPS reports the build's parameters (num_ch, num_vs, win_slots, fifo depth); VS entries
    from num_vs on (a reduced build, the 25F's 4) read as zero and ignore writes, the others
    keep what the bus wrote."""
    bus = await setup(dut)
    f = R.REGISTERS["CAPS"].fields
    caps = await bus.read(R.CAPS_ADDR)
    assert (f["NUM_CH"].get(caps), f["NUM_VS"].get(caps), f["WIN_SLOTS"].get(caps), f["FIFO_DEPTH_LOG2"].get(caps)) \
        == (load_layout().n, CSR_NUM_VS, CSR_WSLOTS, 9), hex(caps)
    n_map = R.REGISTERS["VS_PHASE"].dims[0]
    phase, window = R.REGISTERS["VS_PHASE"], R.REGISTERS["VS_WINDOW"]
    for v in range(n_map):
        await bus.write(phase.addr(v), 0x1000 + v)
        await bus.write(window.addr(v), 0x0002_0003 + (v << 4))
    for v in range(n_map):
        got = (await bus.read(phase.addr(v)), await bus.read(window.addr(v)))
        if v < CSR_NUM_VS:
            assert got == (0x1000 + v, 0x0002_0003 + (v << 4)), (v, got)
        else:
            assert got == (0, 0), f"entry {v} is not implemented (num_vs {CSR_NUM_VS}) but reads {got}"
