"""cocotb tests of ms_sched_div (the scheduler engine's divider unit) against its contract and
its model, multisonar.tools.sched_program.DivUnit: floor(x / n), n = 0 as 1, the quotient
ready within DIV_LATENCY clocks of the start, a start while busy restarting."""

from __future__ import annotations

import random

import cocotb
from cocotb.triggers import FallingEdge

from multisonar.tools.sched_program import DIV_LATENCY, DIV_N, DIV_X, DivUnit
from tbutil import start_and_reset


async def divide(dut, x: int, n: int) -> tuple[int, int]:
    """Start a division at a falling edge; return (quotient, clocks until busy fell)."""
    await FallingEdge(dut.clk_i)
    dut.x_i.value, dut.n_i.value, dut.start_i.value = x, n, 1
    await FallingEdge(dut.clk_i)
    dut.start_i.value = 0
    clocks = 1
    while int(dut.busy_o.value):
        await FallingEdge(dut.clk_i)
        clocks += 1
        assert clocks <= DIV_LATENCY, f"{x} / {n}: still busy after {DIV_LATENCY} clocks"
    return int(dut.q_o.value), clocks


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def quotients_equal_the_model(dut):
    """Edge and random dividends (24 bits) by every divisor 0..15: the model's quotient."""
    await start_and_reset(dut.clk_i, dut.rst_i, dut.start_i, dut.x_i, dut.n_i)
    rng = random.Random(11)
    model = DivUnit()
    xs = [0, 1, 2, 7, 8, 15, (1 << 24) - 1, 1 << 23, 48_000, 123_456]
    for n in range(16):
        for x in xs + [rng.getrandbits(24) for _ in range(20)]:
            q, clocks = await divide(dut, x, n)
            model.write(0, DIV_X, x)
            model.write(0, DIV_N, n)
            assert q == model.read(DIV_LATENCY) == x // max(n, 1), f"{x} / {n}: {q}"
            assert clocks == 25


@cocotb.test(timeout_time=5, timeout_unit="ms")
async def a_start_while_busy_restarts(dut):
    """A second start in the middle of a division gives the second quotient, on time."""
    await start_and_reset(dut.clk_i, dut.rst_i, dut.start_i, dut.x_i, dut.n_i)
    dut.x_i.value, dut.n_i.value, dut.start_i.value = 1_000_000, 3, 1
    await FallingEdge(dut.clk_i)
    dut.start_i.value = 0
    for _ in range(10):
        await FallingEdge(dut.clk_i)
    q, clocks = await divide(dut, 999_999, 7)
    assert (q, clocks) == (999_999 // 7, 25)
