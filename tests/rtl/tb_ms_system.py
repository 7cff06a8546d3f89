"""cocotb smoke test of ms_system running firmware/app/system_smoke.c.

The firmware reads the sonar core's identification registers through the SoC's sonar port
(CPU address 0x1000_0000), writes BURST and reads it back, and reports every word to the
SIM_OUT mailbox and, as the payload of one frame packet, to the host link (bulk IN byte
stream, CRC-32 appended by the link). The expected words come from the generated register
constants, not from the firmware.
"""

from __future__ import annotations

import struct

import cocotb
from cocotb.triggers import ClockCycles, First, RisingEdge, Timer

from link_reader import LinkReader
from multisonar import protocol as P
from multisonar.generated import sonar_regs as R
from tbutil import reset, start_clock

START, DONE = 0x5157E000, 0x5157E0FF


def _reset_value(reg: str) -> int:
    """The reset value of register `reg` from the generated register map."""
    return R.REGISTERS[reg].reset


@cocotb.test(timeout_time=2, timeout_unit="ms")
async def firmware_reads_sonar_id_through_system(dut):
    start_clock(dut.clk_i)
    dut.echo_i.value = 0
    for name in ("cmd_valid_i", "cmd_data_i", "cmd_end_i", "cmd_zlp_i"):
        getattr(dut, name).value = 0
    link = LinkReader(dut)
    link.start()
    await reset(dut.clk_i, dut.rst_i)
    words: list[int] = []
    for _ in range(50):
        await First(RisingEdge(dut.sim_out_strobe_o), RisingEdge(dut.trap_o), Timer(100, "us"))
        await Timer(1, "ns")
        assert not int(dut.trap_o.value), f"CPU trapped; mailbox so far {[hex(w) for w in words]}"
        if int(dut.sim_out_strobe_o.value):
            words.append(int(dut.sim_out_o.value))
        if words and words[-1] == DONE:
            break
    burst_written = (_reset_value("BURST") & 0xFFFF0000) | 0x0123
    expect = [START, _reset_value("ID"), _reset_value("VERSION"), _reset_value("CAPS"), burst_written, DONE]
    assert [hex(w) for w in words] == [hex(w) for w in expect]
    assert int.to_bytes(words[1], 4, "big") == b"MSNR"
    assert not int(dut.bus_err_o.value), "a bus access failed"
    # the same words went to the host link as one frame packet (one bulk IN transfer)
    await ClockCycles(dut.clk_i, 200)
    link.stop()
    sp = P.StreamParser()
    packets = sp.feed(link.data)
    assert len(link.transfers) == 1 and len(packets) == 1 and sp.bad_crc == 0, (link.transfers, sp)
    got = list(struct.unpack(f"<{len(expect)}I", packets[0].payload))
    assert [hex(w) for w in got] == [hex(w) for w in expect]
    led = int(dut.led_o.value)
    assert led & 0b110 == 0b010, f"LEDs: expected CPU running and no trap, got {led:08b}"
    assert not led & (1 << 6), "LED 6 still on after the host link was drained"
    assert not int(dut.drive_o.value), "a transducer fired although the firmware never enabled the sonar"
