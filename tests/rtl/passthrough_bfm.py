"""Bus-functional model of the PeakRDL passthrough CPU interface (master side).

Python wakes only on falling edges around a transaction, so a register access costs a few
simulator callbacks; bulk traffic belongs in RTL, not here.
"""

from __future__ import annotations

from dataclasses import dataclass

from cocotb.triggers import FallingEdge, RisingEdge


class BusError(Exception):
    """The register block answered a transaction with rd_err / wr_err."""


@dataclass
class Response:
    data: int
    error: bool


class PassthroughMaster:
    # timeout_cycles guards against a hang only: ms_csr holds a request for up to 72 clocks after
    # a reset while it refills its VS table
    def __init__(self, dut, clk, prefix: str = "bus_", timeout_cycles: int = 128) -> None:
        self.dut, self.clk, self.p, self.timeout = dut, clk, prefix, timeout_cycles
        self._sig("req_i").value = 0

    def _sig(self, name: str):
        return getattr(self.dut, self.p + name)

    async def _transact(self, is_wr: bool, addr: int, data: int = 0, biten: int = 0xFFFF_FFFF) -> Response:
        await FallingEdge(self.clk)
        self._sig("req_i").value = 1
        self._sig("req_is_wr_i").value = int(is_wr)
        self._sig("addr_i").value = addr
        self._sig("wr_data_i").value = data
        self._sig("wr_biten_i").value = biten
        stall = self._sig("req_stall_wr_o" if is_wr else "req_stall_rd_o")
        for _ in range(self.timeout):
            if not int(stall.value):
                break
            await FallingEdge(self.clk)
        else:
            raise TimeoutError(f"bus stalled for {self.timeout} clocks at address 0x{addr:X}")
        await RisingEdge(self.clk)  # request accepted on this edge
        await FallingEdge(self.clk)
        self._sig("req_i").value = 0
        ack = self._sig("wr_ack_o" if is_wr else "rd_ack_o")
        err = self._sig("wr_err_o" if is_wr else "rd_err_o")
        for _ in range(self.timeout):
            if int(ack.value):
                return Response(0 if is_wr else int(self._sig("rd_data_o").value), bool(int(err.value)))
            await FallingEdge(self.clk)
        raise TimeoutError(f"no {'write' if is_wr else 'read'} acknowledge from address 0x{addr:X}")

    async def read(self, addr: int) -> int:
        r = await self._transact(False, addr)
        if r.error:
            raise BusError(f"read error at 0x{addr:X}")
        return r.data

    async def write(self, addr: int, data: int, biten: int = 0xFFFF_FFFF) -> None:
        r = await self._transact(True, addr, data, biten)
        if r.error:
            raise BusError(f"write error at 0x{addr:X}")

    async def read_raw(self, addr: int) -> Response:
        return await self._transact(False, addr)

    async def write_raw(self, addr: int, data: int) -> Response:
        return await self._transact(True, addr, data)
