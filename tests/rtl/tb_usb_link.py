"""cocotb tests of the whole device behind USB (usb_link_tb: ms_system_usb running
firmware/app/sonar).

``driver_against_rtl``: the unchanged host driver (multisonar.Device over pyusb's in-process
backend; at the end also over our USB/IP server, opened as usbip://127.0.0.1:PORT) in its own
thread, served by RtlUsbFunction (tests/rtl/usb_rtl_function.py) through
the USB core's transaction-level port: device info, ECHO sizes (short packet, exact multiple
of 64 + ZLP), error replies (bad CRC, bad magic, short transfer, unknown opcode,
BAD_ADDRESS, BAD_PARAM, CFG_REJECTED, BUSY), configure (validated Schedule -> WRITE_REGS ->
read-back -> START) on a wall scene, frames (CRC checked by the parser, consecutive sequence
numbers, ToF records equal to the golden model's events of each pulse), counters, STOP.

``bus_reset_mid_stream``: a USB bus reset in the middle of a bulk IN transfer while frames
stream, re-enumeration, the driver's clean error, re-open, restart (its docstring).

``wire_level_end_to_end``: the wire-level host (D+/D-, NRZI, bit stuffing): enumeration,
one command round trip (DEVICE_INFO) and one frame reaching the host.
"""

from __future__ import annotations

import json
import math
import os
import struct
import threading
import time
import traceback
from collections import defaultdict

import cocotb
import numpy as np
from cocotb.triggers import RisingEdge, ReadOnly, Timer
from cocotb.utils import get_sim_time

from multisonar import protocol as P
from multisonar.constants import DEVICE_DECISION_LEAD, TICK_HZ, speed_of_sound
from multisonar.device import Device, DeviceDisconnected
from multisonar.fastfiring import FastFiringModel, _rows
from multisonar.generated import sonar_regs as R
from multisonar.layout import load_layout
from multisonar.regmap import schedule_writes
from multisonar.schedule import Schedule, VirtualSensor
from multisonar.usb.function import Disconnected
from multisonar.usb.usbip_server import UsbipServer
from echo_driver import EchoDriver
from tbutil import CLK_PERIOD_PS, reset, start_clock
from usb_host import PID_ACK, PID_DATA0, PID_DATA1, PID_NAK, UsbHost
from usb_rtl_function import ADDR, RtlUsbFunction

LEAD = DEVICE_DECISION_LEAD
LAYOUT = load_layout()
TEMP_C = 20.0
C_SOUND = speed_of_sound(TEMP_C)
WALL_D = 0.6  # m ahead of the ring centre, perpendicular to +x (its echo after D > P)
AXES = np.arctan2(LAYOUT.positions[:, 1], LAYOUT.positions[:, 0])
N_FRAMES = 4


def schedule() -> Schedule:
    return Schedule(LAYOUT, [VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=1, max_range_m=0.8,
                                           t_dead=0.8e-3, t_v=0.2e-3, t_n=0.2e-3)],
                    temperature_c=TEMP_C)


def schedule_long_frames() -> Schedule:
    """Init pings on five receivers: every ToF frame holds five records (76 bytes: two packets),
    so a bus reset can land inside a frame's transfer."""
    return Schedule(LAYOUT, [VirtualSensor("front", tx=[0], rx=[22, 23, 0, 1, 2], mode="init", max_range_m=0.8,
                                           t_dead=0.8e-3, t_v=0.2e-3, t_n=0.2e-3)],
                    temperature_c=TEMP_C)


class WallSource:
    """Specular wall x = WALL_D: the image of the transmitter, heard by receivers facing it."""

    def fire(self, t0, elements, delays):
        k = TICK_HZ / C_SOUND
        n = np.array([1.0, 0.0])
        rows = []
        for r in range(LAYOUT.n):
            if abs((AXES[r] + math.pi) % (2 * math.pi) - math.pi) > math.radians(60):
                continue
            ts = []
            for e, d in zip(np.asarray(elements), np.asarray(delays)):
                ce = LAYOUT.positions[int(e)]
                m = ce - 2.0 * (float(n @ ce) - WALL_D) * n
                ts.append(d + np.linalg.norm(m - LAYOUT.positions[r]) * k)
            rows.append((r, t0 + int(np.rint(min(ts))), 9600))
        return rows


class Echoes:
    """Per pulse strobe of the scheduler: the wall's echoes on echo_i; records t0s and starts."""

    def __init__(self, dut) -> None:
        self.dut = dut
        self.sonar = dut.u_dev.u_sys.u_sonar
        self.sched = self.sonar.u_sched
        self.src = WallSource()
        self.origin = (0, 0)
        self.echo = EchoDriver(dut.echo_i, LAYOUT.n, lambda t: self.origin[1] + (t - self.origin[0]) * CLK_PERIOD_PS)
        self.starts: list[int] = []
        self.tasks = []

    async def start(self) -> None:
        await RisingEdge(self.dut.clk_i)
        await ReadOnly()
        self.origin = (int(self.sonar.tick_q.value), int(get_sim_time("ps")))
        self.tasks = [cocotb.start_soon(self._pulses()), cocotb.start_soon(self._running())]
        await Timer(1, unit="ns")  # leave the read-only phase

    async def _pulses(self) -> None:
        while True:
            await RisingEdge(self.sched.pulse_o)
            await ReadOnly()
            t0, vs = int(self.sched.pulse_t0_o.value), int(self.sched.pulse_vs_o.value)
            mask = int(self.sched.pulse_tx_o.value)
            tx = [e for e in range(LAYOUT.n) if mask >> e & 1]
            for rx, st, w in _rows(self.src.fire(t0, np.array(tx), np.zeros(len(tx), np.int64))):
                self.echo.drive(int(rx), int(st), int(w))
            await RisingEdge(self.dut.clk_i)

    async def _running(self) -> None:
        while True:
            await self.sched.running_o.value_change
            await ReadOnly()
            if int(self.sched.running_o.value):
                self.starts.append(int(self.sonar.tick_q.value) - 1)
            await RisingEdge(self.dut.clk_i)

    def stop(self) -> None:
        for t in self.tasks:
            t.cancel()
        self.echo.stop()


async def run_in_thread(dut, fn: RtlUsbFunction, body, wall_limit_s: float = 600.0) -> dict:
    """Run body() (blocking, pyusb) in a thread while the simulation serves it."""
    out: dict = {}

    def target():
        try:
            out["result"] = body()
        except BaseException as e:  # noqa: BLE001 - re-raised in cocotb's thread
            out["error"] = e
            out["tb"] = traceback.format_exc()

    th = threading.Thread(target=target, daemon=True)
    t0 = time.monotonic()
    th.start()
    while th.is_alive():
        await Timer(200, unit="us")
        assert time.monotonic() - t0 < wall_limit_s, "host thread did not finish in time"
    if "error" in out:
        dut._log.error(out["tb"])
        raise out["error"]
    return out["result"]


def raw_command(dev: Device, pkt: bytes) -> P.Packet:
    """Write a (possibly malformed) command transfer, return the next reply packet."""
    dev._dev.write(P.EP_OUT, pkt, 20000)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        for p in dev._read_packets(1.0):
            if not p.is_frame:
                return p
    raise AssertionError("no reply to a raw command")


def unmapped_address() -> int:
    """The first word address below the VS table that no register of the generated map uses."""
    import itertools

    used = set()
    for reg in R.REGISTERS.values():
        for ix in itertools.product(*(range(n) for n in reg.dims)) if reg.dims else [()]:
            used.add(reg.addr(*ix))
    return next(a for a in range(0, R.REGISTERS["VS_TX_MASK"].addr(0), 4) if a not in used)


def expect_error(fn, status: P.Status):
    try:
        fn()
    except P.DeviceError as e:
        assert e.status == status, f"expected {status.name}, got {e}"
        return e
    raise AssertionError(f"expected {status.name}, the command succeeded")


@cocotb.test(timeout_time=3000, timeout_unit="ms")
async def driver_against_rtl(dut):
    start_clock(dut.clk_i)
    dut.echo_i.value = 0
    host = UsbHost(dut, tl=True)
    await reset(dut.clk_i, dut.rst_i)
    bench = Echoes(dut)
    await bench.start()
    fn = RtlUsbFunction(host)
    await fn.enumerate()
    server = cocotb.start_soon(fn.serve())
    mail: list[int] = []

    async def mailbox():
        while True:
            await RisingEdge(dut.sim_out_strobe_o)
            await ReadOnly()
            mail.append(int(dut.sim_out_o.value))

    cocotb.start_soon(mailbox())
    sched = schedule()
    figures: dict = {}

    def body():
        dev = Device.attach(fn, timeout_s=60.0)
        info = dev.info()
        assert info.protocol_version == 1 and info.max_payload == 1024
        assert info.tick_hz == R.REGISTERS["TICK_HZ"].reset == TICK_HZ
        caps = R.REGISTERS["CAPS"].reset
        assert info.caps_reg == caps and info.channels == R.REGISTERS["CAPS"].fields["NUM_CH"].get(caps) == 24
        assert info.max_vs == 8 and info.version_reg == R.REGISTERS["VERSION"].reset and info.flags == 0
        # ECHO: short, exactly 64-byte multiple transfers (ZLP), odd sizes
        rtt = []
        for n in (0, 1, 5, 48, 64 - 16, 128 - 16, 200, 1024):
            pl = bytes((i * 7 + n) & 0xFF for i in range(n))
            rtt.append(dev.echo(pl))
        figures["echo_wall_s"] = rtt
        # errors, in the check order of docs/protocol.md section 4
        good = P.encode_command(P.Opcode.ECHO, b"abc", seq=77)
        p = raw_command(dev, good[:-1] + bytes([good[-1] ^ 1]))
        assert (p.status, p.seq, p.type) == (P.Status.BAD_CRC, 77, 0x8A), p
        p = raw_command(dev, b"XC" + good[2:])
        assert (p.status, p.type) == (P.Status.BAD_MAGIC, 0xFF), p
        p = raw_command(dev, good[:10])
        assert (p.status, p.type, p.seq) == (P.Status.BAD_LENGTH, 0xFF, 0), p
        p = raw_command(dev, good[:2] + bytes([2]) + good[3:])
        assert (p.status, p.type, p.payload) == (P.Status.BAD_VERSION, 0xFF, b"\x01"), p
        p = raw_command(dev, good + b"\x00")
        assert (p.status, p.type) == (P.Status.BAD_LENGTH, 0x8A), p
        expect_error(lambda: dev.command(0x55), P.Status.UNKNOWN_OPCODE)
        e = expect_error(lambda: dev.write_regs([(R.REGISTERS["BURST"].addr(), R.REGISTERS["BURST"].reset),
                                                 (R.REGISTERS["ID"].addr(), 1)]), P.Status.BAD_ADDRESS)
        assert struct.unpack("<HHI", e.payload) == (1, 0, R.REGISTERS["ID"].addr())
        expect_error(lambda: dev.write_regs([(R.REGISTERS["CTRL"].addr(), 1)]), P.Status.BAD_ADDRESS)
        expect_error(lambda: dev.read_regs([unmapped_address()]), P.Status.BAD_ADDRESS)
        assert dev.read_regs([R.REGISTERS["ID"].addr()]) == [R.REGISTERS["ID"].reset]
        expect_error(lambda: dev.set_param(P.Param.GEOMETRY, 2), P.Status.BAD_PARAM)
        expect_error(lambda: dev.get_param(99), P.Status.BAD_PARAM)
        dev.set_param(P.Param.TEMPERATURE_CC, 2150)
        assert dev.get_param(P.Param.TEMPERATURE_CC) == 2150
        # an empty table is refused at START (CFG_REJECTED, EMPTY_TABLE)
        dev.write_regs([(R.REGISTERS["VS_MODE"].addr(vs), 0) for vs in range(8)])
        try:
            dev.start()
            raise AssertionError("START of an empty table succeeded")
        except P.CfgRejected as e:
            assert e.payload[0] == int(P.CfgError.EMPTY_TABLE), e.payload
        c = dev.counters()
        assert c["bad_commands"] >= 12, c
        dev.clear_counters()
        assert dev.counters()["bad_commands"] == 0
        # configure over USB, run, stream
        dev.configure(sched)
        t = time.monotonic()
        dev.start()
        frames = []
        for f in dev.stream(max_frames=N_FRAMES, idle_timeout_s=300):
            frames.append(f)
        figures["stream_wall_s"] = time.monotonic() - t
        expect_error(lambda: dev.write_regs([(R.REGISTERS["BURST"].addr(), 0)]), P.Status.BUSY)
        expect_error(lambda: dev.command(P.Opcode.START), P.Status.BUSY)
        expect_error(lambda: dev.set_param(P.Param.GLITCH_MIN, 10), P.Status.BUSY)
        n_streamed = len(frames)
        dev.stop(drain_s=30)
        frames += list(dev.queue)
        figures["n_streamed"] = n_streamed
        dev.queue.clear()
        counters = dev.counters()
        dev.close()
        # the same RTL over our USB/IP server on 127.0.0.1, opened by URL
        with UsbipServer(fn) as srv:
            d2 = Device.open(srv.url, timeout_s=60.0)
            assert d2.info().channels == 24
            assert d2.command(P.Opcode.ECHO, b"over usbip") == b"over usbip"
            d2.close()
        return frames, counters, dict(dev.stats.as_dict())

    frames, counters, hstats = await run_in_thread(dut, fn, body)
    fn.stop()
    await server
    end_tick = int(bench.sonar.tick_q.value)
    bench.stop()
    assert not int(dut.trap_o.value) and not int(dut.bus_err_o.value)
    dut._log.info("echo round trips (wall s): %s", ["%.3f" % x for x in figures["echo_wall_s"]])
    dut._log.info("%d frames in %.1f s wall; host stats %s; device counters %s; bridge %s", len(frames),
                  figures["stream_wall_s"], hstats, counters, fn.stats)
    assert len(frames) >= N_FRAMES
    assert hstats["bad_crc"] == 0 and hstats["bad_header"] == 0 and hstats["lost"] == 0, hstats
    assert [f.seq for f in frames] == list(range(frames[0].seq, frames[0].seq + len(frames)))
    assert counters["frames_sent"] >= len(frames) and counters["frames_dropped"] == 0, counters
    # golden model from the start tick of the run
    assert len(bench.starts) == 1, bench.starts
    s0 = bench.starts[0]
    res = FastFiringModel(sched, WallSource(), start_tick=s0, decision_lead=LEAD).run(end_tick - s0)
    groups = defaultdict(list)
    for e in res.events:
        groups[(e.sensor, e.seq & 0xFF)].append((e.tof, e.rx, e.seq & 0xFF, e.sensor, int(e.in_window)
                                                 | int(e.first_echo) << 1 | int(e.window_empty) << 2
                                                 | int(e.init_ping) << 3))
    n_geo = 0
    for i, f in enumerate(frames):
        got = [tuple(int(r[n]) for n in ("tof", "rx", "seq", "vs", "flags")) for r in f.tof]
        want = groups[(f.vs, f.pulse_seq)]
        if f.is_geometry:
            assert not got
        elif i < figures["n_streamed"]:
            assert got == want, f"pulse {(f.vs, f.pulse_seq)}: frame {got} model {want}"
        else:  # closed by STOP: the windows still open were dropped, the rest is as the model
            assert f.flags & P.FRAME_CUT and set(got) <= set(want), \
                f"pulse {(f.vs, f.pulse_seq)} after STOP: frame {got} model {want}"
        if len(f.geo):
            n_geo += 1
            g = f.geo[0]
            assert int(g["cls"]) == 2, g  # a wall
            foot = 1000 * np.array([WALL_D, 0.0])
            assert math.hypot(int(g["x_mm"]) - foot[0], int(g["y_mm"]) - foot[1]) <= 5, g
    assert n_geo >= 1, "no geometry record"
    tags = defaultdict(list)
    for w in mail:
        tags[w >> 28].append(w & 0x0FFFFFFF)
    cyc = [v & 0xFFFF for v in tags[7]]
    dut._log.info("firmware cycles per command (arrival -> reply committed): median %d max %d over %d commands",
                  int(np.median(cyc)), max(cyc), len(cyc))


def check_against_model(frames, n_streamed, sched, start_tick, end_tick) -> None:
    """ToF records of the frames equal the golden model's events of each pulse (frames after
    index n_streamed were closed by STOP: a subset)."""
    res = FastFiringModel(sched, WallSource(), start_tick=start_tick, decision_lead=LEAD).run(end_tick - start_tick)
    groups = defaultdict(list)
    for e in res.events:
        groups[(e.sensor, e.seq & 0xFF)].append((e.tof, e.rx, e.seq & 0xFF, e.sensor, int(e.in_window)
                                                 | int(e.first_echo) << 1 | int(e.window_empty) << 2
                                                 | int(e.init_ping) << 3))
    for i, f in enumerate(frames):
        got = [tuple(int(r[n]) for n in ("tof", "rx", "seq", "vs", "flags")) for r in f.tof]
        want = groups[(f.vs, f.pulse_seq)]
        if f.is_geometry:
            assert not got
        elif i < n_streamed:
            assert got == want, f"pulse {(f.vs, f.pulse_seq)}: frame {got} model {want}"
        else:
            assert f.flags & P.FRAME_CUT and set(got) <= set(want), \
                f"pulse {(f.vs, f.pulse_seq)} after STOP: frame {got} model {want}"


@cocotb.test(timeout_time=3000, timeout_unit="ms")
async def bus_reset_mid_stream(dut):
    """USB bus reset while frames stream (issue #9): the host resets the bus in the middle of
    a bulk IN transfer (one packet of it ACKed, the next sent by the device and not ACKed) and
    re-enumerates the device. The driver gets a clean DeviceDisconnected for the interrupted
    transfer and on every later call of the old handle; re-opened, the device is still
    running (a bus reset reaches the USB core only, docs/usb_core.md): START is BUSY, frames
    keep coming with good CRCs, the ones whose bytes went with the interrupted transfer
    missing by sequence number (the rest of the cut frame is skipped by the parser; the
    un-ACKed packet comes again), none dropped by the device; STOP, START again: frames
    stream again, consecutive from START's seq and equal to the golden model."""
    start_clock(dut.clk_i)
    dut.echo_i.value = 0
    host = UsbHost(dut, tl=True)
    await reset(dut.clk_i, dut.rst_i)
    bench = Echoes(dut)
    await bench.start()
    fn = RtlUsbFunction(host)
    await fn.enumerate()
    server = cocotb.start_soon(fn.serve())
    sched = schedule_long_frames()
    configured_after_reset: list[int] = []

    async def watch_configured():
        # configured_o must drop with the bus reset and come back with SET_CONFIGURATION
        while True:
            await dut.configured_o.value_change
            configured_after_reset.append(int(dut.configured_o.value))

    watch = cocotb.start_soon(watch_configured())

    def body():
        out: dict = {}
        dev = Device.attach(fn, timeout_s=60.0)
        dev.configure(sched)
        dev.start()
        before = list(dev.stream(max_frames=1, idle_timeout_s=300))
        fn.request_bus_reset()
        try:
            for f in dev.stream(max_frames=100, idle_timeout_s=300):
                before.append(f)
            raise AssertionError("the stream went on after the bus reset")
        except DeviceDisconnected as e:
            out["error"] = str(e)
        assert dev.closed
        before += list(dev.queue)  # frames received before the reset stay readable
        dev.queue.clear()
        for call in (lambda: dev.info(refresh=True), lambda: dev.command(P.Opcode.ECHO, b"x"),
                     lambda: list(dev.stream(max_frames=1))):
            try:
                call()
                raise AssertionError("the old handle still works after the bus reset")
            except DeviceDisconnected:
                pass
        try:  # below the driver too: the function refuses the stale handle
            fn.bulk_in(P.EP_IN, 64, 1.0)
            raise AssertionError("stale bulk IN went through")
        except Disconnected:
            pass
        out["before"] = [f.seq for f in before]
        out["old_stats"] = dev.stats.as_dict()
        fn.reconnect()
        d2 = Device.attach(fn, timeout_s=60.0)
        assert d2.info().channels == 24
        expect_error(lambda: d2.command(P.Opcode.START), P.Status.BUSY)  # still running
        after = list(d2.stream(max_frames=1, idle_timeout_s=300))
        out["after"] = [f.seq for f in after]
        out["after_stats"] = d2.stats.as_dict()
        d2.stop(drain_s=30)
        out["counters_reset"] = d2.counters()
        d2.start()
        first = d2._expect
        frames = list(d2.stream(max_frames=2, idle_timeout_s=300))
        out["n_streamed"] = len(frames)
        d2.stop(drain_s=30)
        frames += list(d2.queue)
        d2.queue.clear()
        out["first"] = first
        out["counters"] = d2.counters()
        out["stats"] = d2.stats.as_dict()
        d2.close()
        return frames, out

    frames, out = await run_in_thread(dut, fn, body)
    fn.stop()
    await server
    watch.cancel()
    end_tick = int(bench.sonar.tick_q.value)
    bench.stop()
    rs = fn.resets
    dut._log.info("bus reset: %s; interrupted transfer discarded %d bytes, un-ACKed packet %s; driver: %s",
                  [round(r["sim_ns"]) for r in rs], len(rs[0]["discarded"]),
                  None if rs[0]["unacked"] is None else len(rs[0]["unacked"]), out["error"])
    dut._log.info("frames before %s, after re-open %s (host stats %s); restart seq %d: %d frames, stats %s, "
                  "counters %s", out["before"], out["after"], out["after_stats"], out["first"], len(frames),
                  out["stats"], out["counters"])
    assert len(rs) == 1 and len(rs[0]["discarded"]) >= 64 and rs[0]["unacked"], rs
    assert "Device.open() it again" in out["error"], out["error"]
    assert 0 in configured_after_reset and configured_after_reset[-1] == 1, configured_after_reset
    assert not int(dut.trap_o.value) and not int(dut.bus_err_o.value)
    # re-opened mid-run: good CRCs, the rest of the cut frame skipped, the frames that went
    # with the interrupted transfer missing by seq (the device dropped none)
    a, b = out["before"], out["after"]
    assert a == list(range(a[0], a[0] + len(a))) and b == list(range(b[0], b[0] + len(b))), (a, b)
    heads = rs[0]["discarded"].count(b"MF\x01\x40")  # frames whose head went with the transfer
    assert heads >= 1 and b[0] - a[-1] - 1 == heads, (a, b, heads)
    st = out["after_stats"]
    # the un-ACKed packet came again (DATA0 after the reset): it starts with the tail of a cut
    # frame, the only bytes the new parser skips; a reply that shared the packet (to a command
    # sent before the reset, so the thread's timing decides) parses, as a stale reply
    unacked = rs[0]["unacked"]
    tail = min([i for i in map(unacked.find, P.StreamParser.magics) if i >= 0], default=len(unacked))
    assert st["bad_crc"] == 0 and st["bad_frames"] == 0 and st["skipped_bytes"] == tail, (st, tail)
    assert out["counters_reset"]["frames_dropped"] == 0, out["counters_reset"]
    # restarted: consecutive from START's seq, CRCs good, equal to the golden model
    assert len(frames) >= 2 and [f.seq for f in frames] == list(range(out["first"], out["first"] + len(frames)))
    st = {k: v - out["after_stats"][k] for k, v in out["stats"].items()}  # since the re-open's frames
    assert st["bad_crc"] == 0 and st["bad_header"] == 0 and st["lost"] == 0 and st["skipped_bytes"] == 0, st
    assert out["counters"]["frames_dropped"] == 0, out["counters"]
    assert len(bench.starts) == 2, bench.starts
    check_against_model(frames, out["n_streamed"], sched, bench.starts[1], end_tick)


async def wire_bulk_out(host: UsbHost, data: bytes, toggle: bool) -> bool:
    chunks = [data[i:i + 64] for i in range(0, len(data), 64)] + ([b""] if len(data) % 64 == 0 else [])
    for c in chunks:
        for _ in range(1000):
            r = await host.out(ADDR, 1, toggle, c)
            if r.pid == PID_ACK:
                break
            assert r.pid == PID_NAK, f"bulk OUT answered {r.name}"
            await Timer(20, unit="us")
        toggle = not toggle
    return toggle


async def wire_read_packet(host: UsbHost, parser: P.StreamParser, want_frame: bool, limit_us: int):
    """IN transactions until the parser has a reply (or a frame); returns (packet, sim us)."""
    t0 = get_sim_time("us")
    while get_sim_time("us") - t0 < limit_us:
        r = await host.in_token(ADDR, 1)
        if r.pid in (PID_DATA0, PID_DATA1):
            for p in parser.feed(r.payload):
                if p.is_frame == want_frame:
                    return p, get_sim_time("us") - t0
            continue
        assert r.pid == PID_NAK, f"bulk IN answered {r.name}"
        await Timer(20, unit="us")
    raise AssertionError(f"no {'frame' if want_frame else 'reply'} within {limit_us} us")


@cocotb.test(timeout_time=3000, timeout_unit="ms")
async def wire_level_end_to_end(dut):
    """D+/D- through the device's own receiver and transmitter: enumeration, DEVICE_INFO,
    WRITE_REGS + START, one frame reaching the host (no echoes: window_empty records)."""
    start_clock(dut.clk_i)
    dut.echo_i.value = 0
    host = UsbHost(dut, tl=False)
    await reset(dut.clk_i, dut.rst_i)
    mail: list[tuple[float, int]] = []

    async def mailbox():
        while True:
            await RisingEdge(dut.sim_out_strobe_o)
            await ReadOnly()
            mail.append((get_sim_time("us"), int(dut.sim_out_o.value)))

    mb = cocotb.start_soon(mailbox())
    await Timer(10, unit="us")
    await host.bus_reset()
    d = await host.control_read(0, 0x80, 6, 0x0100, 0, 64)
    assert struct.unpack_from("<HH", d, 8) == (P.USB_VID, P.USB_PID), d.hex()
    await host.control_nodata(0, 0x00, 5, ADDR, 0)
    cfg = await host.control_read(ADDR, 0x80, 6, 0x0200, 0, 9)
    cfg = await host.control_read(ADDR, 0x80, 6, 0x0200, 0, struct.unpack_from("<H", cfg, 2)[0])
    assert cfg[9 + 5] == 0xFF, "vendor interface"
    await host.control_nodata(ADDR, 0x00, 9, 1, 0)
    assert int(dut.configured_o.value) == 1
    parser = P.StreamParser()
    toggle = await wire_bulk_out(host, P.encode_command(P.Opcode.DEVICE_INFO, seq=41), False)
    p, us = await wire_read_packet(host, parser, False, 5000)
    assert (p.status, p.seq, p.type) == (P.Status.OK, 41, 0x81), p
    info = P.DeviceInfo.decode(p.payload)
    assert info.protocol_version == 1 and info.tick_hz == TICK_HZ and info.channels == 24
    dut._log.info("wire level: DEVICE_INFO answered %.0f us after its OUT transfer (mailbox: %s)", us,
                  [(round(t), hex(w)) for t, w in mail])
    writes = schedule_writes(schedule())
    toggle = await wire_bulk_out(host, P.encode_command(P.Opcode.WRITE_REGS, P.write_regs_payload(writes), seq=42),
                                 toggle)
    p, _ = await wire_read_packet(host, parser, False, 5000)
    assert (p.status, p.seq, struct.unpack("<H", p.payload)[0]) == (P.Status.OK, 42, len(writes)), p
    toggle = await wire_bulk_out(host, P.encode_command(P.Opcode.START, seq=43), toggle)
    p, _ = await wire_read_packet(host, parser, False, 20000)
    assert (p.status, p.seq) == (P.Status.OK, 43), p
    first = struct.unpack("<I", p.payload)[0]
    p, us = await wire_read_packet(host, parser, True, 30000)
    f = P.decode_frame(p)
    assert f.seq == first and f.vs == 0 and f.flags & P.FRAME_INIT_PING, f
    assert sorted(int(r["rx"]) for r in f.tof) == [0, 1, 23] and all(int(r["flags"]) & 4 for r in f.tof), f.tof
    assert parser.bad_crc == 0 and parser.bad_header == 0
    dut._log.info("wire level: first frame %.0f us after START's reply; max device response %.2f bit times",
                  us, host.max_delay_bits)
    assert not int(dut.collision_o.value) and not int(dut.trap_o.value)
    mb.cancel()
    host.stop()


@cocotb.test(skip=os.environ.get("RTL_LINK_BENCH") is None, timeout_time=10000, timeout_unit="ms")
async def bench_link(dut):
    """scripts/bench_rtl_link.py: command round trips and bulk throughput through the RTL path
    (ECHO), frames streamed from the wall scene; figures written as JSON to $RTL_LINK_BENCH."""
    start_clock(dut.clk_i)
    dut.echo_i.value = 0
    host = UsbHost(dut, tl=True)
    await reset(dut.clk_i, dut.rst_i)
    bench = Echoes(dut)
    await bench.start()
    fn = RtlUsbFunction(host)
    await fn.enumerate()
    server = cocotb.start_soon(fn.serve())
    n_frames = int(os.environ.get("RTL_LINK_FRAMES", "20"))
    rows: dict = {}

    def body():
        dev = Device.attach(fn, timeout_s=60.0)
        for n in (0, 48, 240, 1024):
            pl = bytes(i & 0xFF for i in range(n))
            sims, walls = [], []
            for _ in range(3):
                k = len(fn.log)
                walls.append(dev.echo(pl))
                ev = fn.log[k:]
                sims.append(ev[-1][2] - ev[0][1])
            rows[f"echo_{n}"] = {"bytes": n, "sim_us": float(np.median(sims)) / 1e3, "wall_s": float(np.median(walls))}
        dev.configure(schedule())
        k = len(fn.log)
        t = time.monotonic()
        dev.start()
        t_start = fn.log[-1][2]
        frames = list(dev.stream(max_frames=n_frames, idle_timeout_s=600))
        wall = time.monotonic() - t
        t_end = fn.log[-1][2]
        nbytes = sum(e[3] for e in fn.log[k:] if e[0] == "bulk_in" and e[3] > 0)
        rows["stream"] = {"frames": len(frames), "sim_s": (t_end - t_start) / 1e9, "wall_s": wall, "bytes": nbytes,
                          "frame_bytes": float(np.mean([16 + 20 + 8 * len(f.tof) + 16 * len(f.geo) for f in frames]))}
        dev.stop(drain_s=30)
        dev.close()

    await run_in_thread(dut, fn, body, wall_limit_s=3600)
    fn.stop()
    await server
    bench.stop()
    rows["bridge"] = dict(fn.stats)
    with open(os.environ["RTL_LINK_BENCH"], "w") as fh:
        json.dump(rows, fh, indent=1)
