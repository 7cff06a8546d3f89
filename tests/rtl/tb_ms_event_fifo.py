"""cocotb tests of ms_event_fifo against a clock-accurate Python model of its contract.

This testbench drives wr_i/rd_i every clock (a FIFO's behaviour *is* per-clock), so it is kept
to a few thousand clocks; the sonar-core tests exercise the FIFO at speed.
"""

from __future__ import annotations

import random

import cocotb
from cocotb.triggers import FallingEdge, RisingEdge

from tbutil import start_and_reset

OVF = 1 << 44


class FifoModel:
    """Same registers as the RTL: RAM pointers, one read in flight, a head register."""

    def __init__(self, depth: int) -> None:
        self.depth, self.ram, self.fetch, self.head, self.ovf_pending = depth, [], None, None, False
        self.dropped = 0

    def clock(self, wr: bool, word: int, rd: bool) -> None:
        full = len(self.ram) >= self.depth
        pop = rd and self.head is not None
        fetch = bool(self.ram) and self.fetch is None and (self.head is None or pop)
        arriving, self.fetch = self.fetch, (self.ram.pop(0) if fetch else None)
        if arriving is not None:
            self.head = arriving
        elif pop:
            self.head = None
        if wr and not full:
            self.ram.append(word | (OVF if self.ovf_pending else 0))
            self.ovf_pending = False
        elif wr:
            self.ovf_pending = True
            self.dropped += 1

    def level(self) -> int:
        return len(self.ram) + (self.fetch is not None) + (self.head is not None)


async def run(dut, cycles: int, p_wr: float, p_rd: float, seed: int, depth: int) -> tuple[int, int]:
    await start_and_reset(dut.clk_i, dut.rst_i, dut.wr_i, dut.rd_i, dut.wdata_i)
    rng = random.Random(seed)
    model = FifoModel(depth)
    popped = overflows = 0
    for cyc in range(cycles):
        await FallingEdge(dut.clk_i)
        # compare outputs (registered state after the previous edge)
        head = model.head
        assert int(dut.rvalid_o.value) == (head is not None), f"cycle {cyc}: rvalid"
        if head is not None:
            assert int(dut.rdata_o.value) == head, f"cycle {cyc}: head 0x{int(dut.rdata_o.value):x} != 0x{head:x}"
        assert int(dut.level_o.value) == model.level(), f"cycle {cyc}: level {int(dut.level_o.value)} != {model.level()}"
        overflows += int(dut.overflow_o.value)
        wr = rng.random() < p_wr
        rd = rng.random() < p_rd
        word = rng.getrandbits(44)
        dut.wr_i.value, dut.rd_i.value, dut.wdata_i.value = int(wr), int(rd), word
        popped += int(rd and head is not None)
        model.clock(wr, word, rd)
    await RisingEdge(dut.clk_i)
    await FallingEdge(dut.clk_i)
    overflows += int(dut.overflow_o.value)
    assert overflows == model.dropped, f"overflow strobes {overflows} != dropped {model.dropped}"
    return popped, model.dropped


DEPTH = 1 << 9


@cocotb.test(timeout_time=5, timeout_unit="ms")
async def random_traffic_never_overflows(dut):
    popped, dropped = await run(dut, 4000, 0.4, 0.6, seed=1, depth=DEPTH)
    assert dropped == 0 and popped > 1000


@cocotb.test(timeout_time=5, timeout_unit="ms")
async def overflow_counted_and_flagged(dut):
    """Writing much faster than reading fills the FIFO: every drop strobes overflow_o and the
    next stored word carries the flag; nothing stored is corrupted or reordered."""
    popped, dropped = await run(dut, 3000, 0.9, 0.15, seed=2, depth=DEPTH)
    assert dropped > 500, "the test must actually overflow"


@cocotb.test(timeout_time=5, timeout_unit="ms")
async def drain_after_overflow(dut):
    """Fill with no reads, overflow, then drain completely (the model checks every head)."""
    await start_and_reset(dut.clk_i, dut.rst_i, dut.wr_i, dut.rd_i)
    n = DEPTH + 1 + 17
    for i in range(n):
        await FallingEdge(dut.clk_i)
        dut.wr_i.value, dut.wdata_i.value = 1, i
    await FallingEdge(dut.clk_i)
    dut.wr_i.value, dut.wdata_i.value = 1, 0xABC  # stored once there is room? no: still full
    await FallingEdge(dut.clk_i)
    dut.wr_i.value = 0
    assert int(dut.level_o.value) == DEPTH + 1
    got = []
    for _ in range(4 * (DEPTH + 1)):  # pop exactly the words seen valid at a falling edge
        if len(got) == DEPTH + 1:
            break
        valid = int(dut.rvalid_o.value)
        if valid:
            got.append(int(dut.rdata_o.value))
        dut.rd_i.value = valid
        await FallingEdge(dut.clk_i)
    dut.rd_i.value = 0
    assert got == list(range(DEPTH + 1)), f"words stored before the overflow come out unchanged, in order: got {len(got)}: {got[:5]}...{got[-5:]}"
    await FallingEdge(dut.clk_i)
    dut.wr_i.value, dut.wdata_i.value = 1, 0x123
    await FallingEdge(dut.clk_i)
    dut.wr_i.value = 0
    dut.rd_i.value = 1
    for _ in range(4):
        await FallingEdge(dut.clk_i)
        if int(dut.rvalid_o.value):
            break
    assert int(dut.rdata_o.value) == 0x123 | OVF, "first word after the drops carries the overflow flag"
