"""The simulated Multisonar device: protocol v1 (docs/protocol.md) on top of the golden model.

:class:`SimDevice` is a :class:`~multisonar.usb.function.UsbFunction` (descriptors + endpoint
callbacks), so the same object is served in-process (``sim://SCENE``) or over USB/IP
(``multisonar.usb.usbip_server``) to the unchanged pyusb driver.

Behind the endpoints it does what the board does:

* the board's USB descriptors byte for byte (:mod:`multisonar.usb.descriptors`: device, BOS,
  MS OS 2.0 set, strings; ``serial`` is the board's serial number);
* at power-up the registers hold the firmware's compiled-in table (``power_up_table``, default
  the board image's ``"scene"``, :func:`multisonar.tools.fw_schedule.power_up_writes`) and its
  temperature: START runs it unless WRITE_REGS replaced it (``power_up_table=None``: all
  sensors off, START refused with EMPTY_TABLE);
* a register file with the sonar core's map (``multisonar.generated.sonar_regs``): WRITE_REGS /
  READ_REGS work on it with the board's address checks;
* START decodes the virtual-sensor table **from the registers** (VS_* registers and the DELAY
  memory, exactly as the firmware checks and loads them), checks it (``CfgError`` codes, reported
  as CFG_REJECTED), and runs the tick-exact :class:`~multisonar.fastfiring.FastFiringModel` on
  the acoustic model of the scene (:class:`~multisonar.fastfiring.SceneEchoSource`);
* every pulse becomes one frame once its last window has closed: the pulse's ToF records and,
  with three or more first echoes, one geometry record (:func:`multisonar.geometry.classify`);
* frames wait in a bounded queue (``queue_frames``); when the host does not read, new frames
  are dropped and counted (READ_COUNTERS.frames_dropped, ``dropped`` in every frame, and a
  gap in the frame sequence numbers).

Time: with ``rate=None`` (default) the simulation is in lock-step with the host: sonar time
advances only while the host waits for data and nothing is queued, so nothing is ever dropped
and throughput is limited by the model. With ``rate=r`` sonar time follows the wall clock
(r x real time): frames the host does not fetch in time are dropped, as on the board.
``source="replay"`` replays a model run of ``replay_s`` seconds in a loop (timestamps keep
increasing), a fast frame source for transport benchmarks and overflow tests.

Malformed commands are answered with an error status (never a hang); every command has
exactly one reply.
"""

from __future__ import annotations

import heapq
import itertools
import struct
import threading
import time
import zlib
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import protocol as P
from .constants import TICK_HZ, speed_of_sound, DEVICE_DECISION_LEAD
from .usb.descriptors import DEFAULT_SERIAL, multisonar_descriptors
from .usb.function import Disconnected, Stall, UsbFunction, UsbTimeout
from .errors import DeviceNotFound
from .urls import DeviceUrl, Model, register_scheme

TIMESTAMP_MASK = 0xFFFFFFFF


def _regs():
    from .generated import sonar_regs

    return sonar_regs


# ------------------------------------------------------------------------------------------
# register file
# ------------------------------------------------------------------------------------------
class RegisterFile:
    """Sonar-core CSRs by byte address. Reset values from the generated map."""

    #: registers the firmware owns (START / STOP / CLEAR_COUNTERS, its verdict in STATUS), not
    #: writable by WRITE_REGS
    DECODER_OWNED = ("CTRL", "STATUS")
    #: the scheduler's load port, the firmware's alone: neither readable nor writable over USB
    FIRMWARE_ONLY = ("LOAD_ADDR", "LOAD_DATA")

    def __init__(self) -> None:
        R = _regs()
        self.values: dict[int, int] = {}
        self.writable_mask: dict[int, int] = {}
        self.names: dict[int, str] = {}
        self.hidden: set[int] = set()
        for reg in R.REGISTERS.values():
            idxs = itertools.product(*(range(n) for n in reg.dims)) if reg.dims else [()]
            wmask = 0
            for f in reg.fields.values():
                if "w" in f.sw:
                    wmask |= f.mask
            for ix in idxs:
                a = reg.addr(*ix)
                self.values[a] = reg.reset
                self.names[a] = reg.name + ("[" + ",".join(map(str, ix)) + "]" if ix else "")
                if reg.name in self.FIRMWARE_ONLY:
                    self.hidden.add(a)
                elif wmask and reg.name not in self.DECODER_OWNED:
                    self.writable_mask[a] = wmask
        from .schedule import DELAY_W

        #: memory entries last written with bits beyond what the RTL stores (DELAY: DELAY_W =
        #: 16 bits of the 32-bit word, rtl/ms_csr.sv); START refuses them (CfgError.DELAY)
        self.over_width: set[int] = set()
        self.mem_entries: set[int] = set()
        for mem in R.MEMORIES.values():
            width = DELAY_W if mem.name == "DELAY" else mem.width
            for i in range(mem.entries):
                a = mem.address + i * mem.stride
                self.values[a] = 0
                self.names[a] = f"{mem.name}[{i}]"
                self.writable_mask[a] = (1 << width) - 1
                self.mem_entries.add(a)

    def readable(self, addr: int) -> bool:
        return addr in self.values and addr not in self.hidden

    def writable(self, addr: int) -> bool:
        return addr in self.writable_mask

    def write(self, addr: int, value: int) -> None:
        """A bus write of a writable address (the caller checks :meth:`writable`): its writable
        bits; a memory entry keeps the bits the RTL stores and remembers an over-wide write."""
        m = self.writable_mask[addr]
        self.values[addr] = (self.values[addr] & ~m) | (value & m)
        if addr in self.mem_entries:  # an overflow is refused at START
            (self.over_width.add if value & ~m else self.over_width.discard)(addr)

    def get(self, name: str, *index: int) -> int:
        return self.values[_regs().REGISTERS[name].addr(*index)]

    def field(self, name: str, fld: str, *index: int) -> int:
        return _regs().REGISTERS[name].fields[fld].get(self.get(name, *index))

    def set_hw(self, name: str, value: int, *index: int) -> None:
        self.values[_regs().REGISTERS[name].addr(*index)] = value & 0xFFFFFFFF


class _CfgErr(Exception):
    def __init__(self, code: P.CfgError, vs: int, why: str) -> None:
        super().__init__(f"virtual sensor {vs}: {why}")
        self.code, self.vs = code, vs


def decode_vs_table(regs: RegisterFile, layout: Any) -> list[Any]:
    """The virtual-sensor table as the firmware checks and loads it: ResolvedSensor per enabled
    entry (mode != 0), ids = table index. Raises _CfgErr with the cfg_error code."""
    from .schedule import DELAY_W, MAX_ORDER, MODE_CODE, ResolvedSensor, _adjacent_run, _xtalk

    R = _regs()
    n_vs = R.REGISTERS["VS_MODE"].dims[0]
    n_el = layout.n
    code_mode = {v: k for k, v in MODE_CODE.items()}
    mem = R.MEMORIES["DELAY"]
    # first (as the firmware, before the scheduler validates: the RTL never sees the lost bits):
    # an enabled entry whose tx element's DELAY word was written wider than DELAY_W bits
    for vs in range(n_vs):
        tx_mask = regs.field("VS_TX_MASK", "MASK", vs)
        over = [e for e in range(32) if tx_mask >> e & 1 and mem.address + (vs * 32 + e) * mem.stride in regs.over_width]
        if regs.field("VS_MODE", "MODE", vs) != 0 and over:
            raise _CfgErr(P.CfgError.DELAY, vs, f"phasing delay of tx element {over[0]} written >= 2^{DELAY_W} "
                          f"ticks (the DELAY memory keeps {DELAY_W} bits)")
    out = []
    for vs in range(n_vs):
        mode_code = regs.field("VS_MODE", "MODE", vs)
        if mode_code == 0:
            continue
        if mode_code not in code_mode:
            raise _CfgErr(P.CfgError.BAD_MODE, vs, f"mode code {mode_code}")
        tx_mask, rx_mask = regs.field("VS_TX_MASK", "MASK", vs), regs.field("VS_RX_MASK", "MASK", vs)
        tx_el = [e for e in range(24) if tx_mask >> e & 1]
        rx_el = [e for e in range(24) if rx_mask >> e & 1]
        if not tx_el or max(tx_el) >= n_el:
            raise _CfgErr(P.CfgError.TX_MASK, vs, f"tx mask 0x{tx_mask:06X} empty or beyond the layout")
        tx = _adjacent_run(tx_el, n_el)
        if tx is None:
            raise _CfgErr(P.CfgError.TX_MASK, vs, f"tx mask 0x{tx_mask:06X} is not one adjacent run")
        if not rx_el or max(rx_el) >= n_el:
            raise _CfgErr(P.CfgError.RX_MASK, vs, f"rx mask 0x{rx_mask:06X} empty or beyond the layout")
        order = regs.field("VS_MODE", "ORDER", vs)
        if order > MAX_ORDER:
            raise _CfgErr(P.CfgError.ORDER, vs, f"order {order} > {MAX_ORDER}")
        miss = regs.field("VS_MODE", "MISS_LIMIT", vs)
        if miss < 1:
            raise _CfgErr(P.CfgError.MISS_LIMIT, vs, "miss limit 0")
        t_v, t_n = regs.field("VS_WINDOW", "T_V", vs), regs.field("VS_WINDOW", "T_N", vs)
        t_dead = regs.field("VS_T_DEAD", "TICKS", vs)
        t_xt, nb = regs.field("VS_XTALK", "T_XTALK", vs), regs.field("VS_XTALK", "NB", vs)
        max_tof = regs.field("VS_MAX_TOF", "TICKS", vs)
        vmax, burst = regs.field("VS_TRACK", "VMAX", vs), regs.field("VS_TRACK", "BURST_CYCLES", vs)
        phase = regs.field("VS_PHASE", "TICKS", vs)
        if burst < 1:
            raise _CfgErr(P.CfgError.BURST, vs, "burst of 0 cycles")
        # the drive burst as the phaser makes it: cycles of 2 x BURST.half_period ticks (the RTL's
        # validation uses the register, not the layout's transducer frequency)
        burst_ticks = burst * 2 * regs.field("BURST", "HALF_PERIOD")
        if t_v < 1 or t_n < 1 or t_dead < burst_ticks or t_xt < 1:
            raise _CfgErr(P.CfgError.WINDOW, vs, f"T_V={t_v} T_N={t_n} T_dead={t_dead} T_xtalk={t_xt} ticks")
        d_addr = [mem.address + (vs * 32 + int(e)) * mem.stride for e in tx]
        delays = np.array([regs.values[a] for a in d_addr], dtype=np.int64)
        assert delays.max() < 2**DELAY_W  # stored as the RTL: the low DELAY_W bits (over-wide: refused above)
        xt_el, xt_d = _xtalk(tx, delays, nb, n_el)
        blank = max(t_dead, t_xt) + int(delays.max())
        if max_tof - t_n < blank + t_v:
            raise _CfgErr(P.CfgError.MAX_TOF, vs, f"no window after the blanking: MAX_TOF={max_tof}, D={blank}")
        if blank <= DEVICE_DECISION_LEAD:
            raise _CfgErr(P.CfgError.LEAD, vs, f"blanking D={blank} ticks not longer than the decision lead "
                                               f"{DEVICE_DECISION_LEAD}")
        if t_v + t_n <= DEVICE_DECISION_LEAD // 2:
            raise _CfgErr(P.CfgError.WINDOW_SHORT, vs, f"window T_V + T_N = {t_v + t_n} ticks not longer than half "
                                                       f"the decision lead, {DEVICE_DECISION_LEAD // 2}")
        out.append(ResolvedSensor(
            id=vs, name=f"vs{vs}", tx=tx, rx=np.array(rx_el, dtype=np.int64), delays=delays, order=order,
            t_v=t_v, t_n=t_n, t_dead=t_dead, t_xtalk=t_xt, xtalk_neighbours=nb, xtalk_elements=xt_el,
            xtalk_delays=xt_d, blank=blank, max_tof=max_tof, miss_limit=miss, mode=code_mode[mode_code],
            burst_cycles=burst, burst_ticks=burst_ticks, vmax=vmax, phase=phase, nominal_tof=None,
            source=(0.0, 0.0), reinit_every=regs.field("VS_MODE", "REINIT_EVERY", vs)))
    if not out:
        raise _CfgErr(P.CfgError.EMPTY_TABLE, 0, "no virtual sensor enabled (all modes 0)")
    return out


def _schedule_from_resolved(layout: Any, resolved: list[Any], temperature_c: float) -> Any:
    """A Schedule whose validate() returns the register-decoded table (what the model runs)."""
    from .schedule import Schedule

    class _DecodedSchedule(Schedule):
        def validate(self):  # noqa: D401 - the table was checked by decode_vs_table
            self._resolved = list(resolved)
            return self._resolved

    return _DecodedSchedule(layout, [], temperature_c, check_plan=False)


# ------------------------------------------------------------------------------------------
# frame production
# ------------------------------------------------------------------------------------------
@dataclass
class _OpenPulse:
    pulse: Any
    close: int
    events: list = field(default_factory=list)


@dataclass
class _FrameContent:
    timestamp: int  # absolute ticks (unwrapped)
    t0: int
    vs: int
    pulse_seq: int
    init: bool
    tof: np.ndarray
    geo: np.ndarray
    truncated: bool = False  # more events than MAX_TOF_RECORDS


class SimDevice(UsbFunction):
    """Simulated Multisonar on the golden model. See the module docstring."""

    def __init__(self, scene: str = "corridor", *, rate: float | None = None, queue_frames: int = 256,
                 source: str = "model", replay_s: float = 0.25, seed: int | None = None, serial: int = DEFAULT_SERIAL,
                 build_id: int | None = None, power_up_table: str | None = "scene") -> None:
        from ._version import __version__

        if source not in ("model", "replay"):
            raise ValueError(f"source must be 'model' or 'replay', got {source!r}")
        if rate is not None and not rate > 0:
            raise ValueError(f"rate must be > 0 (x real time) or None (lock-step), got {rate!r}")
        if queue_frames < 1:
            raise ValueError(f"queue_frames must be >= 1, got {queue_frames}")
        super().__init__(multisonar_descriptors(serial))  # the board's, byte for byte
        from .scene import load_scene

        self.scene_name = scene
        self.scene = load_scene(scene) if seed is None else load_scene(scene, seed=seed)
        self.layout = self.scene.layout
        self.rate, self.queue_frames, self.source_kind, self.replay_s = rate, int(queue_frames), source, replay_s
        self.build_id = build_id if build_id is not None else zlib.crc32(f"sim {__version__}".encode()) & 0xFFFFFFFF
        self.lock = threading.RLock()
        self.regs = RegisterFile()
        self.power_up_table = power_up_table
        temperature_cc = int(round(self.scene.temperature_c * 100))
        if power_up_table:  # as the firmware's boot: the compiled-in table into the registers
            from .tools.fw_schedule import TEMPERATURE_C, power_up_writes

            for a, v in power_up_writes(power_up_table, self.layout):
                self.regs.write(a, v)
            temperature_cc = int(round(TEMPERATURE_C * 100))
        self.params = {P.Param.TEMPERATURE_CC: temperature_cc, P.Param.GEOMETRY: 1,
                       P.Param.TOF_RECORDS: 1, P.Param.MAX_ECHOES: 1,
                       P.Param.GLITCH_MIN: self.regs.field("RX_FILTER", "GLITCH_MIN")}
        self.replies: deque[bytes] = deque(maxlen=16)
        self.frames: deque[bytes] = deque()
        self._pending_in = b""  # rest of a packet read with a short buffer
        self.frame_seq = 0
        self.counters = dict.fromkeys(P.COUNTERS_FIELDS, 0)
        self.geo_fixes = 0  # geometry records made (FW_STATS)
        self.running = False
        self.closed = False
        self.now = 0  # device tick (unwrapped)
        self.model: Any = None
        self.resolved: list[Any] = []
        self._by_id: dict[int, Any] = {}
        self._open: dict[tuple[int, int], _OpenPulse] = {}
        self._closing: list[tuple[int, int, tuple[int, int]]] = []
        self._ctr = itertools.count()
        self._ready: list[_FrameContent] = []  # produced, not yet queued (model mode)
        self._replay: list[_FrameContent] | None = None
        self._replay_pos = 0
        self._replay_base = 0
        self._wall0 = 0.0
        self._tick0 = 0

    # -- USB endpoints ----------------------------------------------------------------------
    def bulk_out(self, ep: int, data: bytes) -> None:
        if ep != P.EP_OUT:
            raise Stall(f"no OUT endpoint 0x{ep:02X}")
        with self.lock:
            if self.closed:
                raise Disconnected("simulated device closed")
            self._catch_up()
            self.replies.append(self.handle_command(bytes(data)))

    def bulk_in(self, ep: int, length: int, timeout_s: float) -> bytes:
        if ep != P.EP_IN:
            raise Stall(f"no IN endpoint 0x{ep:02X}")
        deadline = time.monotonic() + max(timeout_s, 0.0)
        while True:
            with self.lock:
                if self.closed:
                    raise Disconnected("simulated device closed")
                if not self._pending_in:
                    self._catch_up()
                    if self.replies:
                        self._pending_in = self.replies.popleft()
                    elif self.frames:
                        self._pending_in = self.frames.popleft()
                    elif self.running and self.rate is None:
                        self._produce_lockstep(budget_s=min(0.05, max(deadline - time.monotonic(), 0.002)))
                        if self.frames:
                            self._pending_in = self.frames.popleft()
                if self._pending_in:
                    out, self._pending_in = self._pending_in[:length], self._pending_in[length:]
                    return out
            if time.monotonic() >= deadline:
                raise UsbTimeout("no data (device NAK) within the timeout")
            time.sleep(0.0005 if self.running else 0.002)

    def reset(self) -> None:
        with self.lock:
            super().reset()
            self._pending_in = b""
            self.replies.clear()

    def close(self) -> None:
        with self.lock:
            self.closed = True
            self.running = False

    # -- commands -------------------------------------------------------------------------
    def handle_command(self, data: bytes) -> bytes:
        """One command transfer -> one reply packet (never raises)."""
        try:
            return self._handle(data)
        except Exception as e:  # a bug must still give the host an answer, not a hang
            self.counters["bad_commands"] += 1
            return P.encode_reply(P.ERROR_REPLY_TYPE & 0x7F, P.Status.INTERNAL, repr(e).encode()[:P.MAX_PAYLOAD])

    def _handle(self, data: bytes) -> bytes:
        def fail(op: int, st: P.Status, seq: int = 0, payload: bytes = b"") -> bytes:
            self.counters["bad_commands"] += 1
            return P.encode_packet(P.MAGIC_REPLY, op, payload, seq=seq, status=st)

        err = P.ERROR_REPLY_TYPE
        if len(data) < P.HEADER_SIZE + P.CRC_SIZE:
            return fail(err, P.Status.BAD_LENGTH)
        magic, ver, op, flags, _st, length, seq = P.HEADER.unpack_from(data, 0)
        if magic != P.MAGIC_COMMAND:
            return fail(err, P.Status.BAD_MAGIC, seq)
        if ver != P.PROTOCOL_VERSION:
            return fail(err, P.Status.BAD_VERSION, seq, bytes([P.PROTOCOL_VERSION]))
        rop = (op | P.REPLY_BIT) & 0xFF
        if length > P.MAX_PAYLOAD or len(data) != P.HEADER_SIZE + length + P.CRC_SIZE:
            return fail(rop, P.Status.BAD_LENGTH, seq)
        (crc,) = struct.unpack_from("<I", data, P.HEADER_SIZE + length)
        if crc != P.crc32(data[:P.HEADER_SIZE + length]):
            return fail(rop, P.Status.BAD_CRC, seq)
        payload = data[P.HEADER_SIZE:P.HEADER_SIZE + length]
        try:
            opcode = P.Opcode(op)
        except ValueError:
            return fail(rop, P.Status.UNKNOWN_OPCODE, seq)
        handler = getattr(self, f"_cmd_{opcode.name.lower()}")
        st, out = handler(payload)
        if st != P.Status.OK:
            self.counters["bad_commands"] += 1
        return P.encode_packet(P.MAGIC_REPLY, rop, out, seq=seq, status=st)

    def _cmd_device_info(self, pl: bytes) -> tuple[P.Status, bytes]:
        if pl:
            return P.Status.BAD_LENGTH, b""
        caps = self.regs.get("CAPS")
        R = _regs()
        f = R.REGISTERS["CAPS"].fields
        info = P.DeviceInfo(P.PROTOCOL_VERSION, P.MAX_PAYLOAD, self.regs.get("TICK_HZ"), f["NUM_CH"].get(caps),
                            f["NUM_VS"].get(caps), f["MAX_ORDER"].get(caps), 1, self.regs.get("VERSION"),
                            self.build_id, caps)
        return P.Status.OK, info.encode()

    def _cmd_write_regs(self, pl: bytes) -> tuple[P.Status, bytes]:
        if len(pl) % 8:
            return P.Status.BAD_LENGTH, b""
        if self.running:
            return P.Status.BUSY, b""
        for i, (a, v) in enumerate(P.parse_write_regs(pl)):
            if not self.regs.writable(a):
                return P.Status.BAD_ADDRESS, struct.pack("<HHI", i, 0, a)
            self.regs.write(a, v)
            if a == _regs().REGISTERS["RX_FILTER"].addr():  # GLITCH_MIN is RX_FILTER.glitch_min (as the firmware)
                self.params[P.Param.GLITCH_MIN] = self.regs.field("RX_FILTER", "GLITCH_MIN")
        return P.Status.OK, struct.pack("<H", len(pl) // 8)

    def _cmd_read_regs(self, pl: bytes) -> tuple[P.Status, bytes]:
        if len(pl) % 4:
            return P.Status.BAD_LENGTH, b""
        self._refresh_status_regs()
        vals = []
        for i, a in enumerate(P.parse_read_regs(pl)):
            if not self.regs.readable(a):
                return P.Status.BAD_ADDRESS, struct.pack("<HHI", i, 0, a)
            vals.append(self.regs.values[a])
        return P.Status.OK, struct.pack(f"<{len(vals)}I", *vals)

    def _refresh_status_regs(self) -> None:
        R = _regs()
        st = R.REGISTERS["STATUS"]
        v = self.regs.get("STATUS")
        v = st.fields["RUNNING"].put(v, int(self.running))
        v = st.fields["FIFO_LEVEL"].put(v, min(len(self.frames), 4095))
        self.regs.set_hw("STATUS", v)
        self.regs.set_hw("OVERFLOWS", self.counters["fifo_overflows"])
        self.regs.set_hw("EVENTS", self.counters["events"])
        self.regs.set_hw("PULSES", self.counters["pulses"])
        self.regs.set_hw("TX_COLLISIONS", self.counters["tx_collisions"])

    def _cmd_start(self, pl: bytes) -> tuple[P.Status, bytes]:
        if pl:
            return P.Status.BAD_LENGTH, b""
        if self.running:
            return P.Status.BUSY, b""
        R = _regs()
        st = R.REGISTERS["STATUS"]
        try:
            resolved = decode_vs_table(self.regs, self.layout)
        except _CfgErr as e:
            v = st.fields["CFG_ERROR"].put(self.regs.get("STATUS"), int(e.code))
            self.regs.set_hw("STATUS", st.fields["CFG_ERROR_VS"].put(v, e.vs))
            return P.Status.CFG_REJECTED, bytes([int(e.code), e.vs])
        v = st.fields["CFG_ERROR"].put(self.regs.get("STATUS"), 0)
        self.regs.set_hw("STATUS", st.fields["CFG_ERROR_VS"].put(v, 0))
        self._start(resolved)
        return P.Status.OK, struct.pack("<I", self.frame_seq)

    def _cmd_stop(self, pl: bytes) -> tuple[P.Status, bytes]:
        if pl:
            return P.Status.BAD_LENGTH, b""
        self.running = False
        self._ready.clear()
        return P.Status.OK, struct.pack("<I", self.frame_seq)

    def _cmd_read_counters(self, pl: bytes) -> tuple[P.Status, bytes]:
        if pl:
            return P.Status.BAD_LENGTH, b""
        c = dict(self.counters)
        c["timestamp"] = self.now & TIMESTAMP_MASK
        return P.Status.OK, P.encode_counters(c)

    def _cmd_clear_counters(self, pl: bytes) -> tuple[P.Status, bytes]:
        if pl:
            return P.Status.BAD_LENGTH, b""
        for k in self.counters:
            self.counters[k] = 0
        self.geo_fixes = 0
        return P.Status.OK, b""

    def _cmd_fw_stats(self, pl: bytes) -> tuple[P.Status, bytes]:
        """The model computes every fix (host geometry, no budget) and closes every pulse when
        its windows have: nothing skipped, declined, cut or late."""
        if pl:
            return P.Status.BAD_LENGTH, b""
        return P.Status.OK, P.encode_fw_stats({"geo_fixes": self.geo_fixes})

    def _cmd_set_param(self, pl: bytes) -> tuple[P.Status, bytes]:
        if len(pl) != 8:
            return P.Status.BAD_LENGTH, b""
        pid, value = P.parse_set_param(pl)
        try:
            param = P.Param(pid)
        except ValueError:
            return P.Status.BAD_PARAM, pl
        lo, hi = P.PARAM_RANGE[param]
        if not lo <= value <= hi:
            return P.Status.BAD_PARAM, pl
        if self.running and param in P.PARAM_BUSY_WHILE_RUNNING:
            return P.Status.BUSY, pl
        self.params[param] = value
        if param is P.Param.GLITCH_MIN:
            R = _regs()
            self.regs.set_hw("RX_FILTER", R.REGISTERS["RX_FILTER"].fields["GLITCH_MIN"].put(self.regs.get("RX_FILTER"), value))
        return P.Status.OK, pl

    def _cmd_get_param(self, pl: bytes) -> tuple[P.Status, bytes]:
        if len(pl) != 2:
            return P.Status.BAD_LENGTH, b""
        pid = P.parse_get_param(pl)
        try:
            param = P.Param(pid)
        except ValueError:
            return P.Status.BAD_PARAM, pl
        return P.Status.OK, P.set_param_payload(param, self.params[param])

    def _cmd_echo(self, pl: bytes) -> tuple[P.Status, bytes]:
        return P.Status.OK, pl

    # -- running ----------------------------------------------------------------------------
    def _start(self, resolved: list[Any]) -> None:
        from .fastfiring import FastFiringModel, SceneEchoSource

        self.resolved = resolved
        self._by_id = {r.id: r for r in resolved}
        self.counters["frames_dropped"] += len(self.frames)  # undelivered frames of the previous run
        self.frames.clear()
        self._open.clear()
        self._closing.clear()
        self._ready.clear()
        temp = self.params[P.Param.TEMPERATURE_CC] / 100.0
        self.c = speed_of_sound(temp)
        if self.source_kind == "replay":
            self._replay = self._make_replay(resolved)
            self._replay_pos, self._replay_base = 0, self.now
            self.model = None
        else:
            sched = _schedule_from_resolved(self.layout, resolved, self.scene.temperature_c)
            self.model = FastFiringModel(sched, SceneEchoSource(self.scene),
                                         glitch_min=self.params[P.Param.GLITCH_MIN],
                                         max_echoes_per_window=self.params[P.Param.MAX_ECHOES],
                                         miss_gate=self.regs.field("RX_FILTER", "MISS_GATE"),  # latched at start
                                         miss_hold=bool(self.regs.field("RX_FILTER", "MISS_HOLD")),
                                         start_tick=self.now, decision_lead=DEVICE_DECISION_LEAD)
        self._wall0, self._tick0 = time.monotonic(), self.now
        self.running = True

    _replay_cache: dict[Any, list[_FrameContent]] = {}

    def _make_replay(self, resolved: list[Any]) -> list[_FrameContent]:
        """Frames of a model run of replay_s seconds (cached per scene and table)."""
        from .fastfiring import FastFiringModel, SceneEchoSource

        key = (self.scene_name, self.replay_s, self.params[P.Param.GEOMETRY], self.params[P.Param.TOF_RECORDS],
               self.regs.field("RX_FILTER", "MISS_GATE"), self.regs.field("RX_FILTER", "MISS_HOLD"),
               self.params[P.Param.GLITCH_MIN], self.params[P.Param.MAX_ECHOES],
               tuple((r.id, int(r.tx.sum()), tuple(r.rx), r.order, r.max_tof, r.phase, r.mode, r.reinit_every)
                     for r in resolved))
        if key in SimDevice._replay_cache:
            return SimDevice._replay_cache[key]
        sched = _schedule_from_resolved(self.layout, resolved, self.scene.temperature_c)
        saved = (self.model, self.now, self._open, self._closing, self._ready, dict(self.counters))
        self.model = FastFiringModel(sched, SceneEchoSource(self.scene), glitch_min=self.params[P.Param.GLITCH_MIN],
                                     max_echoes_per_window=self.params[P.Param.MAX_ECHOES],
                                     miss_gate=self.regs.field("RX_FILTER", "MISS_GATE"),
                                     miss_hold=bool(self.regs.field("RX_FILTER", "MISS_HOLD")),
                                     decision_lead=DEVICE_DECISION_LEAD)
        self._open, self._closing, self._ready, self.now = {}, [], [], 0
        total = int(self.replay_s * TICK_HZ)
        while self.now < total:
            self._advance_model(min(total - self.now, TICK_HZ // 100))
        frames = self._ready
        self.model, self.now, self._open, self._closing, self._ready, self.counters = saved
        if not frames:
            raise RuntimeError(f"replay: the model produced no frame in {self.replay_s} s of scene {self.scene_name!r}")
        SimDevice._replay_cache[key] = frames
        return frames

    def _advance_model(self, ticks: int) -> None:
        """Run the golden model ``ticks`` ticks; finished pulses go to self._ready."""
        from .fastfiring import SEQ_MASK

        res = self.model.run(int(ticks))
        lat = self.model.latency + 1
        for p in res.pulses:
            key = (p.sensor, p.seq & SEQ_MASK)
            r = self._by_id.get(p.sensor)
            end = max((w[2] for w in p.windows), default=p.t0 + (r.max_tof if r is not None else 0))
            op = _OpenPulse(p, end + lat)
            self._open[key] = op
            heapq.heappush(self._closing, (op.close, next(self._ctr), key))
        for e in res.events:
            op = self._open.get((e.sensor, e.seq))
            if op is not None:
                op.events.append(e)
        self.counters["events"] += len(res.events)
        self.counters["pulses"] += len(res.pulses)
        self.now = self.model.now
        new: list[_FrameContent] = []
        while self._closing and self._closing[0][0] <= self.now:
            close, _, key = heapq.heappop(self._closing)
            op = self._open.get(key)
            if op is None or op.close != close:
                continue
            del self._open[key]
            new.append(self._frame_content(op))
        if new and self.params[P.Param.GEOMETRY]:
            self._batch_geometry(new)
        self._ready += new

    def _frame_content(self, op: _OpenPulse) -> _FrameContent:
        p = op.pulse
        evs = op.events[:P.MAX_TOF_RECORDS]
        tof = np.zeros(len(evs) if self.params[P.Param.TOF_RECORDS] else 0, P.TOF_DTYPE)
        for i, e in enumerate(evs[:len(tof)]):
            tof[i] = P.tof_record(e)
        fc = _FrameContent(op.close, p.t0, p.sensor, p.seq & 0xFF, p.init, tof, np.zeros(0, P.GEO_DTYPE),
                           len(op.events) > P.MAX_TOF_RECORDS)
        fc.firsts = {e.rx: e.tof for e in op.events if e.sample}  # type: ignore[attr-defined]
        return fc

    def _batch_geometry(self, items: list[_FrameContent]) -> None:
        """One geometry record per frame with >= 3 first echoes: classify_batch per (sensor,
        receiver set), position from the point or wall fit of the winning model (a cylinder
        reports its fitted nearest point: the point fit)."""
        from .georecord import geo_records, sensor_paths

        groups: dict[tuple[int, tuple[int, ...]], list[_FrameContent]] = {}
        for fc in items:
            firsts = getattr(fc, "firsts", {})
            if len(firsts) >= 3:
                groups.setdefault((fc.vs, tuple(sorted(firsts))), []).append(fc)
        for (sid, rxs), fcs in groups.items():
            tofs = np.array([[fc.firsts[i] for i in rxs] for fc in fcs], float)  # type: ignore[attr-defined]
            source, paths = sensor_paths(self.layout, self._by_id[sid], tofs, self.c)
            try:
                recs = geo_records(self.layout.positions[np.array(rxs)], paths, source)
            except (ValueError, FloatingPointError):
                continue
            for fc, g in zip(fcs, recs):
                if g is not None:
                    fc.geo = np.array([g], P.GEO_DTYPE)
                    self.geo_fixes += 1

    def _enqueue(self, fc: _FrameContent) -> None:
        seq = self.frame_seq
        self.frame_seq = (self.frame_seq + 1) & 0xFFFFFFFF
        if len(self.frames) >= self.queue_frames:
            self.counters["frames_dropped"] += 1
            return
        head = {"timestamp": fc.timestamp & TIMESTAMP_MASK, "t0": fc.t0 & TIMESTAMP_MASK, "vs": fc.vs,
                "pulse_seq": fc.pulse_seq, "dropped": self.counters["frames_dropped"] & 0xFFFFFFFF,
                "fifo_overflows": self.counters["fifo_overflows"] & 0xFFFF, "watchdog": self.counters["watchdog"] & 0xFFFF}
        flags = P.FRAME_SIMULATED | (P.FRAME_INIT_PING if fc.init else 0) | (P.FRAME_TRUNCATED if fc.truncated else 0)
        self.frames.append(P.encode_frame(seq, head, fc.tof, fc.geo, flags=flags))
        self.counters["frames_sent"] += 1

    def _next_replay(self) -> _FrameContent:
        fr = self._replay
        assert fr is not None
        period = int(self.replay_s * TICK_HZ)
        k, i = divmod(self._replay_pos, len(fr))
        base = fr[i]
        off = self._replay_base + k * period
        self._replay_pos += 1
        self.counters["pulses"] += 1
        self.counters["events"] += len(base.tof)
        return _FrameContent(base.timestamp + off, base.t0 + off, base.vs, base.pulse_seq, base.init,
                             base.tof, base.geo, base.truncated)

    def _replay_peek_time(self) -> int:
        fr = self._replay
        assert fr is not None
        k, i = divmod(self._replay_pos, len(fr))
        return fr[i].timestamp + self._replay_base + k * int(self.replay_s * TICK_HZ)

    def _produce_lockstep(self, budget_s: float) -> None:
        t_end = time.monotonic() + budget_s
        if self.source_kind == "replay":
            fc = self._next_replay()
            self.now = max(self.now, fc.timestamp)
            self._enqueue(fc)
            return
        while not self._ready and time.monotonic() < t_end:
            self._advance_model(TICK_HZ // 50)  # 20 ms of sonar time (geometry is batched per step)
        while self._ready and len(self.frames) < self.queue_frames:
            self._enqueue(self._ready.pop(0))

    def _catch_up(self, budget_s: float = 0.2) -> None:
        """Real-time mode: advance sonar time to the wall clock (bounded work per call)."""
        if not self.running or self.rate is None:
            return
        target = self._tick0 + int((time.monotonic() - self._wall0) * self.rate * TICK_HZ)
        t_end = time.monotonic() + budget_s
        if self.source_kind == "replay":
            while self._replay_peek_time() <= target and time.monotonic() < t_end:
                fc = self._next_replay()
                self._enqueue(fc)
            self.now = max(self.now, min(target, self._replay_peek_time()))
            return
        while self.now < target and time.monotonic() < t_end:
            self._advance_model(min(target - self.now, TICK_HZ // 50))
            while self._ready:
                self._enqueue(self._ready.pop(0))


# -- the sim:// device URL scheme (multisonar.urls; found through the multisonar.schemes entry point)
def sim_model(url: DeviceUrl) -> Model:
    """sim://SCENE?rate=R&source=model|replay&queue=N&seed=S: the simulated device in this process"""
    q = url.query
    try:
        sim = SimDevice(url.target or "corridor", rate=float(q["rate"]) if "rate" in q else None,
                        queue_frames=int(q.get("queue", 256)), source=q.get("source", "model"),
                        seed=int(q["seed"]) if "seed" in q else None)
    except (KeyError, OSError) as e:
        raise DeviceNotFound(f"{url.url}: cannot build the simulated device: {e}") from None
    return Model(sim, close=sim.close)


register_scheme("sim", model=sim_model, help=sim_model.__doc__ or "")
