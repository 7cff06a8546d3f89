"""`multisonar export REC --mcap OUT`: a ROS 2 bag (MCAP) read back with the reference readers.

A recording is written frame by frame with known contents (device ticks, ToF records with
their flags, geometry records), exported, and read back with mcap_ros2 (the MCAP project's own
ROS 2 decoder, which decodes from the message definitions stored in the file) and with
rosbags' CDR deserialiser: message counts per topic, ranges, stamps, points and the static
transforms must match what the recording holds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from multisonar import protocol as P
from multisonar.cli import main as cli_main
from multisonar.constants import speed_of_sound
from multisonar.device import RecordingWriter
from multisonar.layout import load_layout

pytest.importorskip("mcap")
pytest.importorskip("rosbags")
from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

TICK = 48_000_000
START = 1_700_000_000.25


def _frame(seq, t0, vs, tofs, geo=()):
    head = {"timestamp": (t0 + 30000) & 0xFFFFFFFF, "t0": t0 & 0xFFFFFFFF, "vs": vs, "pulse_seq": seq & 0xFF,
            "dropped": 0, "fifo_overflows": 0, "watchdog": 0}
    tof = np.zeros(len(tofs), P.TOF_DTYPE)
    for i, (rx, t, flags) in enumerate(tofs):
        tof[i] = (t, rx, seq & 0xFF, vs, flags)
    g = np.zeros(len(geo), P.GEO_DTYPE)
    for i, (x, y, normal, cls) in enumerate(geo):
        g[i]["x_mm"], g[i]["y_mm"], g[i]["normal"], g[i]["cls"], g[i]["quality"], g[i]["n_rx"] = \
            x, y, P.binary_angle(normal), cls, 200, 3
    pkt = P.encode_frame(seq, head, tof, g)
    return P.decode_frame(P.decode_packet(pkt, magics=(P.MAGIC_FRAME,)))


@pytest.fixture()
def recording(tmp_path):
    fin, emp = P.TOF_IN_WINDOW | P.TOF_FIRST_ECHO, P.TOF_WINDOW_EMPTY
    frames = []
    # 12 pulses of sensor 0 (rx 5, 6, 7), the 32-bit tick counter wraps between pulses 5 and 6
    t0 = (1 << 32) - 5 * 480_000
    for k in range(12):
        tofs = [(5, 300_000 + k, fin), (6, 290_000 + k, fin), (7, 310_000 + k, fin if k % 4 else emp)]
        if k == 3:
            tofs.append((6, 400_000, P.TOF_IN_WINDOW))  # a second echo: not a range reading
        geo = [(1200 + k, 50, 0.1, P.GEO_CLASSES.index("wall"))] if k % 2 == 0 else []
        frames.append(_frame(k, t0 + k * 480_000, 0, tofs, geo))
    path = tmp_path / "run.msrec"
    meta = {"format": 1, "protocol_version": P.PROTOCOL_VERSION, "url": "test://", "started_unix": START,
            "device_info": {"tick_hz": TICK}, "sensors": [{"id": 0, "name": "left", "tx": [6], "rx": [5, 6, 7],
                                                          "order": 1, "max_tof": 1_200_000}]}
    with RecordingWriter(path, meta) as w:
        for f in frames:
            w.write(f)
    return path, frames


def _read(path):
    out = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            out.setdefault(channel.topic, []).append((schema.name, message, decoded))
    return out


def test_export_mcap_reads_back(recording, tmp_path, capsys):
    rec, frames = recording
    out = tmp_path / "run.mcap"
    assert cli_main(["export", str(rec), "--mcap", str(out)]) == 0
    assert "range" in capsys.readouterr().out
    msgs = _read(out)
    lay = load_layout()
    c = speed_of_sound(20.0)
    # one Range per first echo or empty window, per receiver; the second echo is not one
    for rx in (5, 6, 7):
        got = msgs[f"/multisonar/range/rx{rx:02d}"]
        assert len(got) == 12
        assert {s for s, _, _ in got} == {"sensor_msgs/msg/Range"}
        for k, (_, m, d) in enumerate(got):
            tof_ticks = {5: 300_000 + k, 6: 290_000 + k, 7: 310_000 + k}[rx]
            empty = rx == 7 and k % 4 == 0
            assert d.header.frame_id == f"sonar_{rx:02d}"
            if empty:
                assert math.isinf(d.range) and d.range > 0
            else:
                assert d.range == pytest.approx(c * tof_ticks / TICK / 2, rel=1e-6)  # float32
            assert d.max_range == pytest.approx(c * 1_200_000 / TICK / 2, rel=1e-6)
            assert d.field_of_view == pytest.approx(2 * lay.transducer.beam_half_angle, rel=1e-6)
            # stamps: device time on the recording's start, across the 32-bit wrap
            t_expect = START + (k * 480_000 + tof_ticks) / TICK  # an empty window's ToF is its end
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
    assert len(tf.transforms) == lay.n
    for i, t in enumerate(tf.transforms):
        assert t.child_frame_id == f"sonar_{i:02d}" and t.header.frame_id == "base_link"
        assert (t.transform.translation.x, t.transform.translation.y) == pytest.approx(tuple(lay.positions[i]))
        yaw = 2 * math.atan2(t.transform.rotation.z, t.transform.rotation.w)
        assert math.remainder(yaw - lay.axes[i], 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_export_cdr_matches_rosbags(recording, tmp_path):
    """The bytes in the bag deserialise with rosbags' own CDR reader to the same values."""
    from rosbags.typesys import Stores, get_typestore

    from multisonar.export import export_mcap

    rec, _ = recording
    out = tmp_path / "run.mcap"
    counts = export_mcap(rec, out)
    assert counts["range"] == 36 and counts["range_empty"] == 3 and counts["points"] == 6 and counts["tf"] == 24
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with open(out, "rb") as fh:
        n = 0
        for schema, channel, message in make_reader(fh).iter_messages(topics=["/multisonar/range/rx06"]):
            m = ts.deserialize_cdr(message.data, schema.name)
            assert m.radiation_type == 0 and 0.2 < m.range < 4.3
            n += 1
    assert n == 12


def test_export_refuses_a_non_recording(tmp_path, capsys):
    bad = tmp_path / "x.msrec"
    bad.write_bytes(b"not a recording at all")
    assert cli_main(["export", str(bad), "--mcap", str(tmp_path / "o.mcap")]) == 1
    assert "not a Multisonar recording" in capsys.readouterr().err


def test_record_from_the_simulated_device_then_export(tmp_path):
    """End to end: `multisonar record` on sim://corridor, export, every range reading in the bag."""
    from multisonar.device import read_recording

    rec = tmp_path / "sim.msrec"
    assert cli_main(["record", "--url", "sim://corridor", "--sensors", "demo", "--frames", "30", "--out", str(rec)]) == 0
    out = tmp_path / "sim.mcap"
    assert cli_main(["export", str(rec), "--mcap", str(out)]) == 0
    ev = read_recording(rec).events()
    # a gated first echo (rejected by the gated miss rule, likely another pulse's echo) is no reading
    readings = ev[((ev["flags"] & (P.TOF_FIRST_ECHO | P.TOF_WINDOW_EMPTY)) != 0) & ((ev["flags"] & P.TOF_GATED) == 0)]
    msgs = _read(out)
    ranges = {t: v for t, v in msgs.items() if t.startswith("/multisonar/range/")}
    assert sum(len(v) for v in ranges.values()) == len(readings) > 0
    for rx in np.unique(readings["rx"]):
        assert len(ranges[f"/multisonar/range/rx{int(rx):02d}"]) == int(np.sum(readings["rx"] == rx))
    n_geo = len(read_recording(rec).geometry())
    assert sum(d.width for _, _, d in msgs.get("/multisonar/reflectors", [])) == n_geo
