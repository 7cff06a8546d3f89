"""cocotb test of the soft-core SoC running real firmware (firmware/app/soc_selftest.c).

Python wakes only on mailbox writes (SIM_OUT) and at the end; the CPU runs in the simulator.
"""

from __future__ import annotations

import struct

import cocotb

from cocotb.triggers import ClockCycles, FallingEdge, First, RisingEdge, Timer

from link_reader import LinkReader
from multisonar import TICK_HZ
from multisonar import protocol as P
from tbutil import CLK_PERIOD_PS, reset

HELLO, HANG, BACK, DONE = 0x5E1F0000, 0xDEAD0001, 0xA1160000, 0x00000D0E
WAIT, WAIT_EVT = 0x3A170000, 0x3A17E000  # | why << 8 | took as long as it should
WAKE_TIMER, WAKE_EVT = 1, 2              # WAIT's reasons (soc_regs.rdl)


@cocotb.test(timeout_time=20, timeout_unit="ms")
async def firmware_selftest_and_watchdog(dut):
    await FallingEdge(dut.clk_i)  # the wrapper's own clock
    link = LinkReader(dut)
    link.start()
    dut.wake_evt_i.value = 0
    await reset(dut.clk_i, dut.rst_i)
    words: list[int] = []

    async def mailbox():
        while True:
            await RisingEdge(dut.sim_out_strobe_o)
            words.append(int(dut.sim_out_o.value))
            if words[-1] == WAIT_EVT:  # the firmware waits next: an event ends it
                await ClockCycles(dut.clk_i, 500)
                dut.wake_evt_i.value = 1
                await RisingEdge(dut.sim_out_strobe_o)
                words.append(int(dut.sim_out_o.value))
                dut.wake_evt_i.value = 0

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
              (-(77777 // 7)) & 0xFFFFFFFF, 1, WAIT | WAKE_TIMER << 8 | 1, WAIT | WAKE_TIMER << 8 | 1,
              WAIT_EVT, WAIT | WAKE_EVT << 8 | 1, 5, HANG, HELLO | 1, BACK | 1, DONE]
    assert [hex(w) for w in words] == [hex(w) for w in expect]
    assert not int(dut.bus_err_o.value)
    # the frame packet the first boot committed went out as one transfer with a good CRC-32
    # (appended by the host link), its payload the two words
    link.stop()
    assert len(link.transfers) == 1, link.transfers
    sp = P.StreamParser()
    packets = sp.feed(link.transfers[0])
    assert sp.bad_crc == 0 and sp.skipped_bytes == 0 and len(packets) == 1, (sp, link.transfers[0].hex())
    p = packets[0]
    assert p.is_frame and p.seq == 0 and p.payload == struct.pack("<II", 0xC0DE0000, 0xC0DE0001), p
    dut._log.info("firmware self-test and watchdog recovery in %d cycles", cycles)
    await ClockCycles(dut.clk_i, 2)
