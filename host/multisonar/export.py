"""Export a recording (``.msrec``, docs/host_driver.md) as a ROS 2 bag in MCAP format.

``multisonar export REC --mcap OUT.mcap [--ros-distro humble|iron|jazzy]`` (and ``multisonar
record ... --mcap OUT.mcap``, which records and then exports) writes one MCAP file with the
``ros2`` profile (schema encoding ``ros2msg``, message encoding ``cdr``: what rosbag2's MCAP
storage plugin writes, so ``ros2 bag play OUT.mcap``, Foxglove and the ``mcap`` / ``rosbags``
libraries read it). The messages come from :mod:`multisonar.rosmsgs`, the code path of the live
Foxglove stream (``multisonar live``), so a recording and a live session have the same channels
and types; definitions and CDR from the ``rosbags`` type store of the chosen distribution
(default Jazzy); the container from the ``mcap`` package. An MCAP metadata record
``multisonar`` names the distribution whose message layout was written (``ros_distro``) and the
Range and scan rules and variance used.

Topics (:func:`multisonar.rosmsgs.channels`):

``/tf_static`` (tf2_msgs/msg/TFMessage, once)
    ``FRAME_ID`` (default ``base_link``, the robot frame) -> ``sonar_NN`` for every element of
    the layout: position and axis (yaw) from the layout file; -> ``sonar_ring``, the ring's centre.
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
``/multisonar/scan`` (sensor_msgs/msg/LaserScan, frame ``sonar_ring``)
    the ring as 24 beams (:class:`multisonar.rosmsgs.ScanWindows`, docs/live.md).
``/multisonar/reflectors`` (sensor_msgs/msg/PointCloud2, frame ``FRAME_ID``)
    one cloud per frame with geometry records: a point per fix (edge position / wall foot) with
    fields x, y, z (float32, m), normal (float32, rad: wall normal bearing, 0 for points),
    quality (float32, 0..1), cls (uint8, index into protocol.GEO_CLASSES), vs (uint8).
``/diagnostics`` (diagnostic_msgs/msg/DiagnosticArray, once per second of recording)
    the counters every frame header carries (device drops, event-FIFO overflows, watchdog) and
    frames lost by sequence number, as ``multisonar live`` reports them.

Time: header stamps and log times are device time (the frame's t0, unwrapped from 32 bits)
placed on the recording's start (``started_unix`` of its meta); a Range message is stamped at
t0 + ToF (an empty window: its end). A robot-to-world transform is not written: recordings
hold no pose (a tf from odometry can be merged into the bag later).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .constants import speed_of_sound
# the Range rule and the topic names live in rosmsgs (shared with multisonar live); these names
# stay importable from here
from .rosmsgs import (DEFAULT_ROS_DISTRO, ELEMENT_FRAME, OK, POINT_DTYPE, POINTS_TOPIC, RANGE_RULE,  # noqa: F401
                      RANGE_TOPIC, ROS_DISTROS, SCAN_RULE, TF_TOPIC, WINDOW_KINDS, Publisher, RangeLimits,
                      RangeReading, RingMessages, RosMsgError, RosTypes, range_reading, range_variance,
                      sensor_limits, timing_sigma_s, window_kind)

__all__ = ["DEFAULT_ROS_DISTRO", "ELEMENT_FRAME", "METADATA_NAME", "POINT_DTYPE", "POINTS_TOPIC", "RANGE_RULE",
           "RANGE_TOPIC", "ROS_DISTROS", "SCAN_RULE", "TF_TOPIC", "WINDOW_KINDS", "ExportError", "McapSink",
           "RangeLimits", "RangeReading", "export_mcap", "range_reading", "range_variance", "sensor_limits",
           "timing_sigma_s", "window_kind"]

#: MCAP metadata record naming the message layout and the Range rule of the file
METADATA_NAME = "multisonar"
#: /tf_static is latched in ROS 2 (transient local): rosbag2 stores the offered QoS with the channel
_TF_STATIC_QOS = ("- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n  deadline:\n    sec: 2147483647\n"
                  "    nsec: 4294967295\n  lifespan:\n    sec: 2147483647\n    nsec: 4294967295\n  liveliness: 1\n"
                  "  liveliness_lease_duration:\n    sec: 2147483647\n    nsec: 4294967295\n"
                  "  avoid_ros_namespace_conventions: false\n")


class ExportError(RuntimeError):
    """The export cannot run (missing package, unusable recording)."""


class McapSink:
    """A :class:`multisonar.rosmsgs.Sink` writing a ROS 2 bag in MCAP (profile ``ros2``)."""

    def __init__(self, fh: Any) -> None:
        try:
            from mcap.writer import Writer
        except ImportError:
            raise ExportError("MCAP export needs the 'mcap' package: .venv/bin/pip install -r requirements.txt") \
                from None
        self.writer = Writer(fh)
        self.writer.start(profile="ros2", library="multisonar")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}

    def add_channel(self, topic: str, typename: str, msgdef: str) -> None:
        if typename not in self._schemas:
            self._schemas[typename] = self.writer.register_schema(name=typename, encoding="ros2msg",
                                                                  data=msgdef.encode())
        meta = {"offered_qos_profiles": _TF_STATIC_QOS} if topic == TF_TOPIC else {}
        self._channels[topic] = self.writer.register_channel(topic=topic, message_encoding="cdr",
                                                             schema_id=self._schemas[typename], metadata=meta)

    def write(self, topic: str, data: bytes, log_time_ns: int) -> None:
        self.writer.add_message(self._channels[topic], log_time=int(log_time_ns), publish_time=int(log_time_ns),
                                data=data)

    def metadata(self, name: str, values: dict[str, str]) -> None:
        self.writer.add_metadata(name, values)

    def finish(self) -> None:
        self.writer.finish()


class _HeadCounters:
    """Counters from the frame headers of a recording (what every frame carries: the device's
    drops, event-FIFO overflows and watchdog expiries, 16 bits for the last two) and frames lost
    by sequence number, under Device.counters() names."""

    def __init__(self) -> None:
        self.values = {"frames_dropped": 0, "fifo_overflows": 0, "watchdog": 0, "host_lost": 0, "host_frames": 0}
        self._head: tuple[int, int, int] | None = None
        self._seq: int | None = None

    def frame(self, f: Any) -> None:
        h = (int(f.head["dropped"]), int(f.head["fifo_overflows"]), int(f.head["watchdog"]))
        if self._head is not None:
            for key, new, old, mask in zip(("frames_dropped", "fifo_overflows", "watchdog"), h, self._head,
                                           (0xFFFFFFFF, 0xFFFF, 0xFFFF)):
                d = (new - old) & mask
                self.values[key] += d if d < (mask + 1) // 2 else 0  # a restart (cleared counters): no loss
        self._head = h
        if self._seq is not None:
            gap = (f.seq - self._seq - 1) & 0xFFFFFFFF
            self.values["host_lost"] += gap if gap < 1 << 31 else 0
        self._seq = int(f.seq)
        self.values["host_frames"] += 1


def export_mcap(recording: str | Path, out: str | Path, *, frame_id: str = "base_link", temperature_c: float = 20.0,
                layout: Any = None, ros_distro: str = DEFAULT_ROS_DISTRO,
                timing_sigma: float | None = None, scan_period_s: float | None = None) -> dict[str, Any]:
    """Write the bag in the message layout of ``ros_distro`` (humble, iron, jazzy). Returns
    {'ros_distro': name} and counts: 'range' (Range messages) = 'range_echo' + 'range_no_return'
    (+inf); the windows without a message (:func:`range_reading`): 'miss_skipped' (empty
    tracking windows), 'gated_skipped' (gated first echoes); 'scans', 'clouds', 'points', 'tf',
    'diagnostics' and the recording's 'frames'.
    ``timing_sigma``: echo timing jitter (s) for the variance; default :func:`timing_sigma_s`
    of the recording's URL. ``scan_period_s``: the LaserScan's window of device time
    (default rosmsgs.DEFAULT_SCAN_PERIOD_S)."""
    from .device import read_recording
    from .layout import load_layout
    from .rosmsgs import DEFAULT_SCAN_PERIOD_S

    try:
        types = RosTypes(ros_distro)
    except RosMsgError as e:
        raise ExportError(str(e)) from None
    rec = read_recording(recording)
    if not rec.frames:
        raise ExportError(f"{recording}: the recording holds no frames")
    lay = load_layout() if layout is None else layout
    info = rec.meta.get("device_info") or {}
    tick_hz = int(info.get("tick_hz") or 48_000_000)
    c = speed_of_sound(temperature_c)
    url = str(rec.meta.get("url", ""))
    sigma = timing_sigma_s(url) if timing_sigma is None else float(timing_sigma)
    try:
        ring = RingMessages(types, lay, rec.meta.get("sensors", []), c=c, tick_hz=tick_hz, timing_sigma=sigma,
                            frame_id=frame_id,
                            scan_period_s=DEFAULT_SCAN_PERIOD_S if scan_period_s is None else scan_period_s)
    except RosMsgError as e:
        raise ExportError(f"{recording}: {e}") from None

    start_ns = int(round(float(rec.meta.get("started_unix", 0.0)) * 1e9))
    # unwrap the 32-bit device tick of each frame's t0; device time placed on the recording's start
    t0 = np.array([f.t0 for f in rec.frames], dtype=np.int64)
    t0u = t0 + (np.concatenate([[0], np.cumsum(np.diff(t0) < -(1 << 31))]) << 32)
    tick_min = int(t0u.min())

    def to_ns(tick: int) -> int:
        return start_ns + round((tick - tick_min) * 1e9 / tick_hz)

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    heads = _HeadCounters()
    with open(out, "wb") as fh:
        sink = McapSink(fh)
        pub = Publisher(types, [sink])

        def diagnostics(stamp_ns: int) -> None:
            pub.publish([ring.diagnostics(stamp_ns, hardware_id=url or "recording", link_level=OK,
                                          link_message=f"recording of {url or 'a device'}",
                                          link_values={"url": url, "frames": heads.values["host_frames"],
                                                       "corrupt_frames": rec.corrupt, "truncated": rec.truncated},
                                          counters=heads.values, period_s=1.0)])

        pub.publish([ring.static_tf(to_ns(int(t0u[0])))])
        next_diag = to_ns(int(t0u[0]))
        for f, tick in zip(rec.frames, t0u.tolist()):
            heads.frame(f)
            pub.publish(ring.frame(f, tick, to_ns))
            t_ns = to_ns(tick)
            if t_ns >= next_diag:
                diagnostics(t_ns)
                next_diag = t_ns + 1_000_000_000
        pub.publish(ring.flush(to_ns))
        diagnostics(to_ns(int(t0u[-1])))
        variance = range_variance(c, tick_hz, sigma)
        sink.metadata(METADATA_NAME, {
            "ros_distro": ros_distro,
            "range_rule": RANGE_RULE,
            "scan_rule": SCAN_RULE,
            "scan_period_s": repr(ring.scan_period_s),
            # the variance of every Range message; Humble's Range has no variance field
            "range_variance_m2": repr(variance) if types.has_variance else f"none ({ros_distro} Range has no variance)",
            "timing_sigma_s": repr(sigma),
            "speed_of_sound_mps": repr(c),
            "recording_url": url,
        })
        sink.finish()
    return {"ros_distro": ros_distro, "frames": len(rec.frames), **ring.counts}
