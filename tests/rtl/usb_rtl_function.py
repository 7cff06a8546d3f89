"""The RTL device as a :class:`multisonar.usb.function.UsbFunction`: the unchanged host driver
(pyusb, in-process backend or our USB/IP server) talks to the running cocotb simulation.

Threads: pyusb calls ``control`` / ``bulk_out`` / ``bulk_in`` from its own thread; each call
becomes a request in a queue and waits for its result. :meth:`RtlUsbFunction.serve` runs in
cocotb's thread: it takes the requests one at a time and performs them as USB transactions
through :class:`usb_host.UsbHost` (transaction level: the device's packet layer, transaction
engine, EP0 and bulk endpoints are the real RTL; only the line coding is skipped), and lets
simulated time run (``idle_ps`` per poll) while no request waits, so the firmware and the sonar
core keep working. A NAKed bulk IN is retried every ``nak_ps`` of simulated time until data
arrive or the call's wall-clock timeout passes (then pyusb sees a timeout, as with libusb).

Bus reset (:meth:`RtlUsbFunction.request_bus_reset`, from either thread): the next bulk IN
transfer that has received a full packet takes one more packet from the device without
ACKing it (it stays in the device and comes again as DATA0), then the bridge resets the bus
(``tl_bus_reset_i``) and re-enumerates the device, as a host does after a port reset. The
interrupted transfer fails with :class:`Disconnected` (pyusb: ENODEV, the driver:
DeviceDisconnected) and its data are discarded, like libusb's handle of a re-enumerated
device; every later call fails the same way until :meth:`reconnect` (the application
finding the re-enumerated device; ``Device.attach(fn)`` then opens it again).
"""

from __future__ import annotations

import queue
import struct
import time
from concurrent.futures import Future
from typing import Any

from cocotb.triggers import Timer
from cocotb.utils import get_sim_time

from multisonar.usb.descriptors import DescriptorSet
from multisonar.usb.function import Disconnected, Stall, UsbFunction, UsbTimeout
from usb_host import PID_ACK, PID_DATA0, PID_DATA1, PID_NAK, PID_STALL, StallError, UsbHost, UsbProtocolError

ADDR = 5  # the address the bridge gives the device


class RtlUsbFunction(UsbFunction):
    def __init__(self, host: UsbHost, *, idle_ps: int = 20_000_000, nak_ps: int = 10_000_000,
                 call_timeout_s: float = 120.0) -> None:
        super().__init__(DescriptorSet(b"", b"", (), b"", b""))  # read from the ROM at enumeration
        self.host, self.idle_ps, self.nak_ps = host, idle_ps, nak_ps
        self.call_timeout_s = call_timeout_s
        self.requests: queue.Queue[tuple[str, tuple, Future]] = queue.Queue()
        self.out_toggle = False
        self.in_toggle: bool | None = None
        self.stopped = False
        self.stats = {"requests": 0, "in_naks": 0, "out_naks": 0, "in_packets": 0, "out_packets": 0}
        #: (kind, sim ns at the start, sim ns at the end, bytes) of every request, for benchmarks
        self.log: list[tuple[str, float, float, int]] = []
        self.reset_requested = False
        self.gone = False  # after a bus reset until reconnect(): the old handle is dead
        #: per bus reset: sim ns, bytes of the interrupted transfer the host discarded, the
        #: payload of the packet left un-ACKed in the device (None if it NAKed)
        self.resets: list[dict] = []

    # ------------------------------------------------------------------ cocotb side
    async def enumerate(self) -> None:
        """Bus reset, address, descriptors (what a host does when the device is plugged in)."""
        h = self.host
        await h.bus_reset()
        dev = await h.control_read(0, 0x80, 6, 0x0100, 0, 64)
        await h.control_nodata(0, 0x00, 5, ADDR, 0)
        dev = await h.control_read(ADDR, 0x80, 6, 0x0100, 0, 18)
        cfg = await h.control_read(ADDR, 0x80, 6, 0x0200, 0, 9)
        cfg = await h.control_read(ADDR, 0x80, 6, 0x0200, 0, struct.unpack_from("<H", cfg, 2)[0])
        strings = {}
        for i in range(5):
            strings[i] = await h.control_read(ADDR, 0x80, 6, 0x0300 | i, 0x0409 if i else 0, 255)
        self.descriptors = DescriptorSet(dev, cfg, tuple(strings.values()), b"", b"")

    async def serve(self) -> None:
        """Run requests until :meth:`stop`; simulated time runs meanwhile."""
        while not self.stopped:
            try:
                kind, args, fut = self.requests.get_nowait()
            except queue.Empty:
                await Timer(self.idle_ps, unit="ps")
                continue
            self.stats["requests"] += 1
            t0 = get_sim_time("ns")
            try:
                res = await getattr(self, "_do_" + kind)(*args)
                n = len(res) if isinstance(res, bytes) else len(args[1]) if kind == "bulk_out" else 0
                self.log.append((kind, t0, get_sim_time("ns"), n))
                fut.set_result(res)
            except Exception as e:  # noqa: BLE001 - handed to the calling thread
                self.log.append((kind, t0, get_sim_time("ns"), -1))
                fut.set_exception(e)

    def stop(self) -> None:
        self.stopped = True

    async def _do_control(self, setup: bytes, data: bytes) -> bytes:
        rt, req, value, index, length = struct.unpack("<BBHHH", setup)
        if rt == 0x00 and req == 5:  # SET_ADDRESS: the bridge gave the device its address
            return b""
        try:
            if rt & 0x80:
                return await self.host.control_read(ADDR, rt, req, value, index, length)
            if data:
                raise Stall("control writes with a data stage are not supported by the device")
            await self.host.control_nodata(ADDR, rt, req, value, index)
        except StallError as e:
            raise Stall(str(e)) from None
        if (rt, req) == (0x00, 9) or (rt, req) == (0x01, 11):  # SET_CONFIGURATION / SET_INTERFACE
            self.out_toggle, self.in_toggle = False, None
            self.configuration = value if req == 9 else self.configuration
        if (rt, req) == (0x02, 1):  # CLEAR_FEATURE(ENDPOINT_HALT)
            if index == 0x01:
                self.out_toggle = False
            elif index == 0x81:
                self.in_toggle = None
        return b""

    async def _do_bulk_out(self, ep: int, data: bytes) -> None:
        chunks = [data[i:i + 64] for i in range(0, len(data), 64)]
        if len(data) % 64 == 0:
            chunks.append(b"")  # the transfer ends with a zero-length packet
        for c in chunks:
            for _ in range(100_000):
                r = await self.host.out(ADDR, ep & 0x7F, self.out_toggle, c)
                if r.pid == PID_ACK:
                    self.out_toggle = not self.out_toggle
                    self.stats["out_packets"] += 1
                    break
                if r.pid == PID_STALL:
                    raise Stall(f"endpoint 0x{ep:02X} stalled")
                self.stats["out_naks"] += 1
                await Timer(self.nak_ps, unit="ps")
            else:
                raise UsbTimeout("bulk OUT: the device kept NAKing")

    async def _do_bulk_in(self, ep: int, length: int, deadline: float) -> bytes:
        data = b""
        while True:
            r = await self.host.in_token(ADDR, ep & 0x7F)
            if r.pid in (PID_DATA0, PID_DATA1):
                toggle = r.pid == PID_DATA1
                if self.in_toggle is not None and toggle == self.in_toggle:
                    continue  # a repeat (our ACK was lost): already have it
                self.in_toggle = toggle
                self.stats["in_packets"] += 1
                data += r.payload
                if len(r.payload) < 64 or len(data) >= length:
                    return data
                if self.reset_requested:
                    await self._reset_mid_transfer(ep, data)
                continue
            if r.pid == PID_STALL:
                raise Stall(f"endpoint 0x{ep:02X} stalled")
            if r.pid != PID_NAK:
                raise UsbProtocolError(f"bulk IN answered {r.name}")
            self.stats["in_naks"] += 1
            if not data and time.monotonic() > deadline:
                raise UsbTimeout("bulk IN: no data (NAK)")
            await Timer(self.nak_ps, unit="ps")

    async def _reset_mid_transfer(self, ep: int, got: bytes) -> None:
        r = await self.host.in_token(ADDR, ep & 0x7F, ack=False)  # the device's next packet: lost ACK
        unacked = r.payload if r.pid in (PID_DATA0, PID_DATA1) else None
        await self.host.bus_reset()
        self.reset_requested = False
        self.out_toggle, self.in_toggle = False, None
        self.gone = True
        await self.enumerate()  # the host re-enumerates (address, descriptors; unconfigured)
        self.resets.append({"sim_ns": get_sim_time("ns"), "discarded": bytes(got), "unacked": unacked})
        raise Disconnected("bus reset during a bulk IN transfer: the device was re-enumerated")

    # ------------------------------------------------------------------ pyusb side (other thread)
    def request_bus_reset(self) -> None:
        """Reset the bus in the middle of the next multi-packet bulk IN transfer."""
        self.reset_requested = True

    def reconnect(self) -> None:
        """The application found the re-enumerated device: calls work again."""
        self.gone = False

    def _call(self, kind: str, *args: Any) -> Any:
        if self.stopped:
            raise Disconnected("the simulation has ended")
        if self.gone:
            raise Disconnected("the device was reset and re-enumerated: open it again")
        fut: Future = Future()
        self.requests.put((kind, args, fut))
        return fut.result(timeout=self.call_timeout_s)

    def control(self, setup: bytes, data: bytes = b"") -> bytes:
        return self._call("control", bytes(setup), bytes(data))

    def bulk_out(self, ep: int, data: bytes) -> None:
        self._call("bulk_out", ep, bytes(data))

    def bulk_in(self, ep: int, length: int, timeout_s: float) -> bytes:
        return self._call("bulk_in", ep, length, time.monotonic() + timeout_s)
