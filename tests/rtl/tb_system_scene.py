"""cocotb whole-system test: ms_system running firmware/app/sonar on a scene.

Scene (static, deterministic; :class:`WallPointSource`): a wall 1.5 m ahead (tilted 5 deg) of the
'front' sensor (element 0, receivers 23/0/1) and a point reflector behind-left of the 'back'
sensor (element 12, receivers 11..13), ~28 deg off its axis, so the firmware must re-aim
'back' by one element (to 13, receivers 12..14). The firmware's table is
multisonar.tools.fw_schedule's 'scene' config (the same Python object builds the golden
model's schedule here).

The testbench wakes per pulse strobe (echoes for that pulse, from the scheduler's
pulse_o / pulse_t0_o / pulse_vs_o and the applied tx mask), per echo edge, per host-FIFO word,
per mailbox write and per running_o edge; never per clock.

Checks:
* frames parse (protocol.StreamParser: magic, version, CRC-32), consecutive frame seq, type
  and layout (decode_frame), no host-FIFO drop flag;
* the ToF records of every frame are exactly the golden model's events of that pulse
  (FastFiringModel, decision_lead DEVICE_DECISION_LEAD, start tick = running_o rise - 1), per table segment:
  a re-aim restarts the schedule (old windows dropped, the old pulses' late echoes still
  arrive: fed to the next segment's model as noise), as tests/rtl/tb_ms_scheduler.py does;
  every model pulse that closed well before the end has its frame;
* geometry records: ms_fix against multisonar.geometry (classify_batch + point / wall fits
  with tol = max_gdop = inf, mapped as multisonar.simdevice does) on the same ToF: class
  equal, x / y / range within 1 mm (the fast path's stated 5 um bound + 0.5 mm record
  quantisation on each side), bearing / normal within 1 LSB (2 pi / 65536; bound 5 urad),
  quality within 1, residual within 3 um; and against the scene's truth (wall foot, point)
  within 5 mm;
* at least one wall fix and one edge fix; exactly one re-aim, of 'back', by +1 element, and
  after it the back sensor's edge is within the confidence interval;
* firmware cycle figures from the mailbox (tags documented in firmware/app/sonar/main.c): per-frame
  processing cycles and the main loop's busy cycles, logged (and checked to keep up here).
"""

from __future__ import annotations

import math
import os
import struct
from collections import defaultdict

import cocotb
import numpy as np
from cocotb.triggers import FallingEdge, ReadOnly, RisingEdge, Timer
from cocotb.utils import get_sim_time

from multisonar import protocol as P
from multisonar.constants import DEVICE_DECISION_LEAD, TICK_HZ, speed_of_sound
from multisonar.fastfiring import DEFAULT_MISS_GATE, FastFiringModel, _rows
from multisonar.georecord import geo_records
from multisonar.layout import load_layout
from multisonar.tools.fw_schedule import TEMPERATURE_C, schedule_for
from multisonar.tools.sched_program.layout import MAIN, M_GATE
from echo_driver import EchoDriver
from link_reader import LinkReader, send_command
from tbutil import CLK_PERIOD_PS, reset

LEAD = DEVICE_DECISION_LEAD
MS = 48_000
LAYOUT = load_layout()
C_SOUND = speed_of_sound(TEMPERATURE_C)
WALL_D, WALL_PHI = 1.5, math.radians(5.0)  # wall n.x = WALL_D, n = (cos, sin) WALL_PHI
WALL_N = np.array([math.cos(WALL_PHI), math.sin(WALL_PHI)])
POINT = (1.2 * math.cos(math.radians(200.0)), 1.2 * math.sin(math.radians(200.0)))
TX_BEAM = math.radians(40.0)  # half angle, transmit
RX_BEAM = math.radians(60.0)  # half angle, receive
RUN_TICKS = int(float(os.environ.get("SCENE_MS", "62")) * MS)
BACK = 1  # table index of the re-aimed sensor
AXES = np.arctan2(LAYOUT.positions[:, 1], LAYOUT.positions[:, 0])


def _off(direction: np.ndarray, axis: float) -> float:
    return abs((math.atan2(direction[1], direction[0]) - axis + math.pi) % (2 * math.pi) - math.pi)


class WallPointSource:
    """Specular wall n.x = WALL_D (image source) and a point reflector; an element transmits
    toward a reflector within TX_BEAM of its axis, a receiver hears one within RX_BEAM.
    Deterministic: the model and the bench get the same rows."""

    def __init__(self, width: int = 9600) -> None:
        self.pos, self.width = LAYOUT.positions, width

    def fire(self, t0: int, elements, delays) -> list[tuple[int, int, int]]:
        k = TICK_HZ / C_SOUND
        rows = []
        for r in range(LAYOUT.n):
            cr = self.pos[r]
            best = []
            for e, d in zip(np.asarray(elements), np.asarray(delays)):
                ce = self.pos[int(e)]
                # wall: image of the transmitter, heard from the wall side
                if _off(WALL_N, AXES[e]) < TX_BEAM:
                    m = ce - 2.0 * (float(WALL_N @ ce) - WALL_D) * WALL_N
                    if _off(m - cr, AXES[r]) < RX_BEAM:
                        best.append(("w", d + np.linalg.norm(m - cr) * k))
                p = np.asarray(POINT)
                if _off(p - ce, AXES[e]) < TX_BEAM and _off(p - cr, AXES[r]) < RX_BEAM:
                    best.append(("p", d + (np.linalg.norm(p - ce) + np.linalg.norm(p - cr)) * k))
            for kind in ("w", "p"):  # the phased group's first wavefront per reflector
                ts = [t for kk, t in best if kk == kind]
                if ts:
                    rows.append((r, t0 + int(np.rint(min(ts))), self.width))
        return rows


class RecordingSource:
    def __init__(self, inner) -> None:
        self.inner, self.rows = inner, []

    def fire(self, t0, elements, delays):
        r = _rows(self.inner.fire(t0, elements, delays))
        self.rows += [tuple(int(v) for v in x) for x in r]
        return r


class WithNoise:
    def __init__(self, inner, rows) -> None:
        self.inner, self.rows = inner, rows

    def fire(self, t0, elements, delays):
        return self.inner.fire(t0, elements, delays)

    def noise(self, t_start, t_end):
        return [r for r in self.rows if r[1] + r[2] > t_start and r[1] < t_end]


class Bench:
    def __init__(self, dut) -> None:
        self.dut = dut
        self.sched = dut.u_sys.u_sonar.u_sched
        self.tick_q = dut.u_sys.u_sonar.tick_q
        self.source = RecordingSource(WallPointSource())
        self.echo = EchoDriver(dut.echo_i, LAYOUT.n, self.cycle_start_ps)
        self.origin = (0, 0)  # (tick, ps of that cycle's first edge)
        self.fires: list[tuple[int, int, int]] = []  # (t0, vs, tx element)
        self.starts: list[int] = []  # model start tick of each table segment
        self.stops: list[int] = []  # stop_at of each apply that restarted
        self.mail: list[int] = []
        self.link = LinkReader(dut)
        self.tasks = []

    def cycle_start_ps(self, tick: int) -> int:
        return self.origin[1] + (tick - self.origin[0]) * CLK_PERIOD_PS

    def now_tick(self) -> int:
        return self.origin[0] + (int(get_sim_time("ps")) - self.origin[1]) // CLK_PERIOD_PS

    async def start(self) -> None:
        dut = self.dut
        await FallingEdge(dut.clk_i)  # the wrapper's own clock (system_scene_tb.sv)
        dut.echo_i.value = 0
        for name in ("cmd_valid_i", "cmd_data_i", "cmd_end_i", "cmd_zlp_i"):
            getattr(dut, name).value = 0
        self.link.start()
        await reset(dut.clk_i, dut.rst_i)
        await RisingEdge(dut.clk_i)
        await ReadOnly()
        self.origin = (int(self.tick_q.value), int(get_sim_time("ps")))
        for coro in (self._pulses(), self._running(), self._mailbox()):
            self.tasks.append(cocotb.start_soon(coro))
        await Timer(1, unit="ns")
        # the firmware boots idle with its compiled-in table loaded: START it (command port)
        await send_command(dut, P.encode_command(P.Opcode.START, seq=1))

    async def _pulses(self) -> None:
        while True:
            await RisingEdge(self.sched.pulse_o)
            await ReadOnly()
            t0, vs = int(self.sched.pulse_t0_o.value), int(self.sched.pulse_vs_o.value)
            mask = int(self.sched.pulse_tx_o.value)
            tx = [e for e in range(LAYOUT.n) if mask >> e & 1]
            assert len(tx) == 1, "the scene's sensors fire one element (zero phasing delay)"
            self.fires.append((t0, vs, tx[0]))
            for rx, st, w in _rows(self.source.fire(t0, np.array(tx), np.zeros(len(tx), np.int64))):
                self.echo.drive(int(rx), int(st), int(w))
            await RisingEdge(self.dut.clk_i)

    async def _running(self) -> None:
        while True:
            await self.sched.running_o.value_change
            await ReadOnly()
            if int(self.sched.running_o.value):
                self.starts.append(int(self.tick_q.value) - 1)
            else:
                self.stops.append(int(self.sched.stop_at_q.value))
            await RisingEdge(self.dut.clk_i)

    async def _mailbox(self) -> None:
        while True:
            await RisingEdge(self.dut.sim_out_strobe_o)
            await ReadOnly()
            self.mail.append(int(self.dut.sim_out_o.value))

    def stop(self) -> None:
        for t in self.tasks:
            if not t.done():
                t.cancel()
        self.link.stop()
        self.echo.stop()


def _frames(transfers: list[bytes]) -> tuple[list[P.Frame], list[P.Packet], P.StreamParser]:
    """Frames and replies of the link's bulk IN stream; each transfer holds exactly one packet."""
    sp = P.StreamParser()
    packets = []
    for t in transfers:
        got = sp.feed(t)
        assert len(got) == 1 and sum(len(p.payload) + 16 for p in got) == len(t), f"transfer of {len(t)} bytes"
        packets += got
    return [P.decode_frame(p) for p in packets if p.is_frame], [p for p in packets if not p.is_frame], sp


def _golden_geo(tofs: dict[int, int], src_el: int) -> np.void:
    """The host's geometry record for these first echoes (multisonar.georecord, as the
    simulated device and the demo's firmware check compute it)."""
    rxs = sorted(tofs)
    paths = C_SOUND * np.array([[tofs[r] for r in rxs]], float) / TICK_HZ
    g = geo_records(LAYOUT.positions[rxs], paths, LAYOUT.positions[src_el])[0]
    assert g is not None, f"no finite host fix for {tofs}"
    return g


def _ang_diff(a: int, b: int) -> int:
    return abs(((int(a) - int(b) + 32768) & 0xFFFF) - 32768)


@cocotb.test(timeout_time=10, timeout_unit="sec")
async def sonar_app_on_wall_and_point(dut):
    b = Bench(dut)
    await b.start()
    await Timer(RUN_TICKS * CLK_PERIOD_PS, unit="ps")
    end_tick = b.now_tick()
    b.stop()
    await Timer(2000 * CLK_PERIOD_PS, unit="ps")
    assert not int(dut.trap_o.value), "the CPU trapped"
    assert not int(dut.bus_err_o.value), "a bus access failed"
    assert not int(b.sched.overrun_o.value), "the scheduler overran"

    # ---- mailbox
    tags = defaultdict(list)
    for w in b.mail:
        tags[w >> 28].append(w & 0x0FFFFFFF)
    assert tags[1], f"no boot word in the mailbox: {[hex(w) for w in b.mail[:8]]}"
    assert [(v >> 20, (v >> 16) & 0xF) for v in tags[7]] == [(4, 0)], f"START command: {[hex(v) for v in tags[7]]}"
    assert not tags[0xE], f"the sonar core refused the compiled-in table: {[hex(v) for v in tags[0xE]]}"
    reaims = [((v >> 20) & 0xFF, (v >> 16) & 0xF, (v >> 8) & 0xFF, (v >> 4) & 0xF, v & 0xF) for v in tags[3]]
    first_seq_after = tags[5]

    # ---- frames
    frames, replies, sp = _frames(b.link.transfers)
    assert len(replies) == 1 and replies[0].status == P.Status.OK and replies[0].seq == 1, replies
    assert struct.unpack("<I", replies[0].payload) == (0,), "START's reply: the first frame is seq 0"
    for f in frames:
        dut._log.debug("frame %d vs %d pulse %d t0 %d flags %d tof %s geo %s", f.seq, f.vs, f.pulse_seq, f.t0, f.flags,
                       [tuple(int(v) for v in r) for r in f.tof], [tuple(int(v) for v in g) for g in f.geo])
    dut._log.debug("fifo level %d", int(dut.u_sys.u_sonar.fifo_level.value))
    dut._log.debug("mailbox %s; starts %s stops %s; fires %s", [hex(w) for w in b.mail], b.starts, b.stops, b.fires)
    assert sp.bad_crc == 0 and sp.bad_header == 0 and sp.skipped_bytes == 0, sp
    assert frames, "no frame reached the host FIFO"
    assert [f.seq for f in frames] == list(range(frames[0].seq, frames[0].seq + len(frames))), \
        f"frame seq not consecutive: {[f.seq for f in frames][:20]}"
    assert frames[0].seq == 0
    assert all(int(f.head["dropped"]) == 0 and int(f.head["fifo_overflows"]) == 0 and int(f.head["watchdog"]) == 0
               for f in frames), "frames report drops, event-FIFO overflows or watchdog resets"

    # ---- re-aims: exactly one, of 'back', +1 element, accepted; table segments
    assert len(reaims) == 1, f"expected one re-aim, mailbox says {reaims}"
    count, vs, shift, err, why = reaims[0]
    assert (count, vs, shift, err, why) == (1, BACK, 1, 0, 1), reaims[0]
    assert len(b.starts) == 2 and len(b.stops) == 1, (b.starts, b.stops)
    assert len(first_seq_after) == 1
    seg_tables = [schedule_for("scene"), schedule_for("scene", rotations={BACK: 1})]
    seg_frames = [[f for f in frames if f.seq < first_seq_after[0]], [f for f in frames if f.seq >= first_seq_after[0]]]

    # geometry frames (FRAME_GEO) follow their pulse's ToF frame, keyed (vs, pulse seq, t0): a
    # pulse of the old table may get its geometry frame after the new table's first frame
    geo_after = {}
    tof_seen = set()
    for f in frames:
        key = (f.vs, f.pulse_seq, f.t0)
        if f.flags & P.FRAME_GEO:
            assert len(f.tof) == 0 and len(f.geo) == 1, f"geometry frame {f.seq}: {len(f.tof)} ToF records"
            assert key in tof_seen and key not in geo_after, f"geometry frame {f.seq} for {key}"
            geo_after[key] = f
        else:
            tof_seen.add(key)

    # ---- golden model per table segment
    src = WallPointSource()
    n_cmp = n_geo = 0
    classes = defaultdict(int)
    for k, (sched, fr) in enumerate(zip(seg_tables, seg_frames)):
        s0 = b.starts[k]
        stop = b.stops[k] if k < len(b.stops) else end_tick
        noise = [r for r in b.source.rows if r[1] + r[2] > s0] if k else []
        fires_k = [f for f in b.fires if f[0] > s0 and (k + 1 >= len(b.starts) or f[0] <= b.starts[k + 1])]
        # the gated miss rule the firmware loaded from RX_FILTER.miss_gate (it keeps the reset value)
        gate = int(b.sched.dm_q[MAIN + M_GATE].value)
        assert gate == DEFAULT_MISS_GATE, f"scheduler miss gate {gate}, RX_FILTER.miss_gate reset {DEFAULT_MISS_GATE}"
        model = FastFiringModel(sched, WithNoise(src, noise) if noise else src, start_tick=s0, decision_lead=LEAD,
                                miss_gate=gate)
        res = model.run(stop - s0)
        m_t0 = [p.t0 for p in res.pulses]
        assert [f[0] for f in fires_k][:len(m_t0)] == m_t0[:len(fires_k)], f"segment {k}: pulse ticks differ"
        groups: dict[tuple[int, int], list[tuple]] = defaultdict(list)
        last_tick: dict[tuple[int, int], int] = {}
        for e in res.events:
            last_tick[(e.sensor, e.seq)] = e.tick
            groups[(e.sensor, e.seq)].append((e.tof, e.rx, e.seq, e.sensor, int(e.in_window) | int(e.first_echo) << 1
                                              | int(e.window_empty) << 2 | int(e.init_ping) << 3))
        # pulses whose windows were still open at the segment's stop (the re-aim's apply drops them)
        cut_ok = {(p.sensor, p.seq & 0xFF) for p in res.pulses
                  if max((w[2] for w in p.windows), default=p.t0) + LEAD > stop}
        seen = set()
        for f in fr:
            if f.flags & P.FRAME_GEO:
                continue
            key = (f.vs, f.pulse_seq)
            assert key not in seen, f"segment {k}: two frames for pulse {key}"
            seen.add(key)
            got = [tuple(int(r[n]) for n in ("tof", "rx", "seq", "vs", "flags")) for r in f.tof]
            # t0: the hardware's pulse record, exact
            p = next(p for p in res.pulses if (p.sensor, p.seq & 0xFF) == key)
            assert f.t0 == p.t0 & 0xFFFFFFFF, f"frame t0 {f.t0}, the pulse's t0 {p.t0}"
            assert not f.flags & P.FRAME_LOST, f"pulse {key}: frame flags {f.flags:#x}"
            if f.flags & P.FRAME_CUT:  # the re-aim's apply dropped its open windows: what came is the model's
                assert key in cut_ok and set(got) <= set(groups.get(key, [])), f"pulse {key} cut: {got}"
                continue
            assert got == groups.get(key), f"segment {k} pulse {key}: frame {got} model {groups.get(key)}"
            n_cmp += 1
            last_ev = last_tick[key]  # the frame is closed after the pulse's last event, promptly
            assert (f.timestamp - last_ev) & 0xFFFFFFFF < 4 * MS, \
                f"timestamp {f.timestamp} is not just after the pulse's last event ({last_ev})"
            assert bool(f.flags & P.FRAME_INIT_PING) == p.init
            firsts = {int(r["rx"]): int(r["tof"]) for r in f.tof if int(r["flags"]) & 3 == 3}
            assert len(f.geo) == 0, "geometry goes in a frame of its own"
            key3 = (f.vs, f.pulse_seq, f.t0)
            if len(firsts) < 3:
                assert key3 not in geo_after
                continue
            if key3 not in geo_after and (end_tick - f.timestamp) & 0xFFFFFFFF < MS:
                continue  # committed in the last millisecond: its geometry job had not run yet
            assert key3 in geo_after, f"pulse {key} with {len(firsts)} first echoes has no geometry frame"
            assert geo_after[key3].seq > f.seq
            src_el = int(sched.validate()[f.vs].tx[0])
            g, want = geo_after[key3].geo[0], _golden_geo(firsts, src_el)
            what = f"segment {k} pulse {key}: fw {g} python {want}"
            assert int(g["cls"]) == int(want["cls"]) and int(g["n_rx"]) == int(want["n_rx"]), what
            for fld in ("x_mm", "y_mm", "range_mm"):
                assert abs(int(g[fld]) - int(want[fld])) <= 1, what
            for fld in ("bearing", "normal"):
                assert _ang_diff(g[fld], want[fld]) <= 1, what
            assert abs(int(g["quality"]) - int(want["quality"])) <= 1, what
            assert abs(int(g["residual_um"]) - int(want["residual_um"])) <= 3, what
            classes[int(g["cls"])] += 1
            n_geo += 1
            # scene truth: the wall's foot seen from the source; the edge is POINT
            if int(g["cls"]) == 2:
                ce = LAYOUT.positions[src_el]
                foot = 1000 * (ce - (float(WALL_N @ ce) - WALL_D) * WALL_N)
                assert math.hypot(int(g["x_mm"]) - foot[0], int(g["y_mm"]) - foot[1]) <= 5, what
            elif int(g["cls"]) == 1:
                assert math.hypot(int(g["x_mm"]) - POINT[0] * 1000, int(g["y_mm"]) - POINT[1] * 1000) <= 5, what
            if k == 1 and f.vs == BACK:  # re-aimed: inside the confidence interval
                axis = P.binary_angle(float(AXES[src_el]))
                assert _ang_diff(g["bearing"], axis) < 65536 * 10 / 360, what
        # every model pulse whose windows closed well before the segment's end has its frame
        for p in res.pulses:
            close = max((w[2] for w in p.windows), default=p.t0)
            if (p.sensor, p.seq & 0xFF) in groups and close + 3 * MS < stop and k + 1 == len(seg_tables):
                assert (p.sensor, p.seq & 0xFF) in seen, f"segment {k}: pulse {(p.sensor, p.seq)} closed at {close} has no frame"
    assert classes[1] >= 1 and classes[2] >= 1, f"need an edge and a wall fix, got classes {dict(classes)}"

    # ---- cycle figures
    latency = np.array(tags[2])  # pulse completion -> ToF frame committed
    busy = np.array(tags[4])
    geo_jobs = [(v >> 24, v & 0xFFFFFF) for v in tags[6]]
    geo_cycles = [c for what, c in geo_jobs if what == 0]
    assert len(geo_cycles) == n_geo and all(what in (0, 3) for what, _ in geo_jobs), geo_jobs
    span = end_tick - b.starts[0]
    load = float(busy.sum()) / span
    dut._log.info("frames %d (%d ToF-checked, %d geometry: %s), re-aims %s", len(frames), n_cmp, n_geo, dict(classes), reaims)
    dut._log.info("pulse completion -> ToF frame committed: median %d max %d cycles; a fix with its frame: median %d "
                  "max %d cycles; main loop busy %.1f%% of %d ticks (%d pulses fired)", int(np.median(latency)),
                  int(np.max(latency)), int(np.median(geo_cycles)), int(np.max(geo_cycles)), 100 * load, span,
                  len(b.fires))
    tof_frames = [f for f in frames if not f.is_geometry]
    assert len(tof_frames) == len(latency), (len(tof_frames), len(latency))
    i = int(np.argmax(latency))
    assert latency[i] < 48_000, (f"ToF frame {tof_frames[i].seq} (vs {tof_frames[i].vs}, pulse {tof_frames[i].pulse_seq}, "
                                 f"flags {tof_frames[i].flags:#x}) went {latency[i]} cycles after its pulse completed")
    dut._log.info("main-loop busy cycles between frames: median %d max %d (the max holds the re-aim: ms_prepare + "
                  "restart)", int(np.median(busy)), int(np.max(busy)))
    busy_per_pulse = float(busy.sum()) / max(len(frames), 1)
    dut._log.info("busy cycles per pulse (frame) %.0f -> %.0f pulses/s at 48 MHz", busy_per_pulse, 48e6 / busy_per_pulse)
    assert load < 0.5, f"the firmware is busy {100 * load:.0f}% of the time on this scene"
