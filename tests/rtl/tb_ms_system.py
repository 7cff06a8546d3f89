"""cocotb smoke test of ms_system running firmware/app/system_smoke.c.

The firmware reads the sonar core's identification registers through the SoC's sonar port
(CPU address 0x1000_0000), writes BURST and reads it back, and pushes every word to the host
FIFO (and the SIM_OUT mailbox). The expected words come from the generated register
constants, not from the firmware.
"""

from __future__ import annotations

import cocotb
from cocotb.triggers import ClockCycles, FallingEdge, First, RisingEdge, Timer

from multisonar.generated import sonar_regs as R
from tbutil import reset, start_clock

START, DONE = 0x5157E000, 0x5157E0FF


def _reset_value(reg: str) -> int:
    """The reset value of register `reg` from the generated register map."""
    return R.REGISTERS[reg].reset


@cocotb.test(timeout_time=2, timeout_unit="ms")
async def firmware_reads_sonar_id_through_system(dut):
    start_clock(dut.clk_i)
    dut.host_rd_i.value = 0
    dut.echo_i.value = 0
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
    # the same words wait in the host FIFO (the USB side's source), in order, no drop flag
    assert int(dut.led_o.value) & (1 << 6), "LED 6 (host word waiting) is off"
    got = []
    for _ in range(3 * len(expect)):
        await FallingEdge(dut.clk_i)
        valid = int(dut.host_rvalid_o.value)
        if valid:
            got.append(int(dut.host_rdata_o.value))
        dut.host_rd_i.value = valid
    dut.host_rd_i.value = 0
    assert [hex(w) for w in got] == [hex(w) for w in expect]
    await ClockCycles(dut.clk_i, 2)
    led = int(dut.led_o.value)
    assert led & 0b110 == 0b010, f"LEDs: expected CPU running and no trap, got {led:08b}"
    assert not led & (1 << 6), "LED 6 still on after the host FIFO was drained"
    assert not int(dut.drive_o.value), "a transducer fired although the firmware never enabled the sonar"
