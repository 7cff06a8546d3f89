"""cocotb tests of ms_sched_slot (the scheduler engine's slot unit) against its model,
multisonar.tools.sched_program.SlotUnit: every mode on random elements (random valid slots,
windows before, around and after the candidate's intervals, several sensors), the results and
the clock busy falls equal to the model's; a go while busy restarts."""

from __future__ import annotations

import random

import cocotb
from cocotb.triggers import FallingEdge

from multisonar.tools.sched_program import (SU_CONF, SU_EDGE, SU_FLAGS, SU_GO, SU_HEAD, SU_MINC,
                                            SU_SENSOR, SU_TA, SU_TB, SU_TWA, SU_TWB, SU_VALID,
                                            SU_X, WSLOTS, Slot, SlotUnit)
from tbutil import start_and_reset

NUM_CH = 24
MODES = (SU_CONF, SU_EDGE, SU_HEAD, SU_SENSOR)


async def load(dut, unit: SlotUnit, rng: random.Random, base: int, latm1: int) -> None:
    """Random windows in every slot of every element, near tick ``base`` (the model's slots and
    the RAM's)."""
    await FallingEdge(dut.clk_i)   # inputs change between rising edges
    dut.wr_en_i.value = 1
    for e in range(NUM_CH):
        t = base + rng.randrange(-400_000, 400_000)
        for k in range(WSLOTS):
            t0 = (t + rng.randrange(-300_000, 300_000)) & 0xFFFF_FFFF
            ws = rng.randrange(0, 200_000)
            we = ws + rng.randrange(1, 100_000)
            s = rng.randrange(8)
            unit.slots[e * WSLOTS + k] = Slot(t0 + ws, t0 + we, t0 + we + latm1, s)
            dut.wr_addr_i.value = e * WSLOTS + k
            dut.wr_t0_i.value, dut.wr_we_i.value, dut.wr_len_i.value = t0, we, we - ws
            dut.wr_sensor_i.value = s
            await FallingEdge(dut.clk_i)
    dut.wr_en_i.value = 0


async def scan(dut, unit: SlotUnit, mode: int, e: int, bon: int, won: int, valid: int,
               ta: int, tb: int, twa: int, twb: int) -> None:
    """One scan on the RTL and the model: equal results, busy falling in the model's clock."""
    m = lambda v: v & 0xFFFF_FFFF  # noqa: E731
    for addr, v in ((SU_TA, ta), (SU_TB, tb), (SU_TWA, twa), (SU_TWB, twb), (SU_VALID, valid)):
        unit.write(0, addr, m(v))
    unit.write(0, SU_GO, e | bon << 8 | won << 9 | mode)
    dut.mode_i.value, dut.el_i.value = mode >> 10, e
    dut.bon_i.value, dut.won_i.value, dut.valid_i.value = bon, won, valid
    dut.ta_i.value, dut.tb_i.value, dut.twa_i.value, dut.twb_i.value = m(ta), m(tb), m(twa), m(twb)
    dut.go_i.value = 1
    await FallingEdge(dut.clk_i)
    dut.go_i.value = 0
    clocks = 1
    while int(dut.busy_o.value):
        assert int(dut.flags_o.value) == 0x80 and unit.read(clocks, SU_FLAGS) == 0x80, f"clock {clocks}"
        await FallingEdge(dut.clk_i)
        clocks += 1
        assert clocks <= WSLOTS + 5
    what = f"mode {mode >> 10} element {e} valid {valid:#06x} ta {m(ta)}"
    assert clocks == unit.done_at, f"{what}: busy fell after {clocks} clocks, the model's {unit.done_at}"
    got = (int(dut.x_o.value), int(dut.flags_o.value), int(dut.minc_o.value))
    want = tuple(unit.read(clocks, a) for a in (SU_X, SU_FLAGS, SU_MINC))
    assert got == want, f"{what}: RTL {got}, model {want}"


@cocotb.test(timeout_time=200, timeout_unit="ms")
async def every_mode_equals_the_model(dut):
    await start_and_reset(dut.clk_i, dut.rst_i, dut.go_i, dut.wr_en_i)
    dut.latm1_i.value = latm1 = 7
    rng = random.Random(5)
    for base in (1 << 24, 0xFFFF_0000, 0x7FFF_0000):   # ticks near the wraps too
        unit = SlotUnit()
        await load(dut, unit, rng, base, latm1)
        for i in range(150):
            e = rng.randrange(NUM_CH)
            mode = MODES[i % 4]
            valid = rng.choice([0, (1 << WSLOTS) - 1, rng.getrandbits(WSLOTS), 1 << rng.randrange(WSLOTS)])
            slot = unit.slots[e * WSLOTS + rng.randrange(WSLOTS)]
            ta = rng.choice([slot.start, slot.end, slot.end - 1, slot.start - 1, base + rng.randrange(-500_000, 500_000)])
            if mode == SU_SENSOR:
                ta = rng.randrange(8)
            tb, twa = ta + rng.randrange(1, 200_000), ta + rng.randrange(-50_000, 300_000)
            twb = twa + rng.randrange(1, 100_000)
            await scan(dut, unit, mode, e, rng.randrange(2), rng.randrange(2), valid, ta, tb, twa, twb)


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def a_go_while_busy_restarts(dut):
    await start_and_reset(dut.clk_i, dut.rst_i, dut.go_i, dut.wr_en_i)
    dut.latm1_i.value = 7
    unit = SlotUnit()
    await load(dut, unit, random.Random(9), 1 << 24, 7)
    dut.mode_i.value, dut.el_i.value, dut.valid_i.value, dut.go_i.value = 0, 3, (1 << WSLOTS) - 1, 1
    await FallingEdge(dut.clk_i)
    dut.go_i.value = 0
    for _ in range(5):
        await FallingEdge(dut.clk_i)
    await scan(dut, unit, SU_HEAD, 5, 0, 0, 0x00F0, 1 << 24, 0, 0, 0)
