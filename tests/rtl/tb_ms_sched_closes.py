"""cocotb test of ms_sched_closes (the scheduler's close detector) against its contract, clock
by clock: heads written with close ticks up to a few thousand ticks ahead (many 32-tick
blocks, so the block flags and the scan are exercised), rewritten and removed at random,
across the tick counter's wrap; closes_o in the clock after each close tick, nothing else."""

from __future__ import annotations

import random

import cocotb
from cocotb.triggers import FallingEdge, RisingEdge

from tbutil import start_clock

NUM_CH = 24
M32 = 0xFFFF_FFFF


@cocotb.test(timeout_time=100, timeout_unit="ms")
async def closes_at_their_ticks(dut):
    rng = random.Random(3)
    start_clock(dut.clk_i)
    tick = (1 << 32) - 20_000          # the wrap comes in the middle of the run
    dut.tick_i.value, dut.we_i.value, dut.rst_i.value = tick, 0, 1
    await RisingEdge(dut.clk_i)
    await RisingEdge(dut.clk_i)
    await FallingEdge(dut.clk_i)
    dut.rst_i.value = 0
    heads: dict[int, int] = {}         # element -> close tick (model)
    expect = 0                         # closes_o in this clock: heads closing at tick - 1
    seen = 0
    for _ in range(40_000):
        dut.tick_i.value = tick & M32
        write = rng.random() < 0.05
        if write:
            e = rng.randrange(NUM_CH)
            vld = rng.random() < 0.9
            close = (tick + rng.randrange(1, 3_000)) & M32
            dut.we_i.value, dut.el_i.value, dut.vld_i.value, dut.close_i.value = 1, e, int(vld), close
        else:
            dut.we_i.value = 0
        await RisingEdge(dut.clk_i)
        got = int(dut.closes_o.value)
        assert got == expect, f"tick {tick & M32}: closes {got:#08x}, expected {expect:#08x}"
        seen += bin(got).count("1")
        # this clock compared the heads as of its start with its tick; the write applies after
        expect = sum(1 << e for e, c in heads.items() if c == tick & M32)
        if write:
            if vld:
                heads[e] = close
            else:
                heads.pop(e, None)
        for e in [e for e, c in heads.items() if c == tick & M32]:
            del heads[e]               # a closed head is gone (the engine rewrites the element's)
        await FallingEdge(dut.clk_i)
        tick += 1
    assert seen > 200, f"only {seen} closes: the test did not exercise the detector"
