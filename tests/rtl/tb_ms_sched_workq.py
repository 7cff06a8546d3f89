"""cocotb tests of ms_sched_workq (the scheduler's per-tick work queue) against a clock-accurate
Python model of its contract: a pushed word is at head_o from the next cycle, a pop removes
the head, a push while full drops the word and raises overflow_o until reset; nothing else is
ever lost, reordered or changed.

Every test runs on each build of tests/rtl/test_ms_sched_workq.py (the scheduler's size and a
small queue); traffic patterns as in verilog-axis: balanced, idle gaps, back-pressure, bursts.
"""

from __future__ import annotations

import os
import random

import cocotb
from cocotb.triggers import FallingEdge

from tbutil import reset, start_and_reset


class QueueModel:
    """The contract: a list of stored words and the sticky overflow flag."""

    def __init__(self, depth: int) -> None:
        self.depth, self.words, self.overflow, self.dropped = depth, [], False, 0

    def clock(self, push: bool, word: int, pop: bool) -> None:
        full = len(self.words) == self.depth  # as seen before the edge: a pop does not make room
        if pop and self.words:
            self.words.pop(0)
        if push and full:
            self.overflow = True
            self.dropped += 1
        elif push:
            self.words.append(word)


def sizes(dut) -> tuple[int, int]:
    return int(os.environ.get("WQ_DEPTH", "32")), len(dut.data_i)


async def traffic(dut, cycles: int, p_push: float, p_pop: float, seed: int,
                  burst: int = 1) -> QueueModel:
    """Random push / pop with the given rates (push in bursts of ``burst`` clocks); every
    cycle's head_o, empty_o and overflow_o are compared with the model."""
    depth, width = sizes(dut)
    await start_and_reset(dut.clk_i, dut.rst_i, dut.push_i, dut.pop_i, dut.data_i)
    rng = random.Random(seed)
    model = QueueModel(depth)
    run = 0
    for cyc in range(cycles):
        await FallingEdge(dut.clk_i)
        assert int(dut.empty_o.value) == (not model.words), f"cycle {cyc}: empty_o"
        if model.words:
            assert int(dut.head_o.value) == model.words[0], (
                f"cycle {cyc}: head 0x{int(dut.head_o.value):x}, expected 0x{model.words[0]:x}")
        assert int(dut.overflow_o.value) == model.overflow, f"cycle {cyc}: overflow_o"
        if run == 0 and rng.random() < p_push:
            run = burst
        push = run > 0
        run = max(run - 1, 0)
        pop = rng.random() < p_pop
        word = rng.getrandbits(width)
        dut.push_i.value, dut.pop_i.value, dut.data_i.value = int(push), int(pop), word
        model.clock(push, word, pop)
    dut.push_i.value = 0
    dut.pop_i.value = 0
    return model


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def balanced_traffic_is_lossless(dut):
    """Pushes slower than pops: every word comes out once, in order; at the scheduler's depth
    the queue never fills (a small one may, and then drops exactly as the model does)."""
    depth, _ = sizes(dut)
    model = await traffic(dut, 4000, 0.3, 0.5, seed=1)
    assert depth < 16 or (model.dropped == 0 and not model.overflow)


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def back_pressure_fills_then_overflows(dut):
    """Pops rarer than pushes: the queue fills; each push while full is dropped and raises
    overflow_o (sticky), the stored words stay intact and ordered."""
    model = await traffic(dut, 4000, 0.7, 0.2, seed=2)
    assert model.dropped > 0, "the test must actually overflow"


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def bursts_with_idle_gaps(dut):
    """Pushes in bursts of the queue's depth with idle gaps: fill and drain around full and empty."""
    depth, _ = sizes(dut)
    await traffic(dut, 4000, 0.05, 0.6, seed=3, burst=depth)


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def push_and_pop_while_full(dut):
    """Full queue, push and pop in one clock: the head leaves and the pushed word is dropped
    (the full flag is the clock's before the pop); reset then clears overflow_o."""
    depth, width = sizes(dut)
    await start_and_reset(dut.clk_i, dut.rst_i, dut.push_i, dut.pop_i)
    mask = (1 << width) - 1
    for i in range(depth):
        await FallingEdge(dut.clk_i)
        dut.push_i.value, dut.data_i.value = 1, (i * 0x9E3779B1) & mask
    await FallingEdge(dut.clk_i)
    assert not int(dut.overflow_o.value), "exactly full is no overflow"
    dut.push_i.value, dut.pop_i.value, dut.data_i.value = 1, 1, mask
    await FallingEdge(dut.clk_i)
    dut.push_i.value, dut.pop_i.value = 0, 0
    assert int(dut.overflow_o.value), "a push while full raises overflow_o"
    got = []
    for _ in range(depth + 2):  # the head seen before each pop
        if int(dut.empty_o.value):
            break
        got.append(int(dut.head_o.value))
        dut.pop_i.value = 1
        await FallingEdge(dut.clk_i)
    dut.pop_i.value = 0
    assert got == [(i * 0x9E3779B1) & mask for i in range(1, depth)], "words 1.. survive; the dropped one never appears"
    assert int(dut.overflow_o.value), "overflow_o stays until reset"
    await reset(dut.clk_i, dut.rst_i)
    await FallingEdge(dut.clk_i)
    assert not int(dut.overflow_o.value) and int(dut.empty_o.value), "reset empties the queue and clears overflow_o"
