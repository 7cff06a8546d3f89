"""Export a recording (``.msrec``, docs/host_driver.md) as a ROS 2 bag in MCAP format.

``multisonar export REC --mcap OUT.mcap`` writes one MCAP file with the ``ros2`` profile
(schema encoding ``ros2msg``, message encoding ``cdr``: what rosbag2's MCAP storage plugin
writes, so ``ros2 bag play OUT.mcap``, Foxglove and the ``mcap`` / ``rosbags`` libraries read
it). Message definitions and CDR serialisation come from the ``rosbags`` type store (ROS 2
Humble definitions); the container from the ``mcap`` package.

Topics:

``/tf_static`` (tf2_msgs/msg/TFMessage, once)
    ``FRAME_ID`` (default ``base_link``, the robot frame) -> ``sonar_NN`` for every element of
    the layout: position and axis (yaw) from the layout file.
``/multisonar/range/rxNN`` (sensor_msgs/msg/Range, frame ``sonar_NN``)
    one message per first echo or empty window of receiver NN: ``range`` = c * ToF / 2 (half
    the sound path: exact for the transmitting element, the mean leg for a neighbour); an empty
    window is ``+inf`` (REP 117: nothing detected); ``min_range`` = c * T_dead / 2,
    ``max_range`` = c * MAX_TOF / 2 of the sensor, ``field_of_view`` = 2 x the beam half angle.
``/multisonar/reflectors`` (sensor_msgs/msg/PointCloud2, frame ``FRAME_ID``)
    one cloud per frame with geometry records: a point per fix (edge position / wall foot) with
    fields x, y, z (float32, m), normal (float32, rad: wall normal bearing, 0 for points),
    quality (float32, 0..1), cls (uint8, index into protocol.GEO_CLASSES), vs (uint8).

Time: header stamps and log times are device time (the frame's t0, unwrapped from 32 bits)
placed on the recording's start (``started_unix`` of its meta). A robot-to-world transform is
not written: recordings hold no pose (a tf from odometry can be merged into the bag later).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from . import protocol as P
from .constants import speed_of_sound

RANGE_TOPIC = "/multisonar/range/rx{:02d}"
POINTS_TOPIC = "/multisonar/reflectors"
TF_TOPIC = "/tf_static"
ELEMENT_FRAME = "sonar_{:02d}"

#: PointField datatypes (sensor_msgs/msg/PointField)
_UINT8, _FLOAT32 = 2, 7
POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("normal", "<f4"), ("quality", "<f4"),
                        ("cls", "u1"), ("vs", "u1")])


class ExportError(RuntimeError):
    """The export cannot run (missing package, unusable recording)."""


def _imports() -> tuple[Any, Any]:
    try:
        from mcap.writer import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError as e:
        raise ExportError(f"MCAP export needs the 'mcap' and 'rosbags' packages ({e.name} missing): "
                          ".venv/bin/pip install -r requirements.txt") from None
    return Writer, get_typestore(Stores.ROS2_HUMBLE)


def _stamp(ts: Any, ns: int) -> Any:
    Time = ts.types["builtin_interfaces/msg/Time"]
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def _header(ts: Any, ns: int, frame: str) -> Any:
    return ts.types["std_msgs/msg/Header"](stamp=_stamp(ts, ns), frame_id=frame)


def export_mcap(recording: str | Path, out: str | Path, *, frame_id: str = "base_link", temperature_c: float = 20.0,
                layout: Any = None) -> dict[str, int]:
    """Write the bag; returns message counts per kind ({'range': n, 'range_empty': n, 'points': n,
    'clouds': n, 'tf': n, 'frames': n}) and the gated first echoes not written ('gated_skipped')."""
    from .device import read_recording
    from .layout import load_layout

    Writer, ts = _imports()
    rec = read_recording(recording)
    if not rec.frames:
        raise ExportError(f"{recording}: the recording holds no frames")
    lay = load_layout() if layout is None else layout
    info = rec.meta.get("device_info") or {}
    tick_hz = int(info.get("tick_hz") or 48_000_000)
    c = speed_of_sound(temperature_c)
    sensors = {int(s["id"]): s for s in rec.meta.get("sensors", [])}
    start_ns = int(round(float(rec.meta.get("started_unix", 0.0)) * 1e9))
    # unwrap the 32-bit device tick of each frame's t0
    t0 = np.array([f.t0 for f in rec.frames], dtype=np.int64)
    t0u = t0 + (np.concatenate([[0], np.cumsum(np.diff(t0) < -(1 << 31))]) << 32)
    ns = start_ns + np.rint((t0u - t0u.min()) * 1e9 / tick_hz).astype(np.int64)

    T = ts.types
    Range, PointCloud2, PointField = T["sensor_msgs/msg/Range"], T["sensor_msgs/msg/PointCloud2"], T["sensor_msgs/msg/PointField"]
    TFMessage, TransformStamped = T["tf2_msgs/msg/TFMessage"], T["geometry_msgs/msg/TransformStamped"]
    Transform, Vector3, Quaternion = T["geometry_msgs/msg/Transform"], T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    counts = {"frames": len(rec.frames), "range": 0, "range_empty": 0, "clouds": 0, "points": 0, "tf": 0,
              "gated_skipped": 0}
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "wb") as fh:
        w = Writer(fh)
        w.start(profile="ros2", library="multisonar")
        channels: dict[str, int] = {}
        schemas: dict[str, int] = {}

        def channel(topic: str, typename: str) -> int:
            if topic not in channels:
                if typename not in schemas:
                    text, _ = ts.generate_msgdef(typename, ros_version=2)
                    schemas[typename] = w.register_schema(name=typename, encoding="ros2msg", data=text.encode())
                qos = ("- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n  deadline:\n    sec: 2147483647\n"
                       "    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n"
                       "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
                       "  avoid_ros_namespace_conventions: false\n") if topic == TF_TOPIC else ""
                channels[topic] = w.register_channel(topic=topic, message_encoding="cdr", schema_id=schemas[typename],
                                                     metadata={"offered_qos_profiles": qos} if qos else {})
            return channels[topic]

        def put(topic: str, typename: str, msg: Any, t_ns: int) -> None:
            w.add_message(channel(topic, typename), log_time=int(t_ns), publish_time=int(t_ns),
                          data=bytes(ts.serialize_cdr(msg, typename)))

        # static transforms: robot frame -> each element (position, yaw = axis)
        tfs = []
        for i, ((x, y), a) in enumerate(zip(lay.positions, lay.axes)):
            tfs.append(TransformStamped(header=_header(ts, int(ns[0]), frame_id), child_frame_id=ELEMENT_FRAME.format(i),
                                        transform=Transform(translation=Vector3(x=float(x), y=float(y), z=0.0),
                                                            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(a / 2),
                                                                                w=math.cos(a / 2)))))
        put(TF_TOPIC, "tf2_msgs/msg/TFMessage", TFMessage(transforms=tfs), int(ns[0]))
        counts["tf"] = len(tfs)

        fov = float(2 * lay.transducer.beam_half_angle)
        min_range = float(c * lay.transducer.ring_down_s / 2)
        for f, t_ns in zip(rec.frames, ns):
            s = sensors.get(f.vs, {})
            max_range = float(c * int(s.get("max_tof", 0)) / tick_hz / 2) if s.get("max_tof") else 4.3
            for r in f.tof:
                flags = int(r["flags"])
                if flags & P.TOF_WINDOW_EMPTY:
                    rng = math.inf
                    counts["range_empty"] += 1
                elif flags & P.TOF_GATED:  # rejected by the gated miss rule: likely another pulse's echo
                    counts["gated_skipped"] += 1
                    continue
                elif flags & P.TOF_FIRST_ECHO:
                    rng = float(c * int(r["tof"]) / tick_hz / 2)
                else:
                    continue  # later echoes in the same window: not a range reading
                rx = int(r["rx"])
                stamp_ns = int(t_ns) + int(round(int(r["tof"]) * 1e9 / tick_hz))
                msg = Range(header=_header(ts, stamp_ns, ELEMENT_FRAME.format(rx)), radiation_type=Range.ULTRASOUND,
                            field_of_view=fov, min_range=min_range, max_range=max_range, range=rng)
                put(RANGE_TOPIC.format(rx), "sensor_msgs/msg/Range", msg, stamp_ns)
                counts["range"] += 1
            if len(f.geo):
                pts = np.zeros(len(f.geo), POINT_DTYPE)
                pts["x"] = f.geo["x_mm"] / 1000.0
                pts["y"] = f.geo["y_mm"] / 1000.0
                pts["normal"] = P.from_binary_angle(f.geo["normal"])
                pts["quality"] = f.geo["quality"] / 255.0
                pts["cls"] = f.geo["cls"]
                pts["vs"] = f.vs
                fields = [PointField(name=n, offset=POINT_DTYPE.fields[n][1],
                                     datatype=_UINT8 if POINT_DTYPE[n] == np.uint8 else _FLOAT32, count=1)
                          for n in POINT_DTYPE.names]
                cloud = PointCloud2(header=_header(ts, int(t_ns), frame_id), height=1, width=len(pts), fields=fields,
                                    is_bigendian=False, point_step=POINT_DTYPE.itemsize,
                                    row_step=POINT_DTYPE.itemsize * len(pts),
                                    data=np.frombuffer(pts.tobytes(), np.uint8), is_dense=True)
                put(POINTS_TOPIC, "sensor_msgs/msg/PointCloud2", cloud, int(t_ns))
                counts["clouds"] += 1
                counts["points"] += len(pts)
        w.finish()
    return counts
