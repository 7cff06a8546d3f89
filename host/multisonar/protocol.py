"""Multisonar USB protocol, version 1: packet codec (commands, replies, frames) and CRC.

The wire format is specified in ``docs/protocol.md``; this module is its executable form and
the only place the host encodes or decodes it. Every packet is::

    header (12 bytes, little-endian)       payload (length bytes)   CRC-32 (4 bytes, LE)
    magic[2] version type flags status length:u16 seq:u32

``magic`` is ``b"MC"`` (command, host -> device, bulk OUT 0x01), ``b"MR"`` (reply) or
``b"MF"`` (frame), both device -> host on bulk IN 0x81. The CRC is CRC-32/ISO-HDLC (zlib's
``crc32``) over header + payload. One packet is one USB transfer: it ends with a short packet
(a zero-length packet when its size is a multiple of 64).

Decoding is strict: anything that does not match raises a :class:`ProtocolError` subclass
naming the field; nothing else escapes the decoder (fuzzed in ``tests/test_protocol.py``).
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any, Iterable, NamedTuple, Sequence

import numpy as np

PROTOCOL_VERSION: int = 1
MAGIC_COMMAND: bytes = b"MC"
MAGIC_REPLY: bytes = b"MR"
MAGIC_FRAME: bytes = b"MF"
MAGICS: tuple[bytes, ...] = (MAGIC_COMMAND, MAGIC_REPLY, MAGIC_FRAME)

HEADER = struct.Struct("<2sBBBBHI")
HEADER_SIZE: int = HEADER.size  # 12
CRC_SIZE: int = 4
MAX_PAYLOAD: int = 1024  #: largest payload of any packet, bytes
MAX_PACKET: int = HEADER_SIZE + MAX_PAYLOAD + CRC_SIZE  #: 1040 bytes = 16.25 USB packets
USB_MPS: int = 64  #: bulk max packet size (full speed)
#: host read size: a whole number of USB packets >= MAX_PACKET, so a transfer never cuts a packet
READ_SIZE: int = ((MAX_PACKET + USB_MPS - 1) // USB_MPS) * USB_MPS

# USB identity (pid.codes test PID; docs/protocol.md section 1)
USB_VID: int = 0x1209
USB_PID: int = 0x0001
EP_OUT: int = 0x01
EP_IN: int = 0x81
INTERFACE_CLASS: int = 0xFF

FRAME_TYPE: int = 0x40
REPLY_BIT: int = 0x80
ERROR_REPLY_TYPE: int = 0xFF  #: reply type when the command header itself was unusable
MAX_TOF_RECORDS: int = 64
MAX_GEO_RECORDS: int = 8


class Opcode(IntEnum):
    DEVICE_INFO = 0x01
    WRITE_REGS = 0x02
    READ_REGS = 0x03
    START = 0x04
    STOP = 0x05
    READ_COUNTERS = 0x06
    CLEAR_COUNTERS = 0x07
    SET_PARAM = 0x08
    GET_PARAM = 0x09
    ECHO = 0x0A
    FW_STATS = 0x0B


class Status(IntEnum):
    OK = 0
    BAD_CRC = 1
    BAD_MAGIC = 2
    BAD_VERSION = 3
    BAD_LENGTH = 4
    UNKNOWN_OPCODE = 5
    BAD_ADDRESS = 6
    CFG_REJECTED = 7
    BUSY = 8
    BAD_PARAM = 9
    NOT_CONFIGURED = 10
    INTERNAL = 11


class Param(IntEnum):
    TEMPERATURE_CC = 1  #: air temperature, centi-degC (signed), for the firmware's geometry
    GEOMETRY = 2  #: 0/1: geometry records in frames
    TOF_RECORDS = 3  #: 0/1: per-receiver ToF records in frames
    MAX_ECHOES = 4  #: in-window edges reported per window (1..15)
    GLITCH_MIN = 5  #: RX_FILTER.glitch_min, ticks (1..255)


#: SET_PARAM's accepted range per parameter, inclusive (else BAD_PARAM)
PARAM_RANGE: dict[Param, tuple[int, int]] = {Param.TEMPERATURE_CC: (-4000, 8000), Param.GEOMETRY: (0, 1),
                                             Param.TOF_RECORDS: (0, 1), Param.MAX_ECHOES: (1, 15),
                                             Param.GLITCH_MIN: (1, 255)}
#: parameters SET_PARAM refuses with BUSY while a table runs (they change the echo path)
PARAM_BUSY_WHILE_RUNNING: frozenset[Param] = frozenset({Param.MAX_ECHOES, Param.GLITCH_MIN})


#: CFG_REJECTED detail: STATUS.cfg_error codes (docs/protocol.md section 5)
class CfgError(IntEnum):
    OK = 0
    EMPTY_TABLE = 1
    BAD_MODE = 2
    TX_MASK = 3
    RX_MASK = 4
    ORDER = 5
    WINDOW = 6
    MISS_LIMIT = 7
    DELAY = 8
    MAX_TOF = 9
    BURST = 10
    LEAD = 11  #: blanking D not longer than the device's decision lead (CAPS / DEVICE_DECISION_LEAD)
    WINDOW_SHORT = 12  #: T_V + T_N not longer than half the decision lead


#: ToF record flags (the event word's bits 40..43 shifted down by 40; TOF_GATED is its bit 45): a
#: gated first echo was rejected by the gated miss rule (docs/fast_firing.md section 4.4), likely
#: another pulse's echo: reported, but no tracking sample and no geometry input
TOF_IN_WINDOW, TOF_FIRST_ECHO, TOF_WINDOW_EMPTY, TOF_INIT_PING, TOF_GATED = 0x1, 0x2, 0x4, 0x8, 0x10
#: the flags of a first echo the geometry uses: in its window, first, not gated
TOF_SAMPLE_MASK, TOF_SAMPLE = TOF_IN_WINDOW | TOF_FIRST_ECHO | TOF_GATED, TOF_IN_WINDOW | TOF_FIRST_ECHO


def tof_record(e: Any) -> tuple[int, int, int, int, int]:
    """A ToF event (``fastfiring.ToFEvent``) as the fields of a :data:`TOF_DTYPE` record, as the
    firmware packs it: tof, rx, seq, vs and the flags byte."""
    flags = (TOF_IN_WINDOW * e.in_window | TOF_FIRST_ECHO * e.first_echo | TOF_WINDOW_EMPTY * e.window_empty
             | TOF_INIT_PING * e.init_ping | TOF_GATED * e.gated)
    return e.tof, e.rx, e.seq, e.sensor, int(flags)
#: frame header flags: init ping, more ToF records than the device keeps, simulated device,
#: event-FIFO words of the pulse lost (no geometry), closed before every window reported,
#: a geometry frame (the records of a pulse whose ToF frame went before; no ToF records)
FRAME_INIT_PING, FRAME_TRUNCATED, FRAME_SIMULATED, FRAME_LOST, FRAME_CUT, FRAME_GEO = 0x1, 0x2, 0x4, 0x8, 0x10, 0x20
#: geometry classes
GEO_CLASSES: tuple[str, ...] = ("none", "edge", "wall", "cylinder", "uncertain")

# --------------------------------------------------------------------------------------
# numpy layouts of frame payloads (little-endian, packed, byte-aligned fields)
# --------------------------------------------------------------------------------------
FRAME_HEAD_DTYPE = np.dtype([
    ("timestamp", "<u4"),  # device tick when the frame was closed (all windows of the pulse done)
    ("t0", "<u4"),  # device tick of the pulse trigger (t0)
    ("vs", "u1"), ("pulse_seq", "u1"), ("n_tof", "u1"), ("n_geo", "u1"),
    ("dropped", "<u4"),  # frames the device dropped (bulk IN not read), since CLEAR_COUNTERS
    ("fifo_overflows", "<u2"),  # event-FIFO overflows (OVERFLOWS.count, low 16 bits)
    ("watchdog", "<u2"),  # watchdog expiries (soft-core / scheduler), low 16 bits
])
TOF_DTYPE = np.dtype([("tof", "<u4"), ("rx", "u1"), ("seq", "u1"), ("vs", "u1"), ("flags", "u1")])
GEO_DTYPE = np.dtype([
    ("x_mm", "<i2"), ("y_mm", "<i2"),  # fix (edge position / wall foot), robot frame, mm
    ("range_mm", "<u2"),  # distance virtual source -> reflector, mm
    ("bearing", "<i2"),  # bearing of the fix from the source, 2*pi/65536 rad (binary angle)
    ("normal", "<i2"),  # wall normal bearing, binary angle (0 for points)
    ("quality", "u1"),  # 255 = perfect fit, 0 = at the acceptance threshold
    ("cls", "u1"),  # index into GEO_CLASSES
    ("n_rx", "u1"), ("reserved", "u1"),
    ("residual_um", "<u2"),  # RMS path misfit, um (saturating)
])
assert FRAME_HEAD_DTYPE.itemsize == 20 and TOF_DTYPE.itemsize == 8 and GEO_DTYPE.itemsize == 16

#: one row per ToF record, frame fields repeated (frames_to_events)
EVENT_DTYPE = np.dtype([("frame_seq", "<u4"), ("timestamp", "<u4"), ("t0", "<u4"), ("vs", "u1"),
                        ("pulse_seq", "u1"), ("rx", "u1"), ("flags", "u1"), ("tof", "<u4")])

INFO = struct.Struct("<HHIBBBBIII")  # proto, max_payload, tick_hz, ch, vs, order, flags, version, build, caps
COUNTERS_FIELDS: tuple[str, ...] = ("frames_sent", "frames_dropped", "events", "pulses", "fifo_overflows",
                                    "watchdog", "bad_commands", "tx_collisions", "timestamp")
COUNTERS = struct.Struct("<" + "I" * len(COUNTERS_FIELDS))
#: FW_STATS reply: the firmware's own counts since CLEAR_COUNTERS (docs/protocol.md section 3):
#: geometry jobs by outcome (a fix; skipped: queue full; declined: only the unbounded general
#: path would solve it; stale: the sensor was re-aimed twice since), ToF frames flagged cut / lost,
#: the ToF path's latency (pulse completion -> frame committed): its maximum in ticks and how
#: many frames took over 1 ms; then the worst cycles of each bounded firmware path
#: (firmware/README.md, "Cycles per path"): one event word (frames it closed excluded), one ToF
#: frame, one geometry job, one re-aim slice, one command while running, the longest slice away
#: from the event FIFO, and the main loop's busy cycles in its busiest 10 ms window
FW_STATS_FIELDS: tuple[str, ...] = ("geo_fixes", "geo_skipped", "geo_declined", "geo_stale", "frames_cut",
                                    "frames_lost", "latency_max_ticks", "latency_over_1ms",
                                    "cycles_word_max", "cycles_frame_max", "cycles_geo_max",
                                    "cycles_reaim_max", "cycles_command_max", "cycles_slice_max",
                                    "busy_window_max")
FW_STATS_MIN_FIELDS: int = 8  #: a device from before the cycle fields answers the first 8
FW_STATS = struct.Struct("<" + "I" * len(FW_STATS_FIELDS))


# --------------------------------------------------------------------------------------
# errors
# --------------------------------------------------------------------------------------
class ProtocolError(ValueError):
    """A packet that does not follow docs/protocol.md; ``field`` names the offending field."""

    status: Status = Status.INTERNAL

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field


class BadMagic(ProtocolError):
    status = Status.BAD_MAGIC


class BadVersion(ProtocolError):
    status = Status.BAD_VERSION


class BadLength(ProtocolError):
    status = Status.BAD_LENGTH


class BadCrc(ProtocolError):
    status = Status.BAD_CRC


class BadField(ProtocolError):
    """A well-framed packet whose content is invalid (type, counts, values)."""

    status = Status.BAD_LENGTH


class DeviceError(RuntimeError):
    """The device answered a command with a non-OK status."""

    def __init__(self, opcode: int, status: int, payload: bytes = b"", detail: str = "") -> None:
        try:
            sname = Status(status).name
        except ValueError:
            sname = f"status {status}"
        try:
            oname = Opcode(opcode).name
        except ValueError:
            oname = f"opcode 0x{opcode:02X}"
        super().__init__(f"device refused {oname}: {sname}" + (f" ({detail})" if detail else ""))
        self.opcode, self.status, self.payload = opcode, status, payload


class CfgRejected(DeviceError):
    """START refused: the device's check of the virtual-sensor table (firmware, at START) failed."""

    def __init__(self, opcode: int, payload: bytes) -> None:
        code = payload[0] if len(payload) > 0 else 0
        vs = payload[1] if len(payload) > 1 else 0
        try:
            cname = CfgError(code).name
        except ValueError:
            cname = f"code {code}"
        super().__init__(opcode, Status.CFG_REJECTED, payload,
                         f"cfg_error {code} = {cname} on virtual sensor {vs}")
        self.cfg_error, self.vs = code, vs


# --------------------------------------------------------------------------------------
# framing
# --------------------------------------------------------------------------------------
def crc32(data: bytes | bytearray | memoryview) -> int:
    """CRC-32/ISO-HDLC (poly 0x04C11DB7 reflected, init and xorout 0xFFFFFFFF) = zlib.crc32."""
    return zlib.crc32(data) & 0xFFFFFFFF


class Packet(NamedTuple):
    magic: bytes
    version: int
    type: int
    flags: int
    status: int
    seq: int
    payload: bytes

    @property
    def is_frame(self) -> bool:
        return self.magic == MAGIC_FRAME

    @property
    def is_reply(self) -> bool:
        return self.magic == MAGIC_REPLY


def encode_packet(magic: bytes, ptype: int, payload: bytes = b"", *, seq: int = 0, flags: int = 0,
                  status: int = 0, version: int = PROTOCOL_VERSION) -> bytes:
    if len(payload) > MAX_PAYLOAD:
        raise BadLength("length", f"payload of {len(payload)} bytes exceeds the maximum {MAX_PAYLOAD}")
    for name, v, hi in (("type", ptype, 0xFF), ("flags", flags, 0xFF), ("status", status, 0xFF),
                        ("version", version, 0xFF), ("seq", seq, 0xFFFFFFFF)):
        if not 0 <= int(v) <= hi:
            raise BadField(name, f"{v} does not fit (0..{hi})")
    body = HEADER.pack(magic, version, ptype, flags, status, len(payload), seq) + bytes(payload)
    return body + struct.pack("<I", crc32(body))


def check_header(buf: bytes | memoryview, *, magics: Sequence[bytes] = MAGICS) -> tuple[int, ...]:
    """Validate a header (first 12 bytes). Returns the unpacked fields; raises on bad magic,
    version or length field."""
    if len(buf) < HEADER_SIZE:
        raise BadLength("header", f"{len(buf)} bytes, a header needs {HEADER_SIZE}")
    magic, version, ptype, flags, status, length, seq = HEADER.unpack_from(buf, 0)
    if magic not in magics:
        raise BadMagic("magic", f"{bytes(magic)!r} is not one of {[m.decode() for m in magics]}")
    if version != PROTOCOL_VERSION:
        raise BadVersion("version", f"protocol version {version}, this side speaks {PROTOCOL_VERSION}")
    if length > MAX_PAYLOAD:
        raise BadLength("length", f"payload length {length} exceeds the maximum {MAX_PAYLOAD}")
    return magic, version, ptype, flags, status, length, seq


def decode_packet(buf: bytes | bytearray | memoryview, *, magics: Sequence[bytes] = MAGICS) -> Packet:
    """Decode exactly one packet; raise a ProtocolError subclass on any mismatch."""
    buf = bytes(buf)
    magic, version, ptype, flags, status, length, seq = check_header(buf, magics=magics)
    want = HEADER_SIZE + length + CRC_SIZE
    if len(buf) != want:
        raise BadLength("length", f"header says {length} payload bytes ({want} in all), got {len(buf)} bytes")
    (crc,) = struct.unpack_from("<I", buf, HEADER_SIZE + length)
    calc = crc32(buf[:HEADER_SIZE + length])
    if crc != calc:
        raise BadCrc("crc", f"0x{crc:08X} received, 0x{calc:08X} computed")
    return Packet(bytes(magic), version, ptype, flags, status, seq, buf[HEADER_SIZE:HEADER_SIZE + length])


@dataclass
class StreamParser:
    """Resynchronising parser for the bulk IN byte stream (replies and frames).

    ``feed(data)`` returns the packets completed by ``data``. On a bad header or CRC it drops
    one byte and searches for the next magic (docs/protocol.md section 7); the dropped bytes
    and events are counted. Buffered bytes never exceed one maximal packet plus one feed.
    """

    magics: tuple[bytes, ...] = (MAGIC_REPLY, MAGIC_FRAME)
    buf: bytearray = field(default_factory=bytearray)
    bad_crc: int = 0
    bad_header: int = 0
    skipped_bytes: int = 0

    def feed(self, data: bytes | bytearray | memoryview) -> list[Packet]:
        self.buf += data
        out: list[Packet] = []
        buf = self.buf
        pos = 0
        n = len(buf)
        while n - pos >= HEADER_SIZE:
            try:
                magic, version, ptype, flags, status, length, seq = check_header(
                    memoryview(buf)[pos:pos + HEADER_SIZE], magics=self.magics)
            except ProtocolError:
                self.bad_header += 1
                pos = self._next_magic(pos + 1)
                continue
            end = pos + HEADER_SIZE + length + CRC_SIZE
            if end > n:
                break
            (crc,) = struct.unpack_from("<I", buf, end - CRC_SIZE)
            if crc != zlib.crc32(memoryview(buf)[pos:end - CRC_SIZE]):
                self.bad_crc += 1
                pos = self._next_magic(pos + 1)
                continue
            out.append(Packet(bytes(magic), version, ptype, flags, status, seq,
                              bytes(buf[pos + HEADER_SIZE:end - CRC_SIZE])))
            pos = end
        del buf[:pos]
        return out

    def _next_magic(self, start: int) -> int:
        buf = self.buf
        best = len(buf)
        for m in self.magics:
            i = buf.find(m, start)
            if i >= 0:
                best = min(best, i)
        if best == len(buf) and buf[-1:] in (m[:1] for m in self.magics):
            best = len(buf) - 1  # a magic may be cut by the end of the buffer
        self.skipped_bytes += best - start + 1
        return best

    def reset(self) -> None:
        if self.buf:
            self.skipped_bytes += len(self.buf)
        self.buf.clear()


# --------------------------------------------------------------------------------------
# commands and replies
# --------------------------------------------------------------------------------------
def encode_command(opcode: int, payload: bytes = b"", *, seq: int = 0, flags: int = 0) -> bytes:
    return encode_packet(MAGIC_COMMAND, int(opcode), payload, seq=seq, flags=flags)


def encode_reply(opcode: int, status: int, payload: bytes = b"", *, seq: int = 0) -> bytes:
    return encode_packet(MAGIC_REPLY, (int(opcode) | REPLY_BIT) & 0xFF, payload, seq=seq, status=int(status))


def write_regs_payload(pairs: Iterable[tuple[int, int]]) -> bytes:
    out = bytearray()
    for a, v in pairs:
        if not 0 <= a <= 0xFFFFFFFF or not 0 <= v <= 0xFFFFFFFF:
            raise BadField("pairs", f"address 0x{a:X} / value 0x{v:X} does not fit 32 bits")
        out += struct.pack("<II", a, v)
    if len(out) > MAX_PAYLOAD:
        raise BadLength("length", f"{len(out) // 8} register writes exceed {MAX_PAYLOAD // 8} per command")
    return bytes(out)


def parse_write_regs(payload: bytes) -> list[tuple[int, int]]:
    if len(payload) % 8:
        raise BadLength("length", f"WRITE_REGS payload of {len(payload)} bytes is not a multiple of 8")
    return [struct.unpack_from("<II", payload, i) for i in range(0, len(payload), 8)]


def read_regs_payload(addrs: Iterable[int]) -> bytes:
    addrs = list(addrs)
    if len(addrs) * 4 > MAX_PAYLOAD:
        raise BadLength("length", f"{len(addrs)} register reads exceed {MAX_PAYLOAD // 4} per command")
    return struct.pack(f"<{len(addrs)}I", *addrs)


def parse_read_regs(payload: bytes) -> list[int]:
    if len(payload) % 4:
        raise BadLength("length", f"READ_REGS payload of {len(payload)} bytes is not a multiple of 4")
    return list(struct.unpack(f"<{len(payload) // 4}I", payload))


def set_param_payload(param: int, value: int) -> bytes:
    return struct.pack("<HHi", int(param), 0, int(value))


def parse_set_param(payload: bytes) -> tuple[int, int]:
    if len(payload) != 8:
        raise BadLength("length", f"SET_PARAM payload must be 8 bytes, got {len(payload)}")
    p, _, v = struct.unpack("<HHi", payload)
    return p, v


def parse_get_param(payload: bytes) -> int:
    if len(payload) != 2:
        raise BadLength("length", f"GET_PARAM payload must be 2 bytes, got {len(payload)}")
    return struct.unpack("<H", payload)[0]


@dataclass(frozen=True)
class DeviceInfo:
    protocol_version: int
    max_payload: int
    tick_hz: int
    channels: int
    max_vs: int
    max_order: int
    flags: int  #: bit 0: simulated device
    version_reg: int  #: VERSION register: regmap << 16 | major << 8 | minor
    build_id: int
    caps_reg: int  #: CAPS register

    @property
    def regmap_revision(self) -> int:
        return (self.version_reg >> 16) & 0xFF

    @property
    def gateware_version(self) -> str:
        return f"{(self.version_reg >> 8) & 0xFF}.{self.version_reg & 0xFF}"

    @property
    def simulated(self) -> bool:
        return bool(self.flags & 1)

    @property
    def win_slots(self) -> int:
        """Window-reservation slots per element (CAPS.win_slots: the scheduler's WSLOTS, what
        :class:`multisonar.fastfiring.FastFiringModel` takes as ``win_slots``); gateware that
        predates the field reads 0 there and has 16."""
        return (self.caps_reg >> 24) & 0xFF or 16

    def encode(self) -> bytes:
        return INFO.pack(self.protocol_version, self.max_payload, self.tick_hz, self.channels, self.max_vs,
                         self.max_order, self.flags, self.version_reg, self.build_id, self.caps_reg)

    @classmethod
    def decode(cls, payload: bytes) -> "DeviceInfo":
        if len(payload) != INFO.size:
            raise BadLength("length", f"DEVICE_INFO reply payload must be {INFO.size} bytes, got {len(payload)}")
        return cls(*INFO.unpack(payload))


def encode_counters(values: dict[str, int]) -> bytes:
    return COUNTERS.pack(*(int(values.get(k, 0)) & 0xFFFFFFFF for k in COUNTERS_FIELDS))


def encode_fw_stats(values: dict[str, int]) -> bytes:
    return FW_STATS.pack(*(int(values.get(k, 0)) & 0xFFFFFFFF for k in FW_STATS_FIELDS))


def decode_fw_stats(payload: bytes) -> dict[str, int]:
    """The fields the reply carries: at least FW_STATS_MIN_FIELDS; words beyond the known fields
    (a newer device) are ignored."""
    n = len(payload) // 4
    if len(payload) % 4 or n < FW_STATS_MIN_FIELDS:
        raise BadLength("length", f"FW_STATS reply payload must be a multiple of 4 bytes, at least "
                                  f"{4 * FW_STATS_MIN_FIELDS}, got {len(payload)}")
    n = min(n, len(FW_STATS_FIELDS))
    return dict(zip(FW_STATS_FIELDS, struct.unpack_from("<" + "I" * n, payload)))


def decode_counters(payload: bytes) -> dict[str, int]:
    if len(payload) != COUNTERS.size:
        raise BadLength("length", f"READ_COUNTERS reply payload must be {COUNTERS.size} bytes, got {len(payload)}")
    return dict(zip(COUNTERS_FIELDS, COUNTERS.unpack(payload)))


# --------------------------------------------------------------------------------------
# frames
# --------------------------------------------------------------------------------------
@dataclass
class Frame:
    """One decoded frame: the results of one pulse of one virtual sensor."""

    seq: int  #: device frame counter (u32, +1 per frame produced, dropped ones included)
    flags: int
    head: np.void  #: FRAME_HEAD_DTYPE record
    tof: np.ndarray  #: TOF_DTYPE records
    geo: np.ndarray  #: GEO_DTYPE records
    payload: bytes = b""  #: the frame's payload (tof and geo are views into it)
    #: set by the driver (multisonar.clock): t0 extended to 64 bits, and the host time
    #: (time.time_ns epoch) of t0 mapped from device ticks (None before the first sync)
    t0_ticks: int | None = None
    stamp_ns: int | None = None

    def packet(self) -> bytes:
        """The frame's wire bytes (header + payload + CRC), e.g. for recording."""
        return encode_packet(MAGIC_FRAME, FRAME_TYPE, self.payload, seq=self.seq, flags=self.flags)

    @property
    def timestamp(self) -> int:
        return int(self.head["timestamp"])

    @property
    def t0(self) -> int:
        return int(self.head["t0"])

    @property
    def vs(self) -> int:
        return int(self.head["vs"])

    @property
    def pulse_seq(self) -> int:
        return int(self.head["pulse_seq"])

    @property
    def is_geometry(self) -> bool:
        """A geometry frame: the records of a pulse whose ToF frame came earlier."""
        return bool(self.flags & FRAME_GEO)


def encode_frame(seq: int, head: dict | np.void, tof: np.ndarray | None = None, geo: np.ndarray | None = None,
                 *, flags: int = 0) -> bytes:
    tof = np.zeros(0, TOF_DTYPE) if tof is None else np.ascontiguousarray(tof, dtype=TOF_DTYPE)
    geo = np.zeros(0, GEO_DTYPE) if geo is None else np.ascontiguousarray(geo, dtype=GEO_DTYPE)
    if len(tof) > MAX_TOF_RECORDS or len(geo) > MAX_GEO_RECORDS:
        raise BadField("n_tof" if len(tof) > MAX_TOF_RECORDS else "n_geo",
                       f"{len(tof)} ToF / {len(geo)} geometry records, max {MAX_TOF_RECORDS} / {MAX_GEO_RECORDS}")
    if len(tof) and int(tof["tof"].max()) >= 1 << 24:
        raise BadField("tof", "time of flight does not fit 24 bits")
    h = np.zeros((), FRAME_HEAD_DTYPE)
    for k in FRAME_HEAD_DTYPE.names:
        if k not in ("n_tof", "n_geo"):
            h[k] = head[k]
    h["n_tof"], h["n_geo"] = len(tof), len(geo)
    return encode_packet(MAGIC_FRAME, FRAME_TYPE, h.tobytes() + tof.tobytes() + geo.tobytes(), seq=seq, flags=flags)


def decode_frame(p: Packet) -> Frame:
    """Frame contents of a packet already checked by decode_packet/StreamParser."""
    if p.magic != MAGIC_FRAME or p.type != FRAME_TYPE:
        raise BadField("type", f"packet {p.magic!r} type 0x{p.type:02X} is not a frame (MF, 0x{FRAME_TYPE:02X})")
    pl = p.payload
    hs = FRAME_HEAD_DTYPE.itemsize
    if len(pl) < hs:
        raise BadLength("length", f"frame payload of {len(pl)} bytes is shorter than its {hs}-byte header")
    head = np.frombuffer(pl, FRAME_HEAD_DTYPE, count=1)[0]
    nt, ng = int(head["n_tof"]), int(head["n_geo"])
    if nt > MAX_TOF_RECORDS:
        raise BadField("n_tof", f"{nt} ToF records, at most {MAX_TOF_RECORDS}")
    if ng > MAX_GEO_RECORDS:
        raise BadField("n_geo", f"{ng} geometry records, at most {MAX_GEO_RECORDS}")
    want = hs + nt * TOF_DTYPE.itemsize + ng * GEO_DTYPE.itemsize
    if len(pl) != want:
        raise BadLength("length", f"frame with {nt} ToF and {ng} geometry records needs {want} payload bytes, "
                                  f"got {len(pl)}")
    tof = np.frombuffer(pl, TOF_DTYPE, count=nt, offset=hs)
    geo = np.frombuffer(pl, GEO_DTYPE, count=ng, offset=hs + nt * TOF_DTYPE.itemsize)
    if nt and int(tof["tof"].max()) >= 1 << 24:
        raise BadField("tof", "time of flight has bits above 23 set")
    if ng and int(geo["cls"].max()) >= len(GEO_CLASSES):
        raise BadField("cls", f"geometry class {int(geo['cls'].max())} unknown (0..{len(GEO_CLASSES) - 1})")
    return Frame(p.seq, p.flags, head, tof, geo, pl)


def frames_to_events(frames: Sequence[Frame]) -> np.ndarray:
    """Flat table of every ToF record (EVENT_DTYPE), frame fields repeated."""
    n = sum(len(f.tof) for f in frames)
    out = np.zeros(n, EVENT_DTYPE)
    i = 0
    for f in frames:
        k = len(f.tof)
        if not k:
            continue
        sl = out[i:i + k]
        sl["frame_seq"], sl["timestamp"], sl["t0"] = f.seq, f.timestamp, f.t0
        sl["vs"], sl["pulse_seq"] = f.vs, f.pulse_seq
        sl["rx"], sl["flags"], sl["tof"] = f.tof["rx"], f.tof["flags"], f.tof["tof"]
        i += k
    return out


def frames_to_geometry(frames: Sequence[Frame]) -> np.ndarray:
    """Flat table of geometry records with frame_seq, t0 and vs prepended."""
    dt = np.dtype([("frame_seq", "<u4"), ("t0", "<u4"), ("vs", "u1")] + [(n, GEO_DTYPE[n]) for n in GEO_DTYPE.names])
    rows = [(f, g) for f in frames for g in f.geo]
    out = np.zeros(len(rows), dt)
    for i, (f, g) in enumerate(rows):
        out[i]["frame_seq"], out[i]["t0"], out[i]["vs"] = f.seq, f.t0, f.vs
        for n in GEO_DTYPE.names:
            out[i][n] = g[n]
    return out


def binary_angle(rad: float) -> int:
    """Radians -> signed 16-bit binary angle (2*pi/65536 per LSB)."""
    import math

    v = int(round(rad / (2 * math.pi) * 65536)) & 0xFFFF
    return v - 65536 if v >= 32768 else v


def from_binary_angle(v: int | np.ndarray) -> float | np.ndarray:
    import math

    return np.asarray(v, dtype=np.float64) * (2 * math.pi / 65536)
