"""Export a recording (``.msrec``, docs/host_driver.md) as a ROS 2 bag in MCAP format.

``multisonar export REC --mcap OUT.mcap [--ros-distro humble|iron|jazzy]`` writes one MCAP
file with the ``ros2`` profile (schema encoding ``ros2msg``, message encoding ``cdr``: what
rosbag2's MCAP storage plugin writes, so ``ros2 bag play OUT.mcap``, Foxglove and the ``mcap``
/ ``rosbags`` libraries read it). Message definitions and CDR serialisation come from the
``rosbags`` type store of the chosen distribution (default Jazzy); the container from the
``mcap`` package. An MCAP metadata record ``multisonar`` names the distribution whose message
layout was written (``ros_distro``) and the Range rule and variance used.

Topics:

``/tf_static`` (tf2_msgs/msg/TFMessage, once)
    ``FRAME_ID`` (default ``base_link``, the robot frame) -> ``sonar_NN`` for every element of
    the layout: position and axis (yaw) from the layout file.
``/multisonar/range/rxNN`` (sensor_msgs/msg/Range, frame ``sonar_NN``)
    built by :func:`range_reading` (REP 117 as far as a windowed receiver allows;
    docs/host_driver.md, "ROS 2 export"): one message per first echo of receiver NN, ``range``
    = c * ToF / 2 (half the sound path: exact for the transmitting element, the mean leg for a
    neighbour), and one per empty *open* window (init ping: the receiver listened over the
    whole [min_range, max_range]), ``range`` = +inf. An empty or gated *tracking* window (it
    listened around its predicted echo only, so it says nothing about the cone) gets no
    message. ``min_range`` = c * D / 2 (blanking, default the ring-down T_dead), ``max_range``
    = c * MAX_TOF / 2 of the sensor, ``field_of_view`` = 2 x the beam half angle, ``variance``
    (Iron and later) from the timing noise (:func:`range_variance`).
``/multisonar/reflectors`` (sensor_msgs/msg/PointCloud2, frame ``FRAME_ID``)
    one cloud per frame with geometry records: a point per fix (edge position / wall foot) with
    fields x, y, z (float32, m), normal (float32, rad: wall normal bearing, 0 for points),
    quality (float32, 0..1), cls (uint8, index into protocol.GEO_CLASSES), vs (uint8).

Time: header stamps and log times are device time (the frame's t0, unwrapped from 32 bits)
placed on the recording's start (``started_unix`` of its meta); a Range message is stamped at
t0 + ToF (an empty window: its end). A robot-to-world transform is not written: recordings
hold no pose (a tf from odometry can be merged into the bag later).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from . import protocol as P
from .constants import speed_of_sound

RANGE_TOPIC = "/multisonar/range/rx{:02d}"
POINTS_TOPIC = "/multisonar/reflectors"
TF_TOPIC = "/tf_static"
ELEMENT_FRAME = "sonar_{:02d}"
#: MCAP metadata record naming the message layout and the Range rule of the file
METADATA_NAME = "multisonar"

#: ROS 2 distributions whose message layout the export writes (rosbags type store names);
#: sensor_msgs/msg/Range has ``float32 variance`` from Iron on (Humble has none)
ROS_DISTROS = {"humble": "ROS2_HUMBLE", "iron": "ROS2_IRON", "jazzy": "ROS2_JAZZY"}
DEFAULT_ROS_DISTRO = "jazzy"
#: version of the Range rule of :func:`range_reading` (written to the metadata record)
RANGE_RULE = ("multisonar-range-2: one message per first echo (c*ToF/2) and per empty open (init ping) window "
              "(+inf); none for an empty or gated tracking window; min_range/max_range: the sensor's")

#: PointField datatypes (sensor_msgs/msg/PointField)
_UINT8, _FLOAT32 = 2, 7
POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("normal", "<f4"), ("quality", "<f4"),
                        ("cls", "u1"), ("vs", "u1")])


class ExportError(RuntimeError):
    """The export cannot run (missing package, unusable recording)."""


# --------------------------------------------------------------------------------------------
# Range semantics (shared with any live publisher of sensor_msgs/Range)
# --------------------------------------------------------------------------------------------

class RangeLimits(NamedTuple):
    """What a Range message of one virtual sensor needs besides the ToF record."""

    c: float  #: speed of sound, m/s
    tick_hz: int
    blank: int  #: ticks from t0: start of the open window (blanking D; ring-down T_dead by default)
    max_tof: int  #: ticks from t0: end of the open window (MAX_TOF)
    variance: float  #: m^2, :func:`range_variance`

    @property
    def min_range(self) -> float:
        return self.c * self.blank / self.tick_hz / 2

    @property
    def max_range(self) -> float:
        return self.c * self.max_tof / self.tick_hz / 2


class RangeReading(NamedTuple):
    """The fields of a sensor_msgs/msg/Range to publish for one window."""

    range: float  #: m; +inf: no return within [min_range, max_range] (REP 117)
    min_range: float
    max_range: float
    variance: float  #: m^2 (only Iron and later carry it)
    kind: str  #: "echo" or "no_return" (:func:`window_kind`)


#: window_kind values, in the order the export counts them: a Range message for the first two,
#: none for the others
WINDOW_KINDS = ("echo", "no_return", "miss", "gated")


def window_kind(flags: int) -> str | None:
    """What a ToF record (protocol.TOF_DTYPE flags) ends: "echo" (the window's first echo,
    accepted), "no_return" (an init ping's open window, empty), "miss" (a tracking window,
    empty), "gated" (a tracking window whose first echo the gated miss rule rejected: the
    device counts the window as a miss), or None (a later echo of a window: no window end)."""
    flags = int(flags)
    if flags & P.TOF_GATED:
        return "gated"
    if flags & P.TOF_WINDOW_EMPTY:
        return "no_return" if flags & P.TOF_INIT_PING else "miss"
    if flags & P.TOF_FIRST_ECHO:
        return "echo"
    return None


def range_variance(c: float, tick_hz: int, timing_sigma_s: float) -> float:
    """Variance (m^2) of range = c * ToF / 2 from the timing noise of a first echo: the acoustic
    model's Gaussian jitter of the echo start (``scene.Noise.jitter_s``, sigma in s) and the
    comparator's sampling at the tick (the start is rounded up to the next tick: uniform over
    one tick, variance 1/12 tick^2): (c/2)^2 * (sigma^2 + 1 / (12 f_tick^2))."""
    return (c / 2) ** 2 * (float(timing_sigma_s) ** 2 + 1.0 / (12.0 * float(tick_hz) ** 2))


def sensor_limits(sensor: Mapping[str, Any], *, c: float, tick_hz: int, ring_down_s: float,
                  timing_sigma_s: float) -> RangeLimits:
    """RangeLimits of a virtual sensor from its recording meta entry (``max_tof``, ticks; an
    optional ``blank``, ticks, else the layout's ring-down ``ring_down_s``). Without ``max_tof``
    the schedule's default max range is used."""
    from .schedule import DEFAULT_MAX_RANGE_M

    blank = sensor.get("blank")
    blank = int(blank) if blank else int(round(ring_down_s * tick_hz))
    max_tof = sensor.get("max_tof")
    max_tof = int(max_tof) if max_tof else int(round(2 * DEFAULT_MAX_RANGE_M / c * tick_hz))
    return RangeLimits(float(c), int(tick_hz), blank, max_tof, range_variance(c, tick_hz, timing_sigma_s))


def range_reading(flags: int, tof: int, lim: RangeLimits) -> RangeReading | None:
    """The sensor_msgs/msg/Range to publish for one ToF record (flags and ToF as in
    protocol.TOF_DTYPE), or None: no message.

    ==========================================  ===========  =========  ====================
    window (record flags, :func:`window_kind`)  range        min_range  max_range
    ==========================================  ===========  =========  ====================
    first echo accepted (TOF_SAMPLE), any       c ToF / 2    c D / 2    c MAX_TOF / 2
    init ping's open window empty               +inf         c D / 2    c MAX_TOF / 2 (its end)
    tracking window empty                       no message
    tracking window, first echo gated           no message
    later echo of a window                      no message
    ==========================================  ===========  =========  ====================

    +inf (REP 117: no return within [min_range, max_range]) only where the receiver listened
    over that whole interval: an init ping's open window runs from the blanking D to MAX_TOF.
    A tracking window covers T_V + T_N around the predicted echo only: its miss says nothing
    about the rest of the cone (an object can have come closer), so it is no reading at all,
    neither +inf (a consumer clears the cone) nor NaN (REP 117's invalid reading, which
    nav2's range sensor layer does not filter: it marks a cell through an undefined NaN cast).
    A gated first echo (likely another pulse's echo, its range is not this pulse's) makes the
    window a miss on the device: no message either. The variance is the sensor's, the same
    on every message (0 would mean unknown).
    """
    kind = window_kind(flags)
    if kind == "echo":
        return RangeReading(lim.c * int(tof) / lim.tick_hz / 2, lim.min_range, lim.max_range, lim.variance, kind)
    if kind == "no_return":
        # the open window ends at MAX_TOF (the record's ToF is its end): +inf up to what it covered
        end = min(int(tof), lim.max_tof)
        return RangeReading(math.inf, lim.min_range, lim.c * end / lim.tick_hz / 2, lim.variance, kind)
    return None


def timing_sigma_s(url: str | None) -> float:
    """Echo timing jitter (sigma, s) of the recording's source: the scene's ``noise.jitter_s``
    for a simulated device (``sim://SCENE``, ``twin://SCENE``), else the acoustic model's
    default (``scene.Noise``), which is what the simulation assumes of the hardware."""
    from .scene import Noise, SceneError, load_scene
    from .urls import parse_url

    u = parse_url(url or "")
    if u.scheme in ("sim", "twin") and u.target:
        try:
            return float(load_scene(u.target).noise.jitter_s)
        except (SceneError, OSError):
            pass
    return float(Noise().jitter_s)


# --------------------------------------------------------------------------------------------
# MCAP writer
# --------------------------------------------------------------------------------------------

def _imports(ros_distro: str) -> tuple[Any, Any]:
    if ros_distro not in ROS_DISTROS:
        raise ExportError(f"unknown ROS 2 distribution {ros_distro!r}: one of {', '.join(ROS_DISTROS)}")
    try:
        from mcap.writer import Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError as e:
        raise ExportError(f"MCAP export needs the 'mcap' and 'rosbags' packages ({e.name} missing): "
                          ".venv/bin/pip install -r requirements.txt") from None
    return Writer, get_typestore(getattr(Stores, ROS_DISTROS[ros_distro]))


def _stamp(ts: Any, ns: int) -> Any:
    Time = ts.types["builtin_interfaces/msg/Time"]
    return Time(sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def _header(ts: Any, ns: int, frame: str) -> Any:
    return ts.types["std_msgs/msg/Header"](stamp=_stamp(ts, ns), frame_id=frame)


def export_mcap(recording: str | Path, out: str | Path, *, frame_id: str = "base_link", temperature_c: float = 20.0,
                layout: Any = None, ros_distro: str = DEFAULT_ROS_DISTRO,
                timing_sigma: float | None = None) -> dict[str, Any]:
    """Write the bag in the message layout of ``ros_distro`` (humble, iron, jazzy). Returns
    {'ros_distro': name} and counts: 'range' (Range messages) = 'range_echo' + 'range_no_return'
    (+inf); the windows without a message (:func:`range_reading`): 'miss_skipped' (empty
    tracking windows), 'gated_skipped' (gated first echoes); 'clouds', 'points', 'tf' and the
    recording's 'frames'.
    ``timing_sigma``: echo timing jitter (s) for the variance; default :func:`timing_sigma_s`
    of the recording's URL."""
    from .device import read_recording
    from .layout import load_layout

    Writer, ts = _imports(ros_distro)
    rec = read_recording(recording)
    if not rec.frames:
        raise ExportError(f"{recording}: the recording holds no frames")
    lay = load_layout() if layout is None else layout
    info = rec.meta.get("device_info") or {}
    tick_hz = int(info.get("tick_hz") or 48_000_000)
    c = speed_of_sound(temperature_c)
    sigma = timing_sigma_s(rec.meta.get("url")) if timing_sigma is None else float(timing_sigma)
    limits: dict[int, RangeLimits] = {}

    def sensor(vs: int) -> RangeLimits:
        if vs not in limits:
            meta = next((s for s in rec.meta.get("sensors", []) if int(s["id"]) == vs), {})
            limits[vs] = sensor_limits(meta, c=c, tick_hz=tick_hz, ring_down_s=lay.transducer.ring_down_s,
                                       timing_sigma_s=sigma)
        return limits[vs]

    start_ns = int(round(float(rec.meta.get("started_unix", 0.0)) * 1e9))
    # unwrap the 32-bit device tick of each frame's t0
    t0 = np.array([f.t0 for f in rec.frames], dtype=np.int64)
    t0u = t0 + (np.concatenate([[0], np.cumsum(np.diff(t0) < -(1 << 31))]) << 32)
    ns = start_ns + np.rint((t0u - t0u.min()) * 1e9 / tick_hz).astype(np.int64)

    T = ts.types
    Range, PointCloud2, PointField = T["sensor_msgs/msg/Range"], T["sensor_msgs/msg/PointCloud2"], T["sensor_msgs/msg/PointField"]
    TFMessage, TransformStamped = T["tf2_msgs/msg/TFMessage"], T["geometry_msgs/msg/TransformStamped"]
    Transform, Vector3, Quaternion = T["geometry_msgs/msg/Transform"], T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    has_variance = "variance" in Range.__dataclass_fields__
    counts: dict[str, Any] = {"ros_distro": ros_distro, "frames": len(rec.frames), "range": 0, "range_echo": 0,
                              "range_no_return": 0, "miss_skipped": 0, "gated_skipped": 0, "clouds": 0, "points": 0,
                              "tf": 0}
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
        for f, t_ns in zip(rec.frames, ns):
            lim = sensor(int(f.vs))
            for r in f.tof:
                kind = window_kind(int(r["flags"]))
                reading = range_reading(int(r["flags"]), int(r["tof"]), lim)
                if reading is None:  # a tracking window's miss or gated echo, or a later echo
                    if kind is not None:
                        counts[f"{kind}_skipped"] += 1
                    continue
                rx = int(r["rx"])
                stamp_ns = int(t_ns) + int(round(int(r["tof"]) * 1e9 / tick_hz))
                fields = dict(header=_header(ts, stamp_ns, ELEMENT_FRAME.format(rx)), radiation_type=Range.ULTRASOUND,
                              field_of_view=fov, min_range=reading.min_range, max_range=reading.max_range,
                              range=reading.range)
                if has_variance:
                    fields["variance"] = reading.variance
                put(RANGE_TOPIC.format(rx), "sensor_msgs/msg/Range", Range(**fields), stamp_ns)
                counts["range"] += 1
                counts[f"range_{kind}"] += 1
            if len(f.geo):
                pts = np.zeros(len(f.geo), POINT_DTYPE)
                pts["x"] = f.geo["x_mm"] / 1000.0
                pts["y"] = f.geo["y_mm"] / 1000.0
                pts["normal"] = P.from_binary_angle(f.geo["normal"])
                pts["quality"] = f.geo["quality"] / 255.0
                pts["cls"] = f.geo["cls"]
                pts["vs"] = f.vs
                pfields = [PointField(name=n, offset=POINT_DTYPE.fields[n][1],
                                      datatype=_UINT8 if POINT_DTYPE[n] == np.uint8 else _FLOAT32, count=1)
                           for n in POINT_DTYPE.names]
                cloud = PointCloud2(header=_header(ts, int(t_ns), frame_id), height=1, width=len(pts), fields=pfields,
                                    is_bigendian=False, point_step=POINT_DTYPE.itemsize,
                                    row_step=POINT_DTYPE.itemsize * len(pts),
                                    data=np.frombuffer(pts.tobytes(), np.uint8), is_dense=True)
                put(POINTS_TOPIC, "sensor_msgs/msg/PointCloud2", cloud, int(t_ns))
                counts["clouds"] += 1
                counts["points"] += len(pts)
        variance = range_variance(c, tick_hz, sigma)
        w.add_metadata(METADATA_NAME, {
            "ros_distro": ros_distro,
            "range_rule": RANGE_RULE,
            # the variance of every Range message; Humble's Range has no variance field
            "range_variance_m2": repr(variance) if has_variance else f"none ({ros_distro} Range has no variance)",
            "timing_sigma_s": repr(sigma),
            "speed_of_sound_mps": repr(c),
            "recording_url": str(rec.meta.get("url", "")),
        })
        w.finish()
    return counts
