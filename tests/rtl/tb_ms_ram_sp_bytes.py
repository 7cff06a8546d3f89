"""cocotb test of ms_ram_sp_bytes built from banks (WORDS not a power of two), against a list
model: every word after preload, random byte writes (also past the end, where they must change
nothing) read back."""

from __future__ import annotations

import os
import random
from pathlib import Path

import cocotb
from cocotb.triggers import RisingEdge, Timer

from tbutil import start_clock


async def _read(dut, addr: int) -> int:
    dut.addr_i.value = addr
    dut.we_i.value = 0
    await RisingEdge(dut.clk_i)  # address sampled
    await RisingEdge(dut.clk_i)  # the edge after: bank select and data registered
    await Timer(1, "ps")
    return int(dut.rdata_o.value)


@cocotb.test()
async def banked_ram_matches_model(dut):
    words = int(dut.WORDS.value)
    span = 1 << int(dut.AW.value)
    image = Path(os.environ["MS_RAM_IMAGE"]).read_bytes()
    model = [int.from_bytes(image[4 * i:4 * i + 4], "little") if 4 * i < len(image) else None
             for i in range(words)]
    start_clock(dut.clk_i)
    dut.we_i.value = 0
    dut.wdata_i.value = 0
    dut.addr_i.value = 0
    await RisingEdge(dut.clk_i)

    # preload: every word of the image, in each bank, at its address
    for a in range(words):
        got = await _read(dut, a)
        if model[a] is not None:
            assert got == model[a], f"word {a}: preload {got:#010x}, image {model[a]:#010x}"
        else:
            model[a] = got  # past the image: whatever the bank holds (bin2memh's filler or zero)

    # random byte writes across the banks and past the end, then everything read back
    rng = random.Random(3)
    for _ in range(600):
        a = rng.randrange(span)
        data, be = rng.getrandbits(32), rng.randrange(1, 16)
        dut.addr_i.value, dut.wdata_i.value, dut.we_i.value = a, data, be
        await RisingEdge(dut.clk_i)
        if a < words:
            mask = sum(0xFF << (8 * b) for b in range(4) if be >> b & 1)
            model[a] = (model[a] & ~mask) | (data & mask)
    dut.we_i.value = 0
    for a in range(words):  # writes past the end changed nothing (their reads are unspecified)
        got = await _read(dut, a)
        assert got == model[a], f"word {a}: read {got:#010x}, model {model[a]:#010x}"
