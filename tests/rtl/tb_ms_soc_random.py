"""cocotb bench of the random-input geometry benchmark (firmware/app/bench_fix_random.c) on the SoC.

The CPU runs in the simulator with the clock in C; Python wakes only on mailbox writes
(SIM_OUT): a progress word every 10,000 fixes (logged with the simulation speed), then the
report, whose second word is its length. Writes {words, progress, sim_cycles, sim_wall_s} as
JSON to $RANDOM_OUT for the caller (tests/rtl/test_ms_soc_random.py decode_report).
$RANDOM_MAX_CYCLES caps the run (a hung CPU fails); a trap or a bus error fails at once.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import cocotb
from cocotb.triggers import ClockCycles, FallingEdge, First, RisingEdge, Timer

from tbutil import CLK_PERIOD_PS, reset

RPT_PROGRESS_TAG = 0xA  # bits 31:28 of a progress word: fixes done in bits 27:0
RPT_MAGIC = 0x52460002


@cocotb.test()
async def random_geometry_firmware(dut):
    out = Path(os.environ["RANDOM_OUT"])
    max_cycles = int(os.environ.get("RANDOM_MAX_CYCLES", "4000000000"))
    await FallingEdge(dut.clk_i)  # the wrapper's own clock
    dut.host_rd_i.value = 0
    await reset(dut.clk_i, dut.rst_i)
    words: list[int] = []
    progress: list[tuple[int, int, float]] = []  # (fixes done, cycles, wall s)
    t_start = cocotb.utils.get_sim_time("ps")
    wall0 = time.perf_counter()
    strobe = RisingEdge(dut.sim_out_strobe_o)
    cycles = 0
    while True:
        fired = await First(strobe, RisingEdge(dut.trap_o), Timer(10, "ms"))
        await Timer(1, "ns")
        cycles = round((cocotb.utils.get_sim_time("ps") - t_start) / CLK_PERIOD_PS)
        if fired is strobe:
            w = int(dut.sim_out_o.value)
            if not words and w >> 28 == RPT_PROGRESS_TAG:
                wall = time.perf_counter() - wall0
                progress.append((w & 0x0FFFFFFF, cycles, wall))
                dut._log.info("%d fixes, %d cycles, %.0f s, %.0f cycles/s", w & 0x0FFFFFFF, cycles, wall,
                              cycles / max(wall, 1e-9))
            else:
                assert words or w == RPT_MAGIC, f"unexpected mailbox word {w:#010x} before the report"
                words.append(w)
        assert not int(dut.trap_o.value), f"CPU trapped after {len(words)} report words"
        assert not int(dut.bus_err_o.value), f"bus error after {len(words)} report words"
        if len(words) >= 2 and len(words) >= words[1]:
            break
        assert cycles < max_cycles, f"no end after {cycles} cycles ({len(progress)} progress, {len(words)} report words)"
    wall = time.perf_counter() - wall0
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"words": words, "progress": progress, "sim_cycles": cycles, "sim_wall_s": wall}))
    dut._log.info("random geometry benchmark: %d report words in %d cycles, %.1f s (%.0f cycles/s)",
                  len(words), cycles, wall, cycles / max(wall, 1e-9))
    await ClockCycles(dut.clk_i, 2)
