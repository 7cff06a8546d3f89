"""Wire-level USB 2.0 full-speed host model for the device-core tests (Python per packet).

Packets are encoded here (CRC, bit stuffing, NRZI, SYNC/EOP) into line symbols that the SV
module usb_host_phy_tb puts on the wire at the host's own bit clock; the device's answer comes
back as sampled line symbols and is decoded here, independently of the RTL (NRZI, unstuffing,
PID check, CRC5/CRC16). Errors in what the device sends raise UsbProtocolError.
"""

from __future__ import annotations

from dataclasses import dataclass

from cocotb.clock import Clock
from cocotb.triggers import FallingEdge, First, RisingEdge, Timer

# packet bytes (PIDs, CRC5 / CRC16, token / data packets, the host's check of a device packet)
# are shared with the full-system twin's host (multisonar.twin.usbhost)
from multisonar.usb.packets import (PID_ACK, PID_DATA0, PID_DATA1, PID_IN, PID_NAK, PID_NAMES,  # noqa: F401
                                    PID_OUT, PID_SETUP, PID_SOF, PID_STALL, UsbProtocolError, crc5, crc16,
                                    data_bytes, parse_reply, pid_byte, token_bytes)

SE0, J, K, REL = 0, 1, 2, 3

HOST_TIMEOUT_BITS = 18      # USB 2.0 7.1.19.1: the host times out 16..18 bit times after its EOP
MAX_RESPONSE_BITS = 7.5     # device response must start within 6.5 bit times (+1 for sampling)


def encode(packet: bytes, *, gap_bits: int = 2, stuff_error_at_byte: int | None = None) -> list[int]:
    """Line symbols of a packet: idle gap (bus released), SYNC, bytes LSB first with bit stuffing,
    NRZI, EOP (SE0 SE0 J). stuff_error_at_byte: the first stuffed 0 at or after that byte is sent
    as a 1 (seven 1s in a row); a receiver that silently dropped it would see the packet intact,
    so only stuff-error detection rejects it."""
    bits = [0] * 7 + [1]
    error_from = None
    for i, byte in enumerate(packet):
        if i == stuff_error_at_byte:
            error_from = len(bits)
        bits += [(byte >> b) & 1 for b in range(8)]
    out, ones, injected = [], 0, False
    for i, b in enumerate(bits):
        out.append(b)
        ones = ones + 1 if b else 0
        if ones == 6:
            bad = error_from is not None and i >= error_from and not injected
            out.append(1 if bad else 0)
            injected |= bad
            ones = 0
    if error_from is not None and not injected:
        raise ValueError("no stuffed bit at or after that byte: put six 1s in the payload")
    syms, level = [REL] * gap_bits, J
    for b in out:
        if b == 0:
            level = K if level == J else J
        syms.append(level)
    return syms + [SE0, SE0, J]


def decode(syms: list[int]) -> bytes:
    """Bytes (PID first, CRC bytes included) of one packet recorded from the wire."""
    if not syms:
        raise UsbProtocolError("no packet")
    bits, prev, i = [], J, 0
    while i < len(syms) and syms[i] in (J, K):
        bits.append(1 if syms[i] == prev else 0)
        prev = syms[i]
        i += 1
    if i >= len(syms) or syms[i] != SE0:
        raise UsbProtocolError(f"packet without SE0 (symbols {syms[:80]}...)")
    n_se0 = 0
    while i < len(syms) and syms[i] == SE0:
        n_se0 += 1
        i += 1
    if n_se0 != 2 or i >= len(syms) or syms[i] != J:
        raise UsbProtocolError(f"bad EOP: {n_se0} SE0 bits then {syms[i:i + 1]}")
    if bits[:8] != [0] * 7 + [1]:
        raise UsbProtocolError(f"bad SYNC {bits[:8]}")
    data_bits, ones = [], 1
    for b in bits[8:]:
        if ones == 6:
            if b != 0:
                raise UsbProtocolError("bit-stuff violation in device packet")
            ones = 0
            continue
        data_bits.append(b)
        ones = ones + 1 if b else 0
    if len(data_bits) % 8:
        raise UsbProtocolError(f"{len(data_bits)} bits is not a whole number of bytes")
    return bytes(sum(data_bits[8 * k + j] << j for j in range(8)) for k in range(len(data_bits) // 8))


@dataclass
class Reply:
    pid: int | None                # None: no answer (host timeout)
    payload: bytes = b""
    delay_bits: float = 0.0        # bus release to the first SYNC bit, in bit times

    @property
    def name(self) -> str:
        return "TIMEOUT" if self.pid is None else PID_NAMES.get(self.pid, hex(self.pid))


class UsbHost:
    """Drives usb_device_tb: one call per packet or transaction.

    Wire level (default): packets cross D+/D- through usb_host_phy_tb at the host's own clock
    (48 MHz * (1 + clock_error)). Transaction level (tl=True): the same packet bytes go through
    the device's wire-less port (ms_usb_device tl_*) via usb_tl_host_tb; everything above
    (transactions, control transfers) is shared.
    """

    def __init__(self, dut, clock_error: float = 0.0, dev_period_ps: int = 20834, tl: bool = False) -> None:
        self.dut = dut
        self.tl = tl
        self.nsym = len(dut.tx_syms_i) // 2
        period = int(round(dev_period_ps / (1.0 + clock_error) / 2)) * 2
        self.hclk_period_ps = period
        self.clock = Clock(dut.hclk_i, period, unit="ps", impl="gpi")
        if not tl:
            self.clock.start()
        dut.go_i.value = 0
        dut.tx_nsym_i.value = 0
        dut.listen_i.value = 0
        dut.skew_i.value = 0
        dut.tl_en_i.value = int(tl)
        dut.tl_bus_reset_i.value = 0
        dut.tl_go_i.value = 0
        dut.tl_tx_len_i.value = 0
        dut.tl_listen_i.value = 0
        self.packets = 0
        self.max_delay_bits = 0.0
        self.last_delay_bits = 0.0

    def stop(self) -> None:
        if not self.tl:
            self.clock.stop()

    async def tl_packet(self, packet: bytes, listen_clocks: int) -> bytes:
        """Transaction level: hand one packet to the device, return its answer (b'' if none)."""
        d = self.dut
        if len(packet) > len(d.tl_tx_bytes_i) // 8:
            raise ValueError(f"packet of {len(packet)} bytes > testbench buffer")
        d.tl_tx_bytes_i.value = int.from_bytes(packet, "little")
        d.tl_tx_len_i.value = len(packet)
        d.tl_listen_i.value = listen_clocks
        d.tl_go_i.value = 1
        await First(RisingEdge(d.tl_done_o), Timer(10_000_000, unit="ps"))
        if int(d.tl_done_o.value) != 1:
            raise TimeoutError("usb_tl_host_tb did not finish a packet (testbench stuck)")
        n = int(d.tl_rx_len_o.value)
        raw = int(d.tl_rx_bytes_o.value).to_bytes(len(d.tl_rx_bytes_o) // 8, "little")[:n]
        delay = int(d.tl_resp_delay_o.value)
        d.tl_go_i.value = 0
        await FallingEdge(d.tl_done_o)
        self.packets += 1
        if raw:
            self.last_delay_bits = delay / 4.0
            self.max_delay_bits = max(self.max_delay_bits, self.last_delay_bits)
        return raw

    async def wire(self, syms: list[int], listen_bits: int = 0) -> list[int]:
        """Put symbols on the wire, then optionally record the device's packet."""
        if len(syms) > self.nsym:
            raise ValueError(f"{len(syms)} symbols > testbench buffer {self.nsym}")
        d = self.dut
        d.tx_syms_i.value = sum(s << (2 * i) for i, s in enumerate(syms))
        d.tx_nsym_i.value = len(syms)
        d.listen_i.value = listen_bits
        d.go_i.value = 1
        budget_ps = (len(syms) + listen_bits + self.nsym + 64) * 4 * self.hclk_period_ps
        await First(RisingEdge(d.done_o), Timer(budget_ps, unit="ps"))
        if int(d.done_o.value) != 1:
            raise TimeoutError("usb_host_phy_tb did not finish a packet (testbench stuck)")
        n = int(d.rx_nsym_o.value)
        raw = int(d.rx_syms_o.value)
        delay = int(d.resp_delay_o.value)
        d.go_i.value = 0
        await FallingEdge(d.done_o)
        self.packets += 1
        rx = [(raw >> (2 * i)) & 3 for i in range(n)]
        if int(d.collision_o.value):
            raise UsbProtocolError("device and host drove the bus at the same time")
        if rx:
            self.last_delay_bits = delay / 4.0
            self.max_delay_bits = max(self.max_delay_bits, self.last_delay_bits)
            if self.last_delay_bits > MAX_RESPONSE_BITS:
                raise UsbProtocolError(f"device answered {self.last_delay_bits} bit times after the bus "
                                       f"was released (> {MAX_RESPONSE_BITS})")
        return rx

    async def send(self, packet: bytes, *, listen: bool = False, **enc) -> Reply:
        if self.tl:
            if enc.get("stuff_error_at_byte") is not None:
                raise ValueError("bit-stuff errors exist on the wire only")
            raw = await self.tl_packet(packet, 4 * HOST_TIMEOUT_BITS if listen else 0)
        else:
            rx = await self.wire(encode(packet, **enc), HOST_TIMEOUT_BITS if listen else 0)
            raw = decode(rx) if rx else b""
        if not raw:
            return Reply(None)
        pid, payload = parse_reply(raw)
        return Reply(pid, payload, self.last_delay_bits)

    async def bus_reset(self, bits: int = 64) -> None:
        if self.tl:
            self.dut.tl_bus_reset_i.value = 1
            await Timer(bits * 4 * self.hclk_period_ps, unit="ps")
            self.dut.tl_bus_reset_i.value = 0
            await Timer(16 * self.hclk_period_ps, unit="ps")
        else:
            await self.wire([SE0] * bits + [J])

    async def idle(self, bits: int) -> None:
        if self.tl:
            await Timer(bits * 4 * self.hclk_period_ps, unit="ps")
        else:
            await self.wire([REL] * bits)

    # ------------------------------------------------------------ transactions
    async def sof(self, frame: int) -> Reply:
        """Start-of-frame token (11-bit frame number); a device never answers it."""
        return await self.send(token_bytes(PID_SOF, frame & 0x7F, (frame >> 7) & 0xF), listen=True)

    async def in_token(self, addr: int, ep: int, *, ack: bool = True) -> Reply:
        """IN transaction; the host ACKs a good data packet unless ack=False (lost ACK)."""
        r = await self.send(token_bytes(PID_IN, addr, ep), listen=True)
        if ack and r.pid in (PID_DATA0, PID_DATA1):
            await self.send(bytes([pid_byte(PID_ACK)]))
        return r

    async def out(self, addr: int, ep: int, data1: bool, payload: bytes, *, bad_crc: bool = False,
                  stuff_error_at_byte: int | None = None, pid: int = PID_OUT) -> Reply:
        await self.send(token_bytes(pid, addr, ep))
        return await self.send(data_bytes(PID_DATA1 if data1 else PID_DATA0, payload, bad_crc=bad_crc),
                               listen=True, stuff_error_at_byte=stuff_error_at_byte)

    async def setup(self, addr: int, req: bytes) -> Reply:
        return await self.out(addr, 0, False, req, pid=PID_SETUP)

    async def control_read(self, addr: int, bm: int, breq: int, value: int, index: int, length: int,
                           *, max_naks: int = 10) -> bytes:
        req = bytes([bm, breq, value & 0xFF, value >> 8, index & 0xFF, index >> 8, length & 0xFF, length >> 8])
        r = await self.setup(addr, req)
        if r.pid != PID_ACK:
            raise UsbProtocolError(f"SETUP answered {r.name}")
        data, toggle = b"", True
        while True:
            r = await self.in_token(addr, 0)
            if r.pid == PID_STALL:
                raise StallError(f"control read {req.hex()} stalled")
            if r.pid not in (PID_DATA0, PID_DATA1):
                raise UsbProtocolError(f"data stage answered {r.name}")
            if (r.pid == PID_DATA1) != toggle:
                raise UsbProtocolError(f"data stage toggle: got {r.name}")
            toggle = not toggle
            data += r.payload
            if len(r.payload) < 64 or len(data) >= length:
                break
        r = await self.out(addr, 0, True, b"")
        if r.pid != PID_ACK:
            raise UsbProtocolError(f"status stage (OUT) answered {r.name}")
        return data

    async def control_nodata(self, addr: int, bm: int, breq: int, value: int, index: int) -> None:
        req = bytes([bm, breq, value & 0xFF, value >> 8, index & 0xFF, index >> 8, 0, 0])
        r = await self.setup(addr, req)
        if r.pid != PID_ACK:
            raise UsbProtocolError(f"SETUP answered {r.name}")
        r = await self.in_token(addr, 0)
        if r.pid == PID_STALL:
            raise StallError(f"request {req.hex()} stalled")
        if r.pid != PID_DATA1 or r.payload:
            raise UsbProtocolError(f"status stage (IN) answered {r.name} {r.payload.hex()}")


class StallError(Exception):
    """The device answered STALL."""
