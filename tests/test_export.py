"""`multisonar export REC --mcap OUT`: a ROS 2 bag (MCAP) read back with the reference readers.

A recording is written frame by frame with known contents (device ticks, ToF records with
their flags, geometry records), exported, and read back with mcap_ros2 (the MCAP project's own
ROS 2 decoder, which decodes from the message definitions stored in the file) and with
rosbags' CDR deserialiser of the distribution the file names: message counts per topic, ranges,
stamps, points and the static transforms must match what the recording holds. The Range rule
(issue #29 item 3): +inf only for an empty open window (init ping), no message for an empty or
gated tracking window; ``variance`` from the timing noise where the distribution's Range has it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from multisonar import protocol as P
from multisonar.cli import main as cli_main
from multisonar.constants import speed_of_sound
from multisonar.device import RecordingWriter
from multisonar.export import RangeLimits, range_reading, range_variance, timing_sigma_s, window_kind
from multisonar.layout import load_layout

pytest.importorskip("mcap")
pytest.importorskip("rosbags")
from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

TICK = 48_000_000
START = 1_700_000_000.25


def _frame(seq, t0, vs, tofs, geo=(), flags=0, dropped=0, fifo_overflows=0, watchdog=0):
    head = {"timestamp": (t0 + 30000) & 0xFFFFFFFF, "t0": t0 & 0xFFFFFFFF, "vs": vs, "pulse_seq": seq & 0xFF,
            "dropped": dropped, "fifo_overflows": fifo_overflows, "watchdog": watchdog}
    tof = np.zeros(len(tofs), P.TOF_DTYPE)
    for i, (rx, t, fl) in enumerate(tofs):
        tof[i] = (t, rx, seq & 0xFF, vs, fl)
    g = np.zeros(len(geo), P.GEO_DTYPE)
    for i, (x, y, normal, cls) in enumerate(geo):
        g[i]["x_mm"], g[i]["y_mm"], g[i]["normal"], g[i]["cls"], g[i]["quality"], g[i]["n_rx"] = \
            x, y, P.binary_angle(normal), cls, 200, 3
    pkt = P.encode_frame(seq, head, tof, g, flags=flags)
    return P.decode_frame(P.decode_packet(pkt, magics=(P.MAGIC_FRAME,)))


MAX_TOF = 1_200_000
#: pulse period of the fixture: a window closes before the sensor's next pulse (order 1), so every
#: receiver's acquisition times increase
PERIOD = 1_250_000
FIN, EMP, INIT = P.TOF_IN_WINDOW | P.TOF_FIRST_ECHO, P.TOF_WINDOW_EMPTY, P.TOF_INIT_PING
GATED = FIN | P.TOF_GATED


def _expected(rx, k):
    """(ToF ticks, kind) of receiver rx in pulse k of the fixture: pulse 0 is an init ping
    (rx 7's open window empty: its ToF is the window's end, MAX_TOF), then tracking pulses:
    rx 7's window empty in pulses 4 and 8, rx 6's first echo gated in pulse 6."""
    if k == 0:
        return (MAX_TOF, "no_return") if rx == 7 else ({5: 300_000, 6: 290_000}[rx], "echo")
    if rx == 7 and k % 4 == 0:
        return 310_000 + k + 24_000, "miss"  # end of the tracking window T_E + T_N
    if rx == 6 and k == 6:
        return 330_000, "gated"
    return {5: 300_000 + k, 6: 290_000 + k, 7: 310_000 + k}[rx], "echo"


def _write_recording(path, frames, *, url="test://", fmt=2):
    """A recording of ``frames`` from sensor 0 ("left": tx 6, rx 5, 6, 7) started at START."""
    meta = {"format": fmt, "protocol_version": P.PROTOCOL_VERSION, "url": url, "started_unix": START,
            "device_info": {"tick_hz": TICK}, "sensors": [{"id": 0, "name": "left", "tx": [6], "rx": [5, 6, 7],
                                                          "order": 1, "max_tof": MAX_TOF}]}
    with RecordingWriter(path, meta) as w:
        for f in frames:
            w.write(f)
    return path


@pytest.fixture()
def recording(tmp_path):
    flags_of = {"echo": FIN, "no_return": EMP, "miss": EMP, "gated": GATED}
    frames = []
    # 12 pulses of sensor 0 (rx 5, 6, 7), the 32-bit tick counter wraps between pulses 5 and 6
    t0 = (1 << 32) - 5 * PERIOD
    for k in range(12):
        tofs = []
        for rx in (5, 6, 7):
            t, kind = _expected(rx, k)
            tofs.append((rx, t, flags_of[kind] | (INIT if k == 0 else 0)))
        if k == 3:
            tofs.append((6, 400_000, P.TOF_IN_WINDOW))  # a second echo: not a range reading
        geo = [(1200 + k, 50, 0.1, P.GEO_CLASSES.index("wall"))] if k % 2 == 0 else []
        frames.append(_frame(k, t0 + k * PERIOD, 0, tofs, geo, flags=P.FRAME_INIT_PING if k == 0 else 0))
    return _write_recording(tmp_path / "run.msrec", frames, fmt=1), frames


def _read(path):
    out = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            out.setdefault(channel.topic, []).append((schema.name, message, decoded))
    return out


def _read_rosbags(path):
    """The file's metadata record and its Range messages per topic (file order), deserialised
    with rosbags' CDR reader of the distribution the file names."""
    from rosbags.typesys import Stores, get_typestore

    with open(path, "rb") as fh:
        reader = make_reader(fh)
        (meta,) = [m.metadata for m in reader.iter_metadata() if m.name == "multisonar"]
        ts = get_typestore(getattr(Stores, "ROS2_" + meta["ros_distro"].upper()))
        out = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if schema.name == "sensor_msgs/msg/Range":
                out.setdefault(channel.topic, []).append(ts.deserialize_cdr(message.data, schema.name))
    return meta, out


def _limits(c=None):
    c = speed_of_sound(20.0) if c is None else c
    return c * load_layout().transducer.ring_down_s / 2, c * MAX_TOF / TICK / 2


def test_export_mcap_reads_back(recording, tmp_path, capsys):
    rec, frames = recording
    out = tmp_path / "run.mcap"
    assert cli_main(["export", str(rec), "--mcap", str(out)]) == 0
    said = capsys.readouterr().out
    assert "range" in said and "ros_distro jazzy" in said
    msgs = _read(out)
    lay = load_layout()
    c = speed_of_sound(20.0)
    lo, hi = _limits(c)
    var = range_variance(c, TICK, timing_sigma_s("test://"))
    assert var == pytest.approx((c / 2) ** 2 * (1e-6 ** 2 + 1 / (12 * TICK ** 2)))  # the model's default jitter
    # one Range per first echo or empty open window, per receiver; none for the empty or gated
    # tracking windows (rx 7 in pulses 4 and 8, rx 6 in pulse 6) nor for the second echo
    for rx, n in ((5, 12), (6, 11), (7, 10)):
        got = msgs[f"/multisonar/range/rx{rx:02d}"]
        pulses = [k for k in range(12) if _expected(rx, k)[1] in ("echo", "no_return")]
        assert len(got) == len(pulses) == n
        assert {s for s, _, _ in got} == {"sensor_msgs/msg/Range"}
        for k, (_, m, d) in zip(pulses, got):
            tof_ticks, kind = _expected(rx, k)
            assert d.header.frame_id == f"sonar_{rx:02d}"
            if kind == "no_return":  # the open window covered [min_range, max_range]: REP 117 +inf
                assert math.isinf(d.range) and d.range > 0
            else:
                assert d.range == pytest.approx(c * tof_ticks / TICK / 2, rel=1e-6)  # float32
                assert d.min_range <= d.range <= d.max_range
            assert d.min_range == pytest.approx(lo, rel=1e-6) and d.max_range == pytest.approx(hi, rel=1e-6)
            assert d.variance == pytest.approx(var, rel=1e-6) and d.variance > 0
            assert d.field_of_view == pytest.approx(2 * lay.transducer.beam_half_angle, rel=1e-6)
            # stamps: device time on the recording's start, across the 32-bit wrap
            t_expect = START + (k * PERIOD + tof_ticks) / TICK  # an empty window's ToF is its end
            assert d.header.stamp.sec + d.header.stamp.nanosec * 1e-9 == pytest.approx(t_expect, abs=2e-6)
            assert m.log_time == d.header.stamp.sec * 1_000_000_000 + d.header.stamp.nanosec
    # reflector points: one cloud per frame with geometry, one point each
    clouds = msgs["/multisonar/reflectors"]
    assert len(clouds) == 6
    for j, (_, _, d) in enumerate(clouds):
        k = 2 * j
        assert d.width == 1 and d.header.frame_id == "base_link"
        names = [f.name for f in d.fields]
        assert names[:3] == ["x", "y", "z"]
        row = np.frombuffer(bytes(d.data), np.dtype([(f.name, "<f4" if f.datatype == 7 else "u1") for f in d.fields]))
        assert row["x"][0] == pytest.approx((1200 + k) / 1000, abs=1e-6) and row["y"][0] == pytest.approx(0.05, abs=1e-6)
        assert row["normal"][0] == pytest.approx(0.1, abs=1e-4)
        assert P.GEO_CLASSES[int(row["cls"][0])] == "wall"
    # static transforms: robot frame -> every element, yaw = element axis
    (_, _, tf), = msgs["/tf_static"]
    assert len(tf.transforms) == lay.n + 1
    ring = tf.transforms[-1]  # and to the ring's centre, the scan's origin
    assert ring.child_frame_id == "sonar_ring" and ring.header.frame_id == "base_link"
    assert (ring.transform.translation.x, ring.transform.translation.y) == pytest.approx(tuple(lay.positions.mean(0)))
    for i, t in enumerate(tf.transforms[:-1]):
        assert t.child_frame_id == f"sonar_{i:02d}" and t.header.frame_id == "base_link"
        assert (t.transform.translation.x, t.transform.translation.y) == pytest.approx(tuple(lay.positions[i]))
        yaw = 2 * math.atan2(t.transform.rotation.z, t.transform.rotation.w)
        assert math.remainder(yaw - lay.axes[i], 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("distro", ["humble", "iron", "jazzy"])
def test_export_cdr_matches_rosbags(recording, tmp_path, distro):
    """The bytes in the bag deserialise with rosbags' CDR reader of the distribution the file
    names (its metadata record and the Range schema it stores): Humble's Range has no
    variance, Iron's and Jazzy's carry the timing noise's."""
    from multisonar.export import export_mcap

    rec, _ = recording
    out = tmp_path / f"run_{distro}.mcap"
    counts = export_mcap(rec, out, ros_distro=distro)
    assert counts["ros_distro"] == distro
    assert (counts["range"], counts["range_echo"], counts["range_no_return"], counts["miss_skipped"],
            counts["gated_skipped"]) == (33, 32, 1, 2, 1)
    assert counts["points"] == 6 and counts["tf"] == 25  # 24 elements and the ring centre
    meta, ranges = _read_rosbags(out)
    assert meta["ros_distro"] == distro and "none for an empty or gated tracking window" in meta["range_rule"]
    with open(out, "rb") as fh:
        (schema,) = [s for s in make_reader(fh).get_summary().schemas.values() if s.name == "sensor_msgs/msg/Range"]
    assert (b"float32 variance" in schema.data) == (distro != "humble")
    got = ranges["/multisonar/range/rx06"]
    assert len(got) == 11  # pulse 6's first echo was gated
    for m in got:
        assert m.radiation_type == 0
        assert m.min_range <= m.range <= m.max_range and 0.2 < m.range < 4.3
        if distro == "humble":
            assert not hasattr(m, "variance")
        else:
            assert m.variance > 0 and float(meta["range_variance_m2"]) == pytest.approx(m.variance, rel=1e-6)


def test_range_reading_rule():
    """The Range rule of every kind of window (docs/host_driver.md, "ROS 2 export")."""
    c = speed_of_sound(20.0)
    lim = RangeLimits(c, TICK, 72_000, MAX_TOF, 1e-8)
    lo, hi = lim.min_range, lim.max_range
    assert (lo, hi) == pytest.approx((c * 0.0015 / 2, c * 0.025 / 2))
    for flags in (FIN | INIT, FIN):  # first echo of an init ping's or a tracking window
        r = range_reading(flags, 300_000, lim)
        assert r.kind == window_kind(flags) == "echo"
        assert (r.range, r.min_range, r.max_range, r.variance) == pytest.approx((c * 300_000 / TICK / 2, lo, hi, 1e-8))
    r = range_reading(EMP | INIT, MAX_TOF, lim)  # open window, empty: nothing in [min_range, max_range]
    assert r.kind == window_kind(EMP | INIT) == "no_return"
    assert r.range == math.inf and (r.min_range, r.max_range, r.variance) == (lo, hi, 1e-8)
    r = range_reading(EMP | INIT, MAX_TOF - 4800, lim)  # (an open window ending early: +inf up to its end)
    assert r.range == math.inf and r.max_range == pytest.approx(c * (MAX_TOF - 4800) / TICK / 2)
    # a tracking window's miss, a gated first echo, a later echo: no message
    for flags, kind in ((EMP, "miss"), (GATED, "gated"), (P.TOF_IN_WINDOW, None)):
        assert window_kind(flags) == kind and range_reading(flags, 500_000, lim) is None


def test_range_variance_is_the_timing_noise_of_the_model(tmp_path):
    """range_variance = var(c * ToF / 2) of the acoustic model's timing: a Gaussian jitter of the
    echo start (scene noise.jitter_s), then the comparator's sampling at the next tick
    (fastfiring.SceneEchoSource: ceil(start * TICK_HZ))."""
    from urllib.parse import quote

    from multisonar.scene import SCENE_DIR, Noise, load_scene

    c = speed_of_sound(20.0)
    sigma = timing_sigma_s("sim://corridor")
    assert sigma == load_scene("corridor").noise.jitter_s > 0
    assert timing_sigma_s("usb://") == timing_sigma_s("sim://no_such_scene") == Noise().jitter_s
    noisy = tmp_path / "noisy.yaml"  # a scene of its own: its jitter
    noisy.write_text((SCENE_DIR / "wall_1m.yaml").read_text().replace("jitter_s: 1.0e-6", "jitter_s: 3.0e-6"))
    assert timing_sigma_s("twin://" + quote(str(noisy), safe="")) == pytest.approx(3e-6)
    rng = np.random.default_rng(1)
    start = 0.0071234567 + rng.uniform(0, 1 / TICK, 200_000) + rng.normal(0, sigma, 200_000)
    rng_m = c * np.ceil(start * TICK - 1e-6) / TICK / 2
    assert np.var(rng_m) == pytest.approx(range_variance(c, TICK, sigma), rel=0.02)
    # without jitter the sampling alone: a tick's uniform variance
    assert range_variance(c, TICK, 0.0) == pytest.approx((c / 2 / TICK) ** 2 / 12)


def test_export_refuses_a_non_recording(tmp_path, capsys):
    bad = tmp_path / "x.msrec"
    bad.write_bytes(b"not a recording at all")
    assert cli_main(["export", str(bad), "--mcap", str(tmp_path / "o.mcap")]) == 1
    assert "not a Multisonar recording" in capsys.readouterr().err


@pytest.mark.parametrize("scene", ["corridor", "person_crossing"])
def test_record_from_the_simulated_device_then_export(tmp_path, scene):
    """End to end: `multisonar record` on a simulated scene (60 frames, ~0.1 s of sonar time),
    export, read back with rosbags: a Range message for every first echo (inside [min_range,
    max_range]) and every empty open window (+inf, the window covering [min_range, max_range]),
    none for the empty or gated tracking windows, so no +inf from a tracking window; the
    variance of the timing noise; the Humble layout deserialises with the Humble type store."""
    from multisonar.device import read_recording

    rec = tmp_path / "sim.msrec"
    assert cli_main(["record", "--url", f"sim://{scene}", "--sensors", "demo", "--frames", "60", "--out", str(rec)]) == 0
    out = tmp_path / "sim.mcap"
    assert cli_main(["export", str(rec), "--mcap", str(out)]) == 0
    recording = read_recording(rec)
    ev = recording.events()
    kinds = np.array([window_kind(int(x)) for x in ev["flags"]], dtype=object)
    published = ev[(kinds == "echo") | (kinds == "no_return")]
    meta, ranges = _read_rosbags(out)
    assert meta["ros_distro"] == "jazzy"
    assert sum(len(v) for v in ranges.values()) == len(published) > 0
    c = speed_of_sound(20.0)
    lo = c * load_layout().transducer.ring_down_s / 2
    max_tof = {int(s["id"]): int(s["max_tof"]) for s in recording.meta["sensors"]}
    var = range_variance(c, TICK, timing_sigma_s(f"sim://{scene}"))
    n_inf = 0
    for rx in np.unique(published["rx"]):
        mine = published[published["rx"] == rx]
        msgs = ranges[f"/multisonar/range/rx{int(rx):02d}"]
        assert len(msgs) == len(mine)
        for r, m in zip(mine, msgs):
            fl, tof, hi = int(r["flags"]), int(r["tof"]), c * max_tof[int(r["vs"])] / TICK / 2
            assert m.min_range == pytest.approx(lo, rel=1e-6) and m.max_range == pytest.approx(hi, rel=1e-6)
            assert m.variance == pytest.approx(var, rel=1e-6) and m.variance > 0
            assert not math.isnan(m.range)
            if math.isinf(m.range):
                # +inf: an init ping's open window, empty up to MAX_TOF: it listened over the whole range
                assert m.range > 0 and fl & P.TOF_INIT_PING and fl & P.TOF_WINDOW_EMPTY
                assert tof == max_tof[int(r["vs"])]
                n_inf += 1
            else:
                assert (fl & P.TOF_SAMPLE_MASK) == P.TOF_SAMPLE
                assert m.range == pytest.approx(c * tof / TICK / 2, rel=1e-6)
                assert m.min_range <= m.range <= m.max_range
    f = ev["flags"].astype(int)
    assert n_inf == int(np.sum(((f & P.TOF_WINDOW_EMPTY) != 0) & ((f & P.TOF_INIT_PING) != 0))) > 0
    # the scene has tracking-window misses (and gated echoes): none of them became a message
    assert np.sum(kinds == "miss") > 0 and np.sum(kinds == "gated") > 0
    n_geo = len(recording.geometry())
    assert sum(d.width for _, _, d in _read(out).get("/multisonar/reflectors", [])) == n_geo
    # the Humble layout of the same recording: the Humble type store reads it, no variance
    out_h = tmp_path / "sim_humble.mcap"
    assert cli_main(["export", str(rec), "--mcap", str(out_h), "--ros-distro", "humble"]) == 0
    meta_h, ranges_h = _read_rosbags(out_h)
    assert meta_h["ros_distro"] == "humble"
    assert sum(len(v) for v in ranges_h.values()) == len(published)
    m = next(iter(ranges_h.values()))[0]
    assert not hasattr(m, "variance") and type(m).__msgtype__ == "sensor_msgs/msg/Range"


def test_export_ring_scan(recording, tmp_path):
    """/multisonar/scan (sensor_msgs/LaserScan in frame sonar_ring): the fixture's readings
    grouped by acquisition time (t0 + ToF) into windows of one pulse period (26 ms: the init
    ping's empty open window, ending at 25 ms, shares its window with no later reading of rx 7;
    the default is 50 ms); beam rx = the nearest first echo
    (ring radius + c ToF / 2), +inf for rx 7's empty open window of the init ping when it is the
    window's only reading of rx 7, NaN for every other beam; stamp = the window's earliest
    acquisition, on the recording's start."""
    from multisonar.export import export_mcap

    rec, _ = recording
    out = tmp_path / "run.mcap"
    counts = export_mcap(rec, out, scan_period_s=PERIOD / TICK)
    scans = [d for _, _, d in _read(out)["/multisonar/scan"]]
    c = speed_of_sound(20.0)
    lo, hi = _limits(c)
    radius = float(np.hypot(*load_layout().positions.T).mean())
    period = PERIOD
    first = (1 << 32) - 5 * PERIOD
    windows: dict[int, dict[int, list]] = {}
    for k in range(12):
        for rx in (5, 6, 7):
            tof, kind = _expected(rx, k)
            if kind in ("echo", "no_return"):
                acq = first + k * PERIOD + tof
                value = radius + c * tof / TICK / 2 if kind == "echo" else math.inf
                windows.setdefault(acq // period, {}).setdefault(rx, []).append((value, acq - first))
    assert len(scans) == len(windows) == counts["scans"] > 3
    n_inf = 0
    for d, (_, w) in zip(scans, sorted(windows.items())):
        assert d.header.frame_id == "sonar_ring" and len(d.ranges) == 24
        assert (d.range_min, d.range_max) == pytest.approx((radius + lo, radius + hi), rel=1e-6)
        assert d.angle_increment == pytest.approx(math.radians(15)) and d.time_increment == 0.0
        assert d.scan_time == pytest.approx(PERIOD / TICK)
        for beam, r in enumerate(d.ranges):
            if beam not in w:
                assert math.isnan(r)
                continue
            want = min(v for v, _ in w[beam])
            n_inf += want == math.inf
            assert r == pytest.approx(want, rel=1e-6) if math.isfinite(want) else r == math.inf
        t_first = min(a for vs in w.values() for _, a in vs)
        assert d.header.stamp.sec + d.header.stamp.nanosec * 1e-9 == pytest.approx(START + t_first / TICK, abs=2e-6)
    assert n_inf == 1  # rx 7's open window of the init ping: nothing else of rx 7 in that window


def test_export_diagnostics_from_the_frame_headers(tmp_path):
    """/diagnostics of a recording, once per second of device time and at its end: the counters
    every frame header carries and frames missing by sequence number, as `multisonar live`
    reports them: the counters status rises to WARN for overflows and lost frames and to ERROR
    for a watchdog expiry; the link status names the recording."""
    from multisonar.export import export_mcap

    step = int(0.3 * TICK)
    frames = []
    for k in range(8):
        seq = k if k < 6 else k + 1  # frame 6 lost on the way
        frames.append(_frame(seq, 1000 + k * step, 0, [(6, 300_000, FIN)], dropped=0,
                             fifo_overflows=2 if k >= 5 else 0, watchdog=1 if k >= 7 else 0))
    path = _write_recording(tmp_path / "diag.msrec", frames, url="sim://corridor")
    out = tmp_path / "diag.mcap"
    counts = export_mcap(path, out)
    diags = [d for _, _, d in _read(out)["/diagnostics"]]
    assert len(diags) == counts["diagnostics"] == 3  # at 0 s, at 1.2 s, at the end (2.1 s)
    stamps = [d.header.stamp.sec + d.header.stamp.nanosec * 1e-9 - START for d in diags]
    assert stamps == pytest.approx([0.0, 1.2, 2.1], abs=1e-6)
    status = [{s.name: s for s in d.status} for d in diags]
    assert [s["multisonar/counters"].level for s in status] == [0, 0, 2]  # OK, OK, ERROR (watchdog)
    last = status[-1]["multisonar/counters"]
    assert "+2 fifo_overflows" in last.message and "+1 host_lost" in last.message and "+1 watchdog" in last.message
    assert {kv.key: kv.value for kv in last.values}["fifo_overflows"] == "2"
    link = status[-1]["multisonar/link"]
    assert link.level == 0 and "sim://corridor" in link.message and link.hardware_id == "sim://corridor"


def test_record_mcap_is_the_export_of_the_recording(tmp_path):
    """`multisonar record ... --mcap` writes the export of its recording, byte for byte, with
    the channels `multisonar live` advertises (Range only for receivers with messages)."""
    from multisonar.rosmsgs import channels

    rec, m_rec, m_exp = tmp_path / "r.msrec", tmp_path / "r.mcap", tmp_path / "e.mcap"
    assert cli_main(["record", "--url", "sim://corridor", "--frames", "80", "--out", str(rec),
                     "--mcap", str(m_rec)]) == 0
    assert cli_main(["export", str(rec), "--mcap", str(m_exp)]) == 0
    assert m_rec.read_bytes() == m_exp.read_bytes()
    with open(m_rec, "rb") as fh:
        summary = make_reader(fh).get_summary()
    got = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
    receivers = [int(t.rsplit("rx", 1)[1]) for t in got if t.startswith("/multisonar/range/")]
    assert len(receivers) >= 10
    assert got == dict(channels(receivers))


def test_cloud_of_a_geometry_frame_is_stamped_at_its_pulses_echoes(tmp_path):
    """The board sends a pulse's geometry records in a frame of their own after its ToF frame
    (flag FRAME_GEO, no ToF records, the pulse's t0): the cloud is stamped at t0 + that pulse's
    latest accepted first echo, as a cloud from a frame holding both."""
    from multisonar.export import export_mcap

    t0, step = 1000, int(0.01 * TICK)
    frames = []
    for k in range(6):
        frames.append(_frame(2 * k, t0 + k * step, 0, [(5, 300_000 + k, FIN), (6, 290_000, FIN), (7, 310_000, EMP)]))
        frames.append(_frame(2 * k + 1, t0 + k * step, 0, [], [(1200, 50, 0.1, P.GEO_CLASSES.index("wall"))],
                             flags=P.FRAME_GEO))
    assert frames[1].is_geometry
    path = _write_recording(tmp_path / "geo.msrec", frames)
    out = tmp_path / "geo.mcap"
    export_mcap(path, out)
    clouds = [d for _, _, d in _read(out)["/multisonar/reflectors"]]
    assert len(clouds) == 6
    for k, d in enumerate(clouds):  # rx 5's echo is the latest accepted one (rx 7's window was empty)
        want = START + (k * step + 300_000 + k) / TICK
        assert d.header.stamp.sec + d.header.stamp.nanosec * 1e-9 == pytest.approx(want, abs=2e-6)
