"""Host driver: one :class:`Device` for the board (libusb), a simulated device over USB/IP, or
the simulated device in-process, switched by a URL only (docs/host_driver.md)::

    with Device.open("sim://corridor") as dev:          # or None (board), "usbip://127.0.0.1:3240"
        dev.configure([VirtualSensor("front", tx=[23, 0, 1], rx=[23, 0, 1])])
        dev.start()
        for frame in dev.stream(duration_s=1.0):
            frame.tof["tof"], frame.tof["rx"], frame.geo
        print(dev.counters())

Every transfer goes through pyusb (``usb.core``): libusb for the board, our USB/IP client
backend or the in-process backend for the simulation, so the same driver code runs against
all three. Commands and frames follow ``docs/protocol.md`` (:mod:`multisonar.protocol`).
"""

from __future__ import annotations

import errno
import json
import struct
import time
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from .clock import DeviceClock
from . import protocol as P
from .errors import DeviceDisconnected, DeviceNotFound, DeviceTimeout
from .schedule import Schedule, ScheduleError, VirtualSensor
from .urls import Connection, DeviceUrl, open_url, register_scheme


#: host-side counters (Device.counters() adds them with a ``host_`` prefix)
HOST_COUNTERS = ("frames", "lost", "bad_crc", "bad_header", "bad_frames", "skipped_bytes", "queue_dropped",
                 "stale_replies", "seq_resets")


@dataclass
class HostStats:
    frames: int = 0  #: frames decoded and delivered (or queued)
    lost: int = 0  #: frames missing by sequence number (device drops and transfer losses)
    bad_crc: int = 0  #: packets with a CRC mismatch (dropped; resync)
    bad_header: int = 0  #: bad magic/version/length positions skipped while resynchronising
    bad_frames: int = 0  #: CRC-valid frames whose content is malformed
    skipped_bytes: int = 0
    queue_dropped: int = 0  #: frames dropped by the bounded host queue (oldest first)
    stale_replies: int = 0  #: replies to earlier commands (not awaited any more)
    seq_resets: int = 0  #: sequence jumped backwards (device restarted)

    def as_dict(self) -> dict[str, int]:
        return {k: int(getattr(self, k)) for k in HOST_COUNTERS}


def _is_timeout(e: Exception) -> bool:
    import usb.core

    return isinstance(e, usb.core.USBTimeoutError) or getattr(e, "errno", None) == errno.ETIMEDOUT


class Device:
    """A Multisonar over pyusb. Use :meth:`open`."""

    def __init__(self, usbdev: Any, *, url: str, cleanup: Callable[[], None] | None = None,
                 queue_frames: int = 4096, timeout_s: float = 2.0) -> None:
        import usb.util

        self.url = url
        self._dev = usbdev
        self._cleanup = cleanup
        self.timeout_s = timeout_s
        self._buf = usb.util.create_buffer(P.READ_SIZE)
        self._parser = P.StreamParser()
        self.queue: deque[P.Frame] = deque()
        self.queue_frames = int(queue_frames)
        self.stats = HostStats()
        self._seq = int(time.monotonic_ns()) & 0xFFFF  # start away from 0: stale replies never match
        self._expect: int | None = None  # next frame sequence number
        self._info: P.DeviceInfo | None = None
        self.schedule: Schedule | None = None
        self.sensor_names: dict[int, str] = {}
        self.closed = False
        #: device ticks -> 64 bits -> host time (syncs: START, then every SYNC_EVERY_S while streaming)
        self.clock = DeviceClock()
        self._next_sync = 0.0

    # -- opening ----------------------------------------------------------------------------
    @classmethod
    def open(cls, url: str | None = None, *, timeout_s: float = 2.0, queue_frames: int = 4096) -> "Device":
        """Open the device at ``url``; its scheme picks the opener (:mod:`multisonar.urls`).

        * ``None`` / ``"usb://"`` (or ``libusb://``): the first board on libusb (VID 0x1209,
          PID 0x0001); ``usb://?serial=XYZ`` picks one by serial number. The driver's own.
        * ``"usbip://HOST:PORT"``: a (simulated) device exported over USB/IP.
        * ``"sim://SCENE?rate=R&source=model|replay&queue=N&seed=S"``: the simulated device
          in this process (in-process pyusb backend; fastest, for tests and tools).
        * ``"twin://SCENE"``: the full-system twin in this process (the device's RTL in
          Verilator with the scene's echoes, multisonar.twin; ~100x slower than real time;
          timeouts of at least 120 s).

        The last three are registered by the modules that implement them, found through the
        ``multisonar.schemes`` entry points on first use; ``multisonar.urls.register_scheme``
        adds more. An unknown scheme raises :class:`multisonar.urls.UnknownScheme` (a
        ValueError) listing the known ones.
        """
        import usb.core

        url = url or "usb://"
        conn = open_url(url, timeout_s=timeout_s)
        dev, cleanup = conn.device, conn.cleanup
        timeout_s = max(timeout_s, conn.min_timeout_s)
        try:
            try:
                cfg = dev.get_active_configuration()
            except usb.core.USBError:
                cfg = None
            if cfg is None or cfg.bConfigurationValue != 1:
                dev.set_configuration(1)
            import usb.util

            usb.util.claim_interface(dev, 0)
        except usb.core.USBError as e:
            if cleanup:
                cleanup()
            if e.errno == errno.EACCES:
                raise DeviceNotFound(f"{url}: permission denied; install host/udev/99-multisonar.rules") from None
            raise DeviceNotFound(f"{url}: cannot configure the device: {e}") from None
        self = cls(dev, url=url, cleanup=cleanup, queue_frames=queue_frames, timeout_s=timeout_s)
        info = self.info()
        if info.protocol_version != P.PROTOCOL_VERSION:
            self.close()
            raise DeviceNotFound(f"{url}: device speaks protocol {info.protocol_version}, this driver {P.PROTOCOL_VERSION}")
        return self

    @classmethod
    def attach(cls, function: Any, *, url: str = "inproc://", timeout_s: float = 2.0,
               queue_frames: int = 4096) -> "Device":
        """Open a device-side model (a :class:`multisonar.usb.function.UsbFunction`, e.g. a
        SimDevice or an RTL twin) through the in-process pyusb backend."""
        import usb.core

        from .usb.inproc import InProcessBackend

        dev = usb.core.find(idVendor=P.USB_VID, idProduct=P.USB_PID, backend=InProcessBackend(function))
        if dev is None:
            raise DeviceNotFound(f"{url}: the function does not identify as {P.USB_VID:04x}:{P.USB_PID:04x}")
        dev.set_configuration(1)
        self = cls(dev, url=url, cleanup=None, queue_frames=queue_frames, timeout_s=timeout_s)
        self.info()
        return self

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            import usb.util

            usb.util.dispose_resources(self._dev)
        except Exception:  # noqa: BLE001 - closing a dead device must not raise
            pass
        if self._cleanup is not None:
            self._cleanup()

    def __enter__(self) -> "Device":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- transport ----------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self.closed:
            raise DeviceDisconnected(f"{self.url}: device is closed; Device.open() it again")

    def _usb_error(self, e: Exception) -> DeviceDisconnected:
        self.close()
        return DeviceDisconnected(f"{self.url}: device disconnected ({e}); Device.open() it again")

    def _read_packets(self, timeout_s: float) -> list[P.Packet]:
        """One IN transfer -> packets ([] on timeout)."""
        import usb.core

        self._check_open()
        try:
            n = self._dev.read(P.EP_IN, self._buf, max(1, int(timeout_s * 1000)))
        except usb.core.USBError as e:
            if _is_timeout(e):
                return []
            raise self._usb_error(e) from None
        ps = self._parser
        before = (ps.bad_crc, ps.bad_header, ps.skipped_bytes)
        pk = ps.feed(memoryview(self._buf)[:n])
        self.stats.bad_crc += ps.bad_crc - before[0]
        self.stats.bad_header += ps.bad_header - before[1]
        self.stats.skipped_bytes += ps.skipped_bytes - before[2]
        return pk

    def _frame(self, p: P.Packet) -> P.Frame | None:
        try:
            f = P.decode_frame(p)
        except P.ProtocolError:
            self.stats.bad_frames += 1
            return None
        if self._expect is not None:
            gap = (f.seq - self._expect) & 0xFFFFFFFF
            if gap >= 1 << 31:
                self.stats.seq_resets += 1
            else:
                self.stats.lost += gap
        self._expect = (f.seq + 1) & 0xFFFFFFFF
        self.stats.frames += 1
        f.t0_ticks = self.clock.extend(f.t0)
        f.stamp_ns = self.clock.to_host_ns(f.t0_ticks)
        return f

    def _queue(self, f: P.Frame) -> None:
        if len(self.queue) >= self.queue_frames:
            self.queue.popleft()
            self.stats.queue_dropped += 1
        self.queue.append(f)

    def command(self, opcode: int, payload: bytes = b"", *, timeout_s: float | None = None, retries: int = 1) -> bytes:
        """Send one command, return the OK reply's payload; raise DeviceError / CfgRejected on
        an error status, DeviceTimeout without a reply. Frames read meanwhile are queued. A
        command the device received corrupted (BAD_CRC) is sent again up to ``retries`` times
        (every command is safe to repeat after BAD_CRC: the device did not execute it)."""
        while True:
            try:
                return self._command_once(opcode, payload, timeout_s)
            except P.DeviceError as e:
                if e.status != P.Status.BAD_CRC or retries <= 0:
                    raise
                retries -= 1

    def _command_once(self, opcode: int, payload: bytes, timeout_s: float | None) -> bytes:
        import usb.core

        self._check_open()
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        seq = self._seq
        pkt = P.encode_command(opcode, payload, seq=seq)
        try:
            self._dev.write(P.EP_OUT, pkt, int((timeout_s or self.timeout_s) * 1000))
        except usb.core.USBError as e:
            if _is_timeout(e):
                raise DeviceTimeout(f"{self.url}: command {P.Opcode(opcode).name} not accepted in time") from None
            raise self._usb_error(e) from None
        deadline = time.monotonic() + (timeout_s or self.timeout_s)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise DeviceTimeout(f"{self.url}: no reply to {P.Opcode(opcode).name} within {timeout_s or self.timeout_s} s")
            reply = None
            for p in self._read_packets(min(left, 0.5)):
                if p.is_frame:  # frames read with the reply (before or after it) are all kept
                    f = self._frame(p)
                    if f is not None:
                        self._queue(f)
                    continue
                if reply is not None or p.seq != seq or (p.type & 0x7F) != (opcode & 0x7F) \
                        and p.type != P.ERROR_REPLY_TYPE:
                    self.stats.stale_replies += 1
                    continue
                reply = p
            if reply is not None:
                p = reply
                if p.status == P.Status.OK:
                    return p.payload
                if p.status == P.Status.CFG_REJECTED:
                    raise P.CfgRejected(opcode, p.payload)
                detail = ""
                if p.status == P.Status.BAD_ADDRESS and len(p.payload) >= 8:
                    i, _, a = struct.unpack_from("<HHI", p.payload)
                    detail = f"entry {i}: address 0x{a:04X}"
                raise P.DeviceError(opcode, p.status, p.payload, detail)

    # -- commands ----------------------------------------------------------------------------
    def info(self, refresh: bool = False) -> P.DeviceInfo:
        if self._info is None or refresh:
            self._info = P.DeviceInfo.decode(self.command(P.Opcode.DEVICE_INFO))
        return self._info

    def write_regs(self, pairs: Sequence[tuple[int, int]]) -> None:
        n = P.MAX_PAYLOAD // 8
        for i in range(0, len(pairs), n):
            self.command(P.Opcode.WRITE_REGS, P.write_regs_payload(pairs[i:i + n]))

    def read_regs(self, addrs: Sequence[int]) -> list[int]:
        n = P.MAX_PAYLOAD // 4
        out: list[int] = []
        for i in range(0, len(addrs), n):
            out += P.parse_read_regs(self.command(P.Opcode.READ_REGS, P.read_regs_payload(addrs[i:i + n])))
        return out

    def set_param(self, param: P.Param | int, value: int) -> None:
        self.command(P.Opcode.SET_PARAM, P.set_param_payload(param, value))

    def get_param(self, param: P.Param | int) -> int:
        return P.parse_set_param(self.command(P.Opcode.GET_PARAM, struct.pack("<H", int(param))))[1]

    def set_miss_gate(self, ticks: int) -> int:
        """Set the gated miss rule (RX_FILTER.miss_gate, docs/fast_firing.md section 4.4), taking
        effect at the next :meth:`start`: once a track's velocity is measured, a tracking window's
        first echo farther than ``ticks`` from the prediction counts as a miss, one within it
        changes the velocity by half its residual (0 off: no gate, the last difference as the
        velocity; reset 500 = 10.4 us). The other safety rule is per sensor:
        ``VirtualSensor(reinit_every=M)``. Returns the value read back."""
        from .generated import sonar_regs as R

        reg = R.REGISTERS["RX_FILTER"]
        if not 0 <= ticks <= 0xFFFF:
            raise ValueError(f"miss gate {ticks} ticks does not fit RX_FILTER.miss_gate (0..65535 ticks, 0 = off)")
        v = reg.fields["MISS_GATE"].put(self.read_regs([reg.addr()])[0], ticks)
        self.write_regs([(reg.addr(), v)])
        return reg.fields["MISS_GATE"].get(self.read_regs([reg.addr()])[0])

    def set_miss_hold(self, on: bool) -> bool:
        """Set the miss hold (RX_FILTER.miss_hold, docs/fast_firing.md section 4.4), taking effect
        at the next :meth:`start`: while a tracked receiver of a sensor has a missed window, the
        sensor decides its next tracking pulse only once its last pulse's windows have closed,
        at order 0 if the miss is still pending, so that an obstacle cannot hide behind the echo
        of a pulse fired after the miss (reset: on). Returns the value read back."""
        from .generated import sonar_regs as R

        reg = R.REGISTERS["RX_FILTER"]
        v = reg.fields["MISS_HOLD"].put(self.read_regs([reg.addr()])[0], int(bool(on)))
        self.write_regs([(reg.addr(), v)])
        return bool(reg.fields["MISS_HOLD"].get(self.read_regs([reg.addr()])[0]))

    def configure(self, sensors: Sequence[VirtualSensor] | Schedule, *, layout: Any = None,
                  temperature_c: float = 20.0, verify: bool = True) -> Schedule:
        """Validate ``sensors`` with the golden model's Schedule (ScheduleError names the sensor
        and the constraint) and load them into the device's virtual-sensor table. The table is
        applied (and checked by the device) at :meth:`start`."""
        from .layout import load_layout
        from .regmap import schedule_writes

        if isinstance(sensors, Schedule):
            sched = sensors
        else:
            sensors = list(sensors)
            for i, s in enumerate(sensors):
                if not isinstance(s, VirtualSensor):
                    raise TypeError(f"sensor {i}: expected a multisonar.VirtualSensor, got {type(s).__name__}")
            sched = Schedule(layout if layout is not None else load_layout(), sensors, temperature_c=temperature_c)
        sched.validate()
        info = self.info()
        if len(sched.sensors) > info.max_vs:
            raise ScheduleError(f"{len(sched.sensors)} virtual sensors, the device holds {info.max_vs}")
        if sched.layout.n > info.channels:
            raise ScheduleError(f"layout has {sched.layout.n} elements, the device {info.channels} channels")
        writes = schedule_writes(sched)
        self.write_regs(writes)
        self.set_param(P.Param.TEMPERATURE_CC, int(round(sched.temperature_c * 100)))
        if verify:
            back = self.read_regs([a for a, _ in writes])
            bad = [(a, v, b) for (a, v), b in zip(writes, back) if v != b]
            if bad:
                a, v, b = bad[0]
                raise P.DeviceError(P.Opcode.READ_REGS, P.Status.INTERNAL, b"",
                                    f"read-back of 0x{a:04X} gave 0x{b:08X}, wrote 0x{v:08X} ({len(bad)} mismatches)")
        self.schedule = sched
        self.sensor_names = {r.id: r.name for r in sched.resolved}
        return sched

    def start(self) -> None:
        """Apply the table and start firing. Raises CfgRejected if the device refuses it."""
        self.queue.clear()
        self._parser.reset()
        first = struct.unpack("<I", self.command(P.Opcode.START))[0]
        self.queue.clear()  # frames of an earlier run
        self._expect = first
        self.sync_clock()

    def sync_clock(self) -> int:
        """One READ_COUNTERS round trip to map device ticks to host time (``clock``); returns
        the round trip in ns. Frames read meanwhile are queued and stamped."""
        return self._read_counters()[1].rtt_ns

    def _read_counters(self) -> tuple[dict[str, int], Any]:
        """READ_COUNTERS; its ``timestamp`` (the device tick, read during the round trip) also
        syncs ``clock``. Returns the counters and the clock.Sync."""
        sent = time.time_ns()
        d = P.decode_counters(self.command(P.Opcode.READ_COUNTERS))
        sync = self.clock.sync(d["timestamp"], sent, time.time_ns())
        self._next_sync = time.monotonic() + SYNC_EVERY_S
        return d, sync

    def stop(self, drain_s: float = 0.5) -> None:
        """Stop firing; frames already produced stay readable (queued). Frames the device numbered
        before STOP but never delivered (dropped at the end of the run) are counted in ``lost``."""
        end = struct.unpack("<I", self.command(P.Opcode.STOP))[0]
        deadline = time.monotonic() + drain_s
        while self._expect is not None and ((end - self._expect) & 0xFFFFFFFF) and \
                ((end - self._expect) & 0xFFFFFFFF) < 1 << 31 and time.monotonic() < deadline:
            for p in self._read_packets(0.05):
                if p.is_frame and (f := self._frame(p)) is not None:
                    self._queue(f)
        # frames numbered before STOP's sequence number that never came were dropped after the
        # last one that did (queue full up to the end): no later frame shows them as a gap
        tail = (end - self._expect) & 0xFFFFFFFF if self._expect is not None else 0
        if 0 < tail < 1 << 31:
            self.stats.lost += tail
            self._expect = end

    def counters(self) -> dict[str, int]:
        """Device counters (READ_COUNTERS), the firmware's own (``fw_*``, FW_STATS: geometry
        skipped, frames cut or lost, ToF latency) and the host's (``host_*``)."""
        d = self._read_counters()[0]
        try:
            d.update({f"fw_{k}": v for k, v in P.decode_fw_stats(self.command(P.Opcode.FW_STATS)).items()})
        except P.DeviceError as e:  # a device from before FW_STATS
            if e.status != P.Status.UNKNOWN_OPCODE:
                raise
        d.update({f"host_{k}": v for k, v in self.stats.as_dict().items()})
        d["host_queued"] = len(self.queue)
        return d

    def clear_counters(self) -> None:
        self.command(P.Opcode.CLEAR_COUNTERS)
        self.stats = HostStats()

    def echo(self, payload: bytes = b"") -> float:
        """Round trip of an ECHO command, seconds."""
        t = time.perf_counter()
        if self.command(P.Opcode.ECHO, payload) != payload:
            raise P.DeviceError(P.Opcode.ECHO, P.Status.INTERNAL, b"", "echo payload differs")
        return time.perf_counter() - t

    # -- streaming ----------------------------------------------------------------------------
    def stream(self, *, duration_s: float | None = None, max_frames: int | None = None,
               idle_timeout_s: float = 5.0) -> Iterator[P.Frame]:
        """Yield frames (queued ones first) until ``duration_s`` (wall) or ``max_frames``.
        Raises DeviceTimeout if no frame arrives for ``idle_timeout_s``."""
        t_end = None if duration_s is None else time.monotonic() + duration_s
        n = 0
        last = time.monotonic()
        while max_frames is None or n < max_frames:
            if self.queue:
                n += 1
                last = time.monotonic()
                yield self.queue.popleft()
                continue
            now = time.monotonic()
            if t_end is not None and now >= t_end:
                return
            if self.clock.synced and now >= self._next_sync:
                self.sync_clock()
                continue
            if now - last > idle_timeout_s:
                raise DeviceTimeout(f"{self.url}: no frame for {idle_timeout_s} s (started? Device.start())")
            wait = 0.2 if t_end is None else max(min(0.2, t_end - now), 0.001)
            for p in self._read_packets(wait):
                if p.is_frame:
                    f = self._frame(p)
                    if f is not None:
                        self._queue(f)
                else:
                    self.stats.stale_replies += 1

    def record(self, path: str | Path, *, duration_s: float | None = None, max_frames: int | None = None,
               progress: Callable[[int, float], None] | None = None, idle_timeout_s: float = 5.0) -> int:
        """Stream into a recording file (docs/host_driver.md, "Recording format"); returns the
        number of frames written."""
        if duration_s is None and max_frames is None:
            raise ValueError("record() needs duration_s or max_frames")
        meta = {"format": RECORDING_FORMAT, "protocol_version": P.PROTOCOL_VERSION, "url": self.url,
                "started_unix": time.time(), "device_info": self.info().__dict__, "sensors": self._sensor_meta()}
        n = 0
        t0 = last = time.monotonic()
        with RecordingWriter(path, meta) as w:
            for f in self.stream(duration_s=duration_s, max_frames=max_frames, idle_timeout_s=idle_timeout_s):
                w.write(f)
                n += 1
                if progress is not None and n % 32 == 0 and time.monotonic() - last >= 0.25:
                    last = time.monotonic()
                    progress(n, last - t0)
        if progress is not None:
            progress(n, time.monotonic() - t0)
        return n

    def _sensor_meta(self) -> list[dict[str, Any]]:
        return [] if self.schedule is None else sensor_meta(self.schedule.resolved)


def sensor_meta(resolved: Any) -> list[dict[str, Any]]:
    """The recording's (and the live view's) entry per resolved virtual sensor: what the ROS
    messages need of it (docs/host_driver.md, "Recording format"; rosmsgs.sensor_limits)."""
    return [{"id": r.id, "name": r.name, "tx": [int(e) for e in r.tx], "rx": [int(e) for e in r.rx],
             "order": r.order, "max_tof": int(r.max_tof), "blank": int(r.blank)} for r in resolved]


def _safe_serial(d: Any) -> str | None:
    try:
        return d.serial_number
    except Exception:  # noqa: BLE001 - no permission to read strings
        return None


def open_libusb(url: DeviceUrl, *, timeout_s: float = 2.0) -> Connection:
    """usb://[?serial=S]: the first Multisonar board on libusb (VID 0x1209, PID 0x0001), or the one with serial S"""
    import usb.core

    try:
        devs = list(usb.core.find(find_all=True, idVendor=P.USB_VID, idProduct=P.USB_PID))
    except usb.core.NoBackendError as e:
        raise DeviceNotFound(f"{url.url}: no libusb backend ({e}); install libusb-1.0") from None
    if "serial" in url.query:
        devs = [d for d in devs if _safe_serial(d) == url.query["serial"]]
    if not devs:
        raise DeviceNotFound(f"{url.url}: no Multisonar board (USB {P.USB_VID:04x}:{P.USB_PID:04x}) found; is it "
                             "plugged in and do you have access (udev rule host/udev/99-multisonar.rules)?")
    return Connection(devs[0])


# the driver's own schemes; the others register themselves (multisonar.urls)
register_scheme("usb", open_libusb, help=open_libusb.__doc__ or "")
register_scheme("libusb", open_libusb, help="libusb://[?serial=S]: as usb://")


# --------------------------------------------------------------------------------------------
# recording format
# --------------------------------------------------------------------------------------------
RECORDING_MAGIC = b"MSREC\x00\x00\x01"
RECORDING_FORMAT = 2  # 2: per-frame host time = acquisition (t0 mapped), was receive time
#: the driver re-syncs its tick -> host clock this often while streaming (one READ_COUNTERS)
SYNC_EVERY_S = 1.0


class RecordingWriter:
    """``MSREC\\0\\0\\x01``, u32 LE meta length, UTF-8 JSON meta, then per frame: u64 LE host
    time (ns since the Unix epoch) of the pulse's t0, mapped from device ticks by the driver's
    clock (the receive time only for a frame read before the first clock sync), and the frame's
    wire bytes (self-delimiting: header length field, CRC-32)."""

    def __init__(self, path: str | Path, meta: dict[str, Any]) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f = open(self.path, "wb")
        m = json.dumps(meta, default=_json_default).encode()
        self._f.write(RECORDING_MAGIC + struct.pack("<I", len(m)) + m)

    def write(self, frame: P.Frame, host_ns: int | None = None) -> None:
        if host_ns is None:
            host_ns = frame.stamp_ns if frame.stamp_ns is not None else time.time_ns()
        self._f.write(struct.pack("<Q", host_ns) + frame.packet())

    def close(self) -> None:
        self._f.close()

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(type(o).__name__)


@dataclass
class Recording:
    meta: dict[str, Any]
    frames: list[P.Frame]
    host_ns: np.ndarray
    corrupt: int = 0  #: frames whose CRC or content failed (skipped)
    truncated: bool = False  #: the file ends inside a frame (e.g. recording interrupted)

    def events(self) -> np.ndarray:
        return P.frames_to_events(self.frames)

    def geometry(self) -> np.ndarray:
        return P.frames_to_geometry(self.frames)


def read_recording(path: str | Path) -> Recording:
    """Read a recording; raises ProtocolError if it is not one. Corrupt frames are skipped
    and counted; a truncated tail is tolerated (``truncated``)."""
    data = Path(path).read_bytes()
    if data[:8] != RECORDING_MAGIC:
        raise P.BadMagic("recording", f"{path}: not a Multisonar recording (magic {data[:8]!r})")
    if len(data) < 12:
        raise P.BadLength("recording", f"{path}: header truncated")
    (mlen,) = struct.unpack_from("<I", data, 8)
    try:
        meta = json.loads(data[12:12 + mlen].decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise P.BadField("recording meta", f"{path}: {e}") from None
    pos = 12 + mlen
    frames, times, corrupt, truncated = [], [], 0, False
    while pos < len(data):
        if len(data) - pos < 8 + P.HEADER_SIZE:
            truncated = True
            break
        (ns,) = struct.unpack_from("<Q", data, pos)
        try:
            hdr = P.check_header(data[pos + 8:pos + 8 + P.HEADER_SIZE], magics=(P.MAGIC_FRAME,))
        except P.ProtocolError:
            raise P.BadField("recording", f"{path}: unreadable frame header at byte {pos + 8}") from None
        end = pos + 8 + P.HEADER_SIZE + hdr[5] + P.CRC_SIZE
        if end > len(data):
            truncated = True
            break
        try:
            frames.append(P.decode_frame(P.decode_packet(data[pos + 8:end], magics=(P.MAGIC_FRAME,))))
            times.append(ns)
        except P.ProtocolError:
            corrupt += 1
        pos = end
    return Recording(meta, frames, np.array(times, dtype=np.uint64), corrupt, truncated)
