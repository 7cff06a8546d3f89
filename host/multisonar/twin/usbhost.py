"""A USB host for the twin, at transaction level: it sends the packets a full-speed host
controller sends (tokens, data, handshakes; CRC5 / CRC16 computed here, independently of the
RTL) into the device's packet layer and checks what comes back (PID, CRC16, data toggles).

Bus time is kept: after each packet the device runs on for as long as the packet would have
held a 12 Mbit/s bus (4 clocks per bit, SYNC / EOP / worst-case bit stuffing included), so
throughput and latency figures are those of a full-speed link. Not modelled: SOF tokens (the
device core ignores them), the 1 ms frame structure and other devices on the bus.

:class:`TwinUsbFunction` puts this host behind :class:`multisonar.usb.function.UsbFunction`,
so the unchanged pyusb driver reaches the simulated device in-process or over USB/IP.
"""

from __future__ import annotations

import struct
import threading
import time

from ..usb.descriptors import DescriptorSet, read_descriptor_set
from ..usb.function import Stall, UsbFunction, UsbTimeout
from ..usb.packets import (PID_ACK, PID_DATA0, PID_DATA1, PID_IN, PID_NAK, PID_OUT, PID_SETUP, PID_STALL,
                           MAX_PACKET, UsbProtocolError, bus_bits, data_bytes, parse_reply, pid_byte, token_bytes)
from .sim import TwinSim

CLOCKS_PER_BIT = 4           # 48 MHz device clock, 12 Mbit/s
HOST_TIMEOUT_BITS = 18       # USB 2.0 7.1.19.1: the host waits 16..18 bit times for an answer
INTER_PACKET_BITS = 2
ADDR = 5                     # the address this host gives the device


class StallError(Exception):
    """The device answered STALL."""


class Reply:
    __slots__ = ("pid", "payload")

    def __init__(self, pid: int | None, payload: bytes = b"") -> None:
        self.pid, self.payload = pid, payload


class TwinUsbHost:
    def __init__(self, sim: TwinSim) -> None:
        self.sim = sim
        self.packets = 0
        self.bus_clocks = 0
        self._t0: int | None = None
        self._owed = 0

    def send(self, packet: bytes, *, listen: bool = False) -> Reply:
        """One packet; the bus time it (and the answer) would take on the wire is owed and paid
        at the end of the transaction (:meth:`settle`): inside a transaction the packets follow
        each other as on the transaction-level port the cocotb tests use, the device's own
        timeouts (RX_TIMEOUT, ACK_TIMEOUT in ms_usb_xact) counting from the packet ends."""
        if self._t0 is None:
            self._t0 = self.sim.cycles
        raw, delay = self.sim.usb_packet(packet, CLOCKS_PER_BIT * HOST_TIMEOUT_BITS if listen else 0)
        self.packets += 1
        bus = bus_bits(len(packet)) + INTER_PACKET_BITS
        if raw:
            bus += max(delay, 0) // CLOCKS_PER_BIT + bus_bits(len(raw)) + INTER_PACKET_BITS
        elif listen:
            bus += HOST_TIMEOUT_BITS
        self._owed += bus * CLOCKS_PER_BIT
        if not raw:
            return Reply(None)
        pid, payload = parse_reply(raw)
        return Reply(pid, payload)

    def settle(self) -> None:
        """End of a transaction: let the device run until the bus time of its packets is over."""
        if self._t0 is not None:
            spent = self.sim.cycles - self._t0
            self.bus_clocks += self._owed
            if self._owed > spent:
                self.sim.run(self._owed - spent)
        self._t0, self._owed = None, 0

    def bus_reset(self) -> None:
        self.sim.bus_reset(10 * 48_000 // 1000)  # 10 ms of SE0 would be 480 k clocks; 10 us suffice the core
        self.sim.run(48_000)  # 1 ms reset recovery

    def in_token(self, addr: int, ep: int) -> Reply:
        r = self.send(token_bytes(PID_IN, addr, ep), listen=True)
        if r.pid in (PID_DATA0, PID_DATA1):
            self.send(bytes([pid_byte(PID_ACK)]))
        self.settle()
        return r

    def in_poll(self, addr: int, ep: int, poll_clocks: int, max_clocks: int) -> tuple[Reply | None, int]:
        """IN tokens every ``poll_clocks`` of idle bus while the device NAKs, the loop run inside
        the harness (:meth:`TwinSim.usb_in_poll`): the same packets at the same clocks as
        :meth:`in_token` then ``sim.run(poll_clocks)`` per NAK. Returns (the first answer other
        than a NAK, its transaction completed as :meth:`in_token` completes it, or None after
        ``max_clocks`` or so of NAKs; the NAKs)."""
        token = token_bytes(PID_IN, addr, ep)
        listen = CLOCKS_PER_BIT * HOST_TIMEOUT_BITS
        nak_bus = CLOCKS_PER_BIT * (bus_bits(len(token)) + bus_bits(1) + 2 * INTER_PACKET_BITS)
        p = self.sim.usb_in_poll(token, listen, nak_bus, poll_clocks, max_clocks)
        raw, delay, naks = p.answer, p.delay, p.naks
        self.packets += naks
        self.bus_clocks += p.nak_clocks
        if raw is None:
            for clocks in (p.settle_left, p.poll_left):
                if clocks:
                    self.sim.run(clocks)
            return None, naks
        # the answer's transaction from its token on, as send() and in_token() account it
        self._t0 = p.token_at
        self.packets += 1
        bus = bus_bits(len(token)) + INTER_PACKET_BITS
        bus += (max(delay, 0) // CLOCKS_PER_BIT + bus_bits(len(raw)) + INTER_PACKET_BITS) if raw else HOST_TIMEOUT_BITS
        self._owed = bus * CLOCKS_PER_BIT
        r = Reply(*parse_reply(raw)) if raw else Reply(None)
        if r.pid in (PID_DATA0, PID_DATA1):
            self.send(bytes([pid_byte(PID_ACK)]))
        self.settle()
        return r, naks

    def out(self, addr: int, ep: int, data1: bool, payload: bytes, *, pid: int = PID_OUT) -> Reply:
        self.send(token_bytes(pid, addr, ep))
        r = self.send(data_bytes(PID_DATA1 if data1 else PID_DATA0, payload), listen=True)
        self.settle()
        return r

    def control_read(self, addr: int, bm: int, breq: int, value: int, index: int, length: int) -> bytes:
        req = struct.pack("<BBHHH", bm, breq, value, index, length)
        r = self.out(addr, 0, False, req, pid=PID_SETUP)
        if r.pid != PID_ACK:
            raise UsbProtocolError(f"SETUP answered {r.pid}")
        data, toggle = b"", True
        for _ in range(10_000):
            r = self.in_token(addr, 0)
            if r.pid == PID_STALL:
                raise StallError(f"control read {req.hex()} stalled")
            if r.pid == PID_NAK:
                continue
            if r.pid not in (PID_DATA0, PID_DATA1):
                raise UsbProtocolError(f"control data stage answered {r.pid}")
            if (r.pid == PID_DATA1) != toggle:
                raise UsbProtocolError("control data stage: wrong data toggle")
            toggle = not toggle
            data += r.payload
            if len(r.payload) < MAX_PACKET or len(data) >= length:
                break
        r = self.out(addr, 0, True, b"")
        if r.pid != PID_ACK:
            raise UsbProtocolError(f"control status stage (OUT) answered {r.pid}")
        return data

    def control_nodata(self, addr: int, bm: int, breq: int, value: int, index: int) -> None:
        req = struct.pack("<BBHHH", bm, breq, value, index, 0)
        r = self.out(addr, 0, False, req, pid=PID_SETUP)
        if r.pid != PID_ACK:
            raise UsbProtocolError(f"SETUP answered {r.pid}")
        for _ in range(10_000):
            r = self.in_token(addr, 0)
            if r.pid != PID_NAK:
                break
        if r.pid == PID_STALL:
            raise StallError(f"request {req.hex()} stalled")
        if r.pid != PID_DATA1 or r.payload:
            raise UsbProtocolError(f"control status stage (IN) answered {r.pid}")


class TwinUsbFunction(UsbFunction):
    """The twin as a USB function: enumerated at construction (bus reset, SET_ADDRESS, the whole
    descriptor set read from the device's ROM as a host reads it), then control / bulk transfers
    from any thread (one at a time; the simulation belongs to whichever thread calls).

    A NAKed bulk IN is retried every ``poll_s`` of device time (the device runs meanwhile) until
    data arrive or the call's ``timeout_s`` passes in wall-clock time, as libusb counts it (a
    USB/IP client unlinks the transfer then: answering later would lose the data). The retries
    run inside the harness (:meth:`TwinUsbHost.in_poll`, back in Python at least every ~1 ms of
    device time); ``harness_poll=False``: one Python round per NAK, the same packets at the same
    clocks (tests/test_twin_skip.py compares the two)."""

    POLL_HANDBACK_CLOCKS = 48_000  # the harness's NAK loop returns after ~1 ms of device time

    def __init__(self, sim: TwinSim, *, poll_s: float = 50e-6, harness_poll: bool = True) -> None:
        super().__init__(DescriptorSet(b"", b"", (), b"", b""))  # read from the ROM below
        self.sim, self.host = sim, TwinUsbHost(sim)
        self.poll_clocks = int(poll_s * 48e6)
        self.harness_poll = harness_poll
        self.lock = threading.RLock()
        self.out_toggle = False
        self.in_toggle: bool | None = None
        self.stats = {"in_naks": 0, "out_naks": 0, "in_packets": 0, "out_packets": 0, "bytes_in": 0, "bytes_out": 0}
        self.enumerate()

    def enumerate(self) -> None:
        with self.lock:
            h = self.host
            h.bus_reset()
            h.control_read(0, 0x80, 6, 0x0100, 0, 64)
            h.control_nodata(0, 0x00, 5, ADDR, 0)
            self.descriptors = read_descriptor_set(lambda *req: h.control_read(ADDR, *req))
            self.out_toggle, self.in_toggle = False, None

    # ------------------------------------------------------------------ UsbFunction
    def control(self, setup: bytes, data: bytes = b"") -> bytes:
        rt, req, value, index, length = struct.unpack("<BBHHH", bytes(setup))
        if rt == 0x00 and req == 5:  # SET_ADDRESS: the device already has its address
            return b""
        with self.lock:
            try:
                if rt & 0x80:
                    return self.host.control_read(ADDR, rt, req, value, index, length)
                if data:
                    raise Stall("control writes with a data stage are not supported by the device")
                self.host.control_nodata(ADDR, rt, req, value, index)
            except StallError as e:
                raise Stall(str(e)) from None
            if (rt, req) in ((0x00, 9), (0x01, 11)):  # SET_CONFIGURATION / SET_INTERFACE
                self.out_toggle, self.in_toggle = False, None
                if req == 9:
                    self.configuration = value
            if (rt, req) == (0x02, 1):  # CLEAR_FEATURE(ENDPOINT_HALT)
                if index == 0x01:
                    self.out_toggle = False
                elif index == 0x81:
                    self.in_toggle = None
            return b""

    def bulk_out(self, ep: int, data: bytes) -> None:
        data = bytes(data)
        chunks = [data[i:i + MAX_PACKET] for i in range(0, len(data), MAX_PACKET)]
        if len(data) % MAX_PACKET == 0:
            chunks.append(b"")  # the transfer ends with a zero-length packet
        with self.lock:
            for c in chunks:
                for _ in range(100_000):
                    r = self.host.out(ADDR, ep & 0x7F, self.out_toggle, c)
                    if r.pid == PID_ACK:
                        self.out_toggle = not self.out_toggle
                        self.stats["out_packets"] += 1
                        self.stats["bytes_out"] += len(c)
                        break
                    if r.pid == PID_STALL:
                        raise Stall(f"endpoint 0x{ep:02X} stalled")
                    self.stats["out_naks"] += 1
                    self.sim.run(self.poll_clocks)
                else:
                    raise UsbTimeout("bulk OUT: the device kept NAKing")

    def bulk_in(self, ep: int, length: int, timeout_s: float) -> bytes:
        deadline = time.monotonic() + timeout_s
        data = b""
        with self.lock:
            while True:
                if self.harness_poll:
                    polled, naks = self.host.in_poll(ADDR, ep & 0x7F, self.poll_clocks, self.POLL_HANDBACK_CLOCKS)
                    self.stats["in_naks"] += naks
                    if polled is None:  # NAKs for a while
                        if not data and time.monotonic() >= deadline:
                            raise UsbTimeout("bulk IN: no data (NAK) within the timeout")
                        continue
                    r = polled
                else:
                    r = self.host.in_token(ADDR, ep & 0x7F)
                if r.pid in (PID_DATA0, PID_DATA1):
                    toggle = r.pid == PID_DATA1
                    if self.in_toggle is not None and toggle == self.in_toggle:
                        continue  # a repeat: already have it
                    self.in_toggle = toggle
                    self.stats["in_packets"] += 1
                    self.stats["bytes_in"] += len(r.payload)
                    data += r.payload
                    if len(r.payload) < MAX_PACKET or len(data) >= length:
                        return data
                    continue
                if r.pid == PID_STALL:
                    raise Stall(f"endpoint 0x{ep:02X} stalled")
                if r.pid != PID_NAK:
                    raise UsbProtocolError(f"bulk IN answered {r.pid}")
                self.stats["in_naks"] += 1
                if not data and time.monotonic() >= deadline:
                    raise UsbTimeout("bulk IN: no data (NAK) within the timeout")
                self.sim.run(self.poll_clocks)

    def close(self) -> None:
        pass


__all__ = ["TwinUsbFunction", "TwinUsbHost", "StallError", "UsbProtocolError"]
