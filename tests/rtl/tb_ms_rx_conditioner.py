"""cocotb tests of ms_rx_conditioner against a tick-exact Python model.

The comparator input is driven a quarter clock after a rising edge and changes only at
segment boundaries (Python wakes per change, not per clock); rise_o strobes are collected
by awaiting their own edges. The model applies the module's documented contract, so any
difference in latency, glitch rejection or strobe count fails the test.
"""

from __future__ import annotations

import os
import random

import cocotb
from cocotb.triggers import RisingEdge, Timer
from cocotb.utils import get_sim_time

from tbutil import CLK_PERIOD_PS, reset, start_clock


def model_rises(echo: list[int], need: int) -> list[int]:
    """Edges (indices into echo) after which rise_o is high, per the module's contract."""
    meta = sync = level = run = 0
    rises = []
    for k, x in enumerate(echo):
        n_meta, n_sync, n_level, n_run, rise = x, meta, level, run, 0
        if sync == level:
            n_run = 0
        elif run + 1 >= need:
            n_level, rise, n_run = sync, sync, 0
        else:
            n_run = run + 1
        meta, sync, level, run = n_meta, n_sync, n_level, n_run
        if rise:
            rises.append(k)
    return rises


def edge_now() -> int:
    return round(get_sim_time("ps") / CLK_PERIOD_PS)


async def check_random_pulses(dut, glitch_min: int, segments: int, seed: int) -> None:
    start_clock(dut.clk_i)
    dut.echo_i.value = 0
    dut.glitch_min_i.value = glitch_min
    await reset(dut.clk_i, dut.rst_i)
    need = max(glitch_min, 1)
    rng = random.Random(seed)

    seen: list[int] = []

    async def collect():
        while True:
            await RisingEdge(dut.rise_o)
            seen.append(edge_now())

    cocotb.start_soon(collect())
    await RisingEdge(dut.clk_i)
    k0 = edge_now()
    await Timer(CLK_PERIOD_PS // 4, unit="ps")
    echo_by_edge: list[int] = []
    level = 0
    for _ in range(segments):
        level ^= 1
        # widths around the threshold exercise the accept/reject boundary; long ones too
        width = rng.choice([rng.randint(1, need + 2), rng.randint(1, 4 * need + 4)])
        dut.echo_i.value = level
        echo_by_edge += [level] * width  # sampled at the next `width` rising edges
        await Timer(width * CLK_PERIOD_PS, unit="ps")
    dut.echo_i.value = 0
    echo_by_edge += [0] * (need + 8)
    await Timer((need + 8) * CLK_PERIOD_PS, unit="ps")

    expect = [k0 + 1 + k for k in model_rises(echo_by_edge, need)]
    assert seen == expect, (f"glitch_min={glitch_min}: {len(seen)} rises, model {len(expect)}; "
                            f"first difference near {next((a, b) for a, b in zip(seen + [None], expect + [None]) if a != b)}")
    assert len(expect) > segments // 8, "stimulus produced too few accepted pulses to be a test"
    dut._log.info("glitch_min=%d: %d pulses accepted of %d driven, all on the model's tick",
                  glitch_min, len(seen), (segments + 1) // 2)


SEGMENTS = int(os.environ.get("RX_SEGMENTS", "4000"))


@cocotb.test()
async def no_filter(dut):
    await check_random_pulses(dut, 0, SEGMENTS, seed=1)


@cocotb.test()
async def filter_one_tick(dut):
    await check_random_pulses(dut, 1, SEGMENTS, seed=2)


@cocotb.test()
async def filter_five_ticks(dut):
    await check_random_pulses(dut, 5, SEGMENTS, seed=3)


@cocotb.test()
async def filter_half_microsecond(dut):
    await check_random_pulses(dut, 24, SEGMENTS // 4, seed=4)
