"""cocotb bench of the geometry firmware (firmware/app/bench_geom.c) on the SoC.

The CPU runs in the simulator; Python wakes only on mailbox writes (SIM_OUT) and records
every word, then writes {words, sim_cycles} as JSON to $GEOM_OUT for the caller to decode
(multisonar.tools.geom_cases.decode). $GEOM_MAX_CASES (optional) ends the run after that
many cases; $GEOM_MAX_CYCLES caps it (a hung CPU fails).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cocotb
from cocotb.triggers import ClockCycles, FallingEdge, First, RisingEdge, Timer

from multisonar.tools import geom_cases as gc
from tbutil import CLK_PERIOD_PS, reset


@cocotb.test()
async def geometry_firmware(dut):
    out = Path(os.environ["GEOM_OUT"])
    max_cycles = int(os.environ.get("GEOM_MAX_CYCLES", "1000000000"))
    max_cases = int(os.environ.get("GEOM_MAX_CASES", "0"))
    await FallingEdge(dut.clk_i)  # the wrapper's own clock
    dut.host_rd_i.value = 0
    await reset(dut.clk_i, dut.rst_i)
    words: list[int] = []
    expect = None
    t_start = cocotb.utils.get_sim_time("ps")
    strobe = RisingEdge(dut.sim_out_strobe_o)
    while True:
        fired = await First(strobe, RisingEdge(dut.trap_o), Timer(1, "ms"))
        await Timer(1, "ns")
        if fired is strobe:
            words.append(int(dut.sim_out_o.value))
            if len(words) == 2:
                variant = gc.ARITH.get(words[0] & 0xFF, "q")
                expect = gc.expected_words(variant, words[1])
                if 0 < max_cases < words[1]:
                    expect = gc.words_for_cases(variant, max_cases)
        assert not int(dut.trap_o.value), f"CPU trapped after {len(words)} mailbox words"
        assert not int(dut.bus_err_o.value), f"bus error after {len(words)} mailbox words"
        cycles = round((cocotb.utils.get_sim_time("ps") - t_start) / CLK_PERIOD_PS)
        if expect is not None and len(words) >= expect:
            break
        assert cycles < max_cycles, f"no end after {cycles} cycles ({len(words)} mailbox words)"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"words": words, "sim_cycles": cycles}))
    dut._log.info("geometry firmware: %d mailbox words in %d cycles", len(words), cycles)
    await ClockCycles(dut.clk_i, 2)
