"""cocotb test of the soft-core SoC running real firmware (firmware/app/soc_selftest.c).

Python wakes only on mailbox writes (SIM_OUT) and at the end; the CPU runs in the simulator.
"""

from __future__ import annotations

import cocotb
from cocotb.triggers import ClockCycles, First, FallingEdge, RisingEdge, Timer

from multisonar import TICK_HZ
from tbutil import CLK_PERIOD_PS, reset, start_clock

HELLO, HANG, BACK, DONE = 0x5E1F0000, 0xDEAD0001, 0xA1160000, 0x00000D0E


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def firmware_selftest_and_watchdog(dut):
    start_clock(dut.clk_i)
    dut.host_rd_i.value = 0
    await reset(dut.clk_i, dut.rst_i)
    words: list[int] = []

    async def mailbox():
        while True:
            await RisingEdge(dut.sim_out_strobe_o)
            words.append(int(dut.sim_out_o.value))

    cocotb.start_soon(mailbox())
    for _ in range(2000):
        await First(RisingEdge(dut.sim_out_strobe_o), RisingEdge(dut.trap_o), Timer(200, "us"))
        await Timer(1, "ns")
        assert not int(dut.trap_o.value), f"CPU trapped; mailbox so far {[hex(w) for w in words]}"
        if words and words[-1] == DONE:
            break
    cycles = round(cocotb.utils.get_sim_time("ps") / CLK_PERIOD_PS)
    a = 123456789
    expect = [HELLO | 0, int.from_bytes(b"MSNR", "big"), TICK_HZ, (a * 7) & 0xFFFFFFFF, a // 1000, a % 1000,
              (-(77777 // 7)) & 0xFFFFFFFF, 1, 5, HANG, HELLO | 1, BACK | 1, DONE]
    assert [hex(w) for w in words] == [hex(w) for w in expect]
    assert not int(dut.bus_err_o.value)
    # the host FIFO holds the five words the first boot wrote, in order, no overflow flag
    got = []
    for _ in range(40):
        await FallingEdge(dut.clk_i)
        valid = int(dut.host_rvalid_o.value)
        if valid:
            got.append(int(dut.host_rdata_o.value))
        dut.host_rd_i.value = valid
    dut.host_rd_i.value = 0
    assert got == [0xC0DE0000 + i for i in range(5)]
    dut._log.info("firmware self-test and watchdog recovery in %d cycles", cycles)
    await ClockCycles(dut.clk_i, 2)
