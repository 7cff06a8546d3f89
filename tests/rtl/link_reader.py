"""Reads the host link's bulk IN byte stream (ms_soc / ms_system host_*: a byte per clock with
host_rvalid_o and host_rd_i, host_flush_o at the end of each packet) in testbenches that have
no USB core. host_rd_i is held high (the endpoint always has room); Python wakes per clock only
while a packet is being sent, from the first byte to its flush."""

from __future__ import annotations

import cocotb
from cocotb.triggers import FallingEdge, RisingEdge


class LinkReader:
    def __init__(self, dut) -> None:
        self.dut = dut
        self.transfers: list[bytes] = []  # one per flush: what the USB core would send as one transfer
        self.task = None

    def start(self) -> None:
        self.dut.host_rd_i.value = 1
        self.task = cocotb.start_soon(self._run())

    def stop(self) -> None:
        if self.task is not None and not self.task.done():
            self.task.cancel()

    @property
    def data(self) -> bytes:
        return b"".join(self.transfers)

    async def _run(self) -> None:
        d = self.dut
        while True:
            if not int(d.host_rvalid_o.value):
                await RisingEdge(d.host_rvalid_o)
            buf = bytearray()
            while True:
                await FallingEdge(d.clk_i)
                if int(d.host_rvalid_o.value):
                    buf.append(int(d.host_rdata_o.value) & 0xFF)
                if int(d.host_flush_o.value):
                    break
            self.transfers.append(bytes(buf))


async def send_command(dut, transfer: bytes) -> None:
    """Feed one bulk OUT transfer into the link's command port (cmd_*, as ms_usb_device out_*
    would: one entry per clock while cmd_ready_o, the last byte with cmd_end_i; an empty
    transfer is a zero-length-packet entry). Python wakes per clock for len(transfer) clocks."""
    entries = [(b, i == len(transfer) - 1, False) for i, b in enumerate(transfer)] or [(0, True, True)]
    i = 0
    while i < len(entries):
        await FallingEdge(dut.clk_i)
        b, end, zlp = entries[i]
        dut.cmd_valid_i.value = 1
        dut.cmd_data_i.value = b
        dut.cmd_end_i.value = int(end)
        dut.cmd_zlp_i.value = int(zlp)
        if int(dut.cmd_ready_o.value):  # registered: the entry is taken at the next rising edge
            i += 1
    await FallingEdge(dut.clk_i)
    dut.cmd_valid_i.value = 0
    dut.cmd_end_i.value = 0
    dut.cmd_zlp_i.value = 0
