"""Frames -> ROS 2 messages: the one code path of the MCAP export (``multisonar export``,
``record --mcap``) and the live Foxglove stream (``multisonar live``, docs/live.md).

:class:`RingMessages` turns decoded frames (:class:`multisonar.protocol.Frame`) into ROS 2
messages of the ``rosbags`` type store of a distribution (:class:`RosTypes`: schema text for
``ros2msg`` and CDR serialisation); :class:`Publisher` serialises each message once and hands
it to its sinks (an MCAP file, the Foxglove WebSocket server). The caller supplies the time
base of every frame: the host time of its t0 and the host nanoseconds per device tick (live:
the driver's clock, :mod:`multisonar.clock`; export: device time placed on the recording's
start).

Channels (:func:`channels`):

``/tf_static`` (tf2_msgs/msg/TFMessage)
    ``FRAME_ID`` -> ``sonar_NN`` per element (position, yaw = axis) and -> ``sonar_ring`` (the
    ring's centre, the LaserScan's origin).
``/multisonar/range/rxNN`` (sensor_msgs/msg/Range, frame ``sonar_NN``)
    :func:`range_reading` per ToF record (REP 117 as far as a windowed receiver allows).
``/multisonar/scan`` (sensor_msgs/msg/LaserScan, frame ``sonar_ring``)
    one beam per element (angle = the element's axis), the nearest first echo of that receiver
    among the readings acquired in a window of ``scan_period_s`` device time; +inf where the
    receiver's open window covered [range_min, range_max] and heard nothing, NaN where it has no
    reading (:class:`ScanWindows`).
``/multisonar/reflectors`` (sensor_msgs/msg/PointCloud2, frame ``FRAME_ID``)
    one cloud per frame with geometry records (fields x, y, z, normal, quality, cls, vs).
``/diagnostics`` (diagnostic_msgs/msg/DiagnosticArray)
    link state, device / link / firmware counters and ranging rates (:meth:`RingMessages.diagnostics`).

Stamps are acquisition times: a Range message t0 + ToF (an empty window: its end), a cloud
t0 + its pulse's latest accepted first echo, a scan its earliest reading. Frames of different
sensors arrive in the order their windows close, not in acquisition order, so Range messages
and clouds are held until no earlier acquisition can still come (a frame whose t0 is MAX_TOF +
10 ms later arrived) and released in acquisition order. Every channel's stamps are then made
strictly increasing: a stamp not later than the channel's previous one (the tick -> host
mapping moved back at a clock sync) is set 1 ns after it and counted (``clamped``).
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Protocol

import numpy as np

from . import protocol as P

RANGE_TOPIC = "/multisonar/range/rx{:02d}"
SCAN_TOPIC = "/multisonar/scan"
POINTS_TOPIC = "/multisonar/reflectors"
TF_TOPIC = "/tf_static"
DIAGNOSTICS_TOPIC = "/diagnostics"
ELEMENT_FRAME = "sonar_{:02d}"
RING_FRAME = "sonar_ring"

RANGE_TYPE = "sensor_msgs/msg/Range"
SCAN_TYPE = "sensor_msgs/msg/LaserScan"
CLOUD_TYPE = "sensor_msgs/msg/PointCloud2"
TF_TYPE = "tf2_msgs/msg/TFMessage"
DIAGNOSTICS_TYPE = "diagnostic_msgs/msg/DiagnosticArray"

#: ROS 2 distributions whose message layout is written (rosbags type store names);
#: sensor_msgs/msg/Range has ``float32 variance`` from Iron on (Humble has none)
ROS_DISTROS = {"humble": "ROS2_HUMBLE", "iron": "ROS2_IRON", "jazzy": "ROS2_JAZZY"}
DEFAULT_ROS_DISTRO = "jazzy"
#: version of the Range rule of :func:`range_reading` (written to the MCAP metadata record)
RANGE_RULE = ("multisonar-range-2: one message per first echo (c*ToF/2) and per empty open (init ping) window "
              "(+inf); none for an empty or gated tracking window; min_range/max_range: the sensor's")
#: version of the LaserScan rule of :class:`ScanWindows`
SCAN_RULE = ("multisonar-scan-1: beam i = receiver i along its axis, range from the ring centre; nearest first "
             "echo acquired in the scan window, else +inf if an open window covered [range_min, range_max], "
             "else NaN")
#: default scan window, s of device time
DEFAULT_SCAN_PERIOD_S = 0.05

#: PointField datatypes (sensor_msgs/msg/PointField)
_UINT8, _FLOAT32 = 2, 7
POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("normal", "<f4"), ("quality", "<f4"),
                        ("cls", "u1"), ("vs", "u1")])

#: diagnostic_msgs/msg/DiagnosticStatus levels
OK, WARN, ERROR, STALE = 0, 1, 2, 3
#: counters whose increase the diagnostics report (Device.counters() names), and the level it
#: raises: device (READ_COUNTERS), host link (host_*), firmware (fw_*, FW_STATS). Not fw_frames_cut:
#: a frame closed before all its windows reported is the normal outcome of a re-initialisation
#: or a re-aim (docs/protocol.md, frame flags bit 4)
WATCHED_COUNTERS: dict[str, int] = {
    "fifo_overflows": WARN, "frames_dropped": WARN, "watchdog": ERROR, "bad_commands": WARN, "tx_collisions": WARN,
    "host_lost": WARN, "host_bad_crc": WARN, "host_bad_header": WARN, "host_bad_frames": WARN,
    "host_queue_dropped": WARN, "fw_frames_lost": WARN, "fw_geo_skipped": WARN,
}


class RosMsgError(RuntimeError):
    """Messages cannot be built (missing package, unknown distribution, unusable layout)."""


def channels(receivers: Iterable[int]) -> list[tuple[str, str]]:
    """(topic, type) of every channel, Range channels for ``receivers``: what ``multisonar live``
    advertises and what an export holds (an export only the Range topics that got messages)."""
    out = [(TF_TOPIC, TF_TYPE), (SCAN_TOPIC, SCAN_TYPE), (POINTS_TOPIC, CLOUD_TYPE),
           (DIAGNOSTICS_TOPIC, DIAGNOSTICS_TYPE)]
    return out + [(RANGE_TOPIC.format(int(rx)), RANGE_TYPE) for rx in sorted(set(int(r) for r in receivers))]


# --------------------------------------------------------------------------------------------
# Range semantics (REP 117 for a windowed receiver; docs/host_driver.md, "ROS 2 export")
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
    """Echo timing jitter (sigma, s) of the data's source: the scene's ``noise.jitter_s`` for a
    simulated device (``sim://SCENE``, ``twin://SCENE``), else the acoustic model's default
    (``scene.Noise``), which is what the simulation assumes of the hardware."""
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
# type store, serialisation, sinks
# --------------------------------------------------------------------------------------------

class RosTypes:
    """The rosbags type store of one ROS 2 distribution: message classes, ``ros2msg`` schema
    text and CDR bytes."""

    def __init__(self, ros_distro: str = DEFAULT_ROS_DISTRO) -> None:
        if ros_distro not in ROS_DISTROS:
            raise RosMsgError(f"unknown ROS 2 distribution {ros_distro!r}: one of {', '.join(ROS_DISTROS)}")
        try:
            from rosbags.typesys import Stores, get_typestore
        except ImportError:
            raise RosMsgError("ROS 2 messages need the 'rosbags' package: .venv/bin/pip install -r requirements.txt") \
                from None
        self.distro = ros_distro
        self.store = get_typestore(getattr(Stores, ROS_DISTROS[ros_distro]))
        self.types = self.store.types
        #: Range has ``variance`` from Iron on
        self.has_variance = "variance" in self.types[RANGE_TYPE].__dataclass_fields__
        self._defs: dict[str, str] = {}

    def msgdef(self, typename: str) -> str:
        """The ``ros2msg`` schema text (the type and its dependencies, rosbag2's layout)."""
        if typename not in self._defs:
            self._defs[typename] = self.store.generate_msgdef(typename, ros_version=2)[0]
        return self._defs[typename]

    def serialize(self, msg: Any, typename: str) -> bytes:
        return bytes(self.store.serialize_cdr(msg, typename))

    def deserialize(self, data: bytes, typename: str) -> Any:
        return self.store.deserialize_cdr(data, typename)

    def time(self, ns: int) -> Any:
        return self.types["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))

    def header(self, ns: int, frame: str) -> Any:
        return self.types["std_msgs/msg/Header"](stamp=self.time(ns), frame_id=frame)


class Message(NamedTuple):
    topic: str
    typename: str
    msg: Any  #: a rosbags message object
    stamp_ns: int  #: header stamp (log time)


class Sink(Protocol):
    """Where serialised messages go: an MCAP file (export.McapSink), the Foxglove WebSocket
    server (live.FoxgloveSink), a test's list."""

    def add_channel(self, topic: str, typename: str, msgdef: str) -> None: ...

    def write(self, topic: str, data: bytes, log_time_ns: int) -> None: ...


class Publisher:
    """Serialises each message once (CDR of the distribution of ``types``) for all sinks; a
    channel is added to the sinks before its first message (:meth:`advertise` adds them ahead)."""

    def __init__(self, types: RosTypes, sinks: Sequence[Sink]) -> None:
        self.types = types
        self.sinks = list(sinks)
        self.topics: dict[str, str] = {}
        self.counts: dict[str, int] = {}

    def advertise(self, chans: Iterable[tuple[str, str]]) -> None:
        for topic, typename in chans:
            if topic not in self.topics:
                self.topics[topic] = typename
                msgdef = self.types.msgdef(typename)
                for s in self.sinks:
                    s.add_channel(topic, typename, msgdef)

    def publish(self, messages: Iterable[Message]) -> None:
        for m in messages:
            self.advertise([(m.topic, m.typename)])
            data = self.types.serialize(m.msg, m.typename)
            for s in self.sinks:
                s.write(m.topic, data, m.stamp_ns)
            self.counts[m.topic] = self.counts.get(m.topic, 0) + 1


# --------------------------------------------------------------------------------------------
# the ring scan
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RingGeometry:
    """The LaserScan's beams: the ring's centre (in the robot frame), its radius, the first
    element's axis and the step between elements' axes (one beam per element)."""

    centre: tuple[float, float]
    radius: float
    angle_min: float
    increment: float
    n: int

    @classmethod
    def from_layout(cls, layout: Any, tol_rad: float = math.radians(1.0)) -> "RingGeometry":
        """The layout as a ring, or RosMsgError naming what is not: elements equally spaced on
        a circle, axes radial, in counter-clockwise order."""
        pos = np.asarray(layout.positions, float)
        axes = np.asarray(layout.axes, float)
        n = len(axes)
        if n < 3:
            raise RosMsgError(f"layout {layout.name!r}: a ring scan needs >= 3 elements, it has {n}")
        centre = pos.mean(axis=0)
        d = pos - centre
        radius = np.hypot(d[:, 0], d[:, 1])
        if np.ptp(radius) > 1e-3 * max(float(radius.mean()), 1e-9):
            raise RosMsgError(f"layout {layout.name!r}: elements are not on a circle (radii "
                              f"{radius.min():.4f}..{radius.max():.4f} m); no ring scan")
        inc = 2 * math.pi / n
        want = axes[0] + inc * np.arange(n)
        bad = np.abs(np.remainder(axes - want + math.pi, 2 * math.pi) - math.pi) > tol_rad
        radial = np.abs(np.remainder(np.arctan2(d[:, 1], d[:, 0]) - axes + math.pi, 2 * math.pi) - math.pi) > tol_rad
        if bad.any() or radial.any():
            i = int(np.argmax(bad | radial))
            raise RosMsgError(f"layout {layout.name!r}: element {i}'s axis is not "
                              + ("radial" if radial[i] else f"{math.degrees(inc):.1f} deg after element {i - 1}'s")
                              + "; no ring scan")
        a0 = math.remainder(float(axes[0]), 2 * math.pi)
        cx, cy = (round(float(v), 9) for v in centre)  # 1e-18 m of rounding is noise
        return cls((cx, cy), float(radius.mean()), a0, inc, n)


@dataclass
class _Window:
    nearest: np.ndarray  #: per beam: nearest first echo, m from the centre (+inf: none)
    clear: np.ndarray  #: per beam: an open window covered [range_min, range_max] and was empty
    first_ns: int | None = None  #: earliest acquisition in the window (host ns)


@dataclass
class ScanWindows:
    """Collects readings into scan windows of ``period`` device ticks by acquisition tick and
    closes a window once a frame whose t0 is ``lag`` ticks past its end arrived (frames arrive in
    order of their last window's end, at most MAX_TOF after their t0, so nothing of the window
    can come later; a reading that still does is counted in ``late`` and dropped).

    Beam i of a window: the nearest accepted first echo of receiver i (range from the ring
    centre = radius + c*ToF/2, along the element's axis); without one, +inf where an init
    ping's open window of receiver i covered [range_min, range_max] and heard nothing (REP 117:
    no return within the limits); NaN where receiver i has no such reading (not listened to
    over the whole range, or no sensor uses it: REP 117's "no measurement").
    """

    ring: RingGeometry
    period: int  #: ticks
    lag: int  #: ticks
    range_min: float  #: m from the centre
    range_max: float
    windows: dict[int, _Window] = field(default_factory=dict)
    closed_before: int | None = None  #: windows k < this are closed
    late: int = 0

    def add(self, tick: int, rx: int, reading: RangeReading, stamp_ns: int) -> None:
        k = int(tick) // self.period
        if self.closed_before is not None and k < self.closed_before:
            self.late += 1
            return
        w = self.windows.get(k)
        if w is None:
            n = self.ring.n
            w = self.windows[k] = _Window(np.full(n, np.inf), np.zeros(n, bool))
        if reading.kind == "echo":
            w.nearest[rx] = min(w.nearest[rx], self.ring.radius + reading.range)
        elif self.ring.radius + reading.max_range < self.range_max - 1e-6:
            return  # an open window that ended early: not the whole range, no +inf
        else:
            w.clear[rx] = True
        w.first_ns = int(stamp_ns) if w.first_ns is None else min(w.first_ns, int(stamp_ns))

    def close(self, t0_tick: int | None) -> list[tuple[int, np.ndarray, int]]:
        """Windows closed by a frame with t0 ``t0_tick`` (None: all): (k, ranges, stamp_ns)."""
        if t0_tick is not None:
            limit = (int(t0_tick) - self.lag) // self.period
            self.closed_before = limit if self.closed_before is None else max(self.closed_before, limit)
        out = []
        for k in sorted(self.windows):
            if t0_tick is not None and k >= (self.closed_before or 0):
                break
            w = self.windows.pop(k)
            if w.first_ns is None:  # only open windows that ended early: nothing to say
                continue
            ranges = np.where(np.isfinite(w.nearest), w.nearest, np.where(w.clear, np.inf, np.nan))
            out.append((k, ranges.astype(np.float32), w.first_ns))
        return out

    def reset(self) -> None:
        """A new device session (its ticks restart): forget the window numbering."""
        self.windows.clear()
        self.closed_before = None


# --------------------------------------------------------------------------------------------
# frames -> messages
# --------------------------------------------------------------------------------------------

class RingMessages:
    """Builds the messages of every channel from frames (one instance per stream or recording).

    ``sensors``: recording-meta entries of the configured virtual sensors (``id``, ``max_tof``,
    optional ``blank``: :func:`sensor_limits`). ``scan_period_s`` in device time.
    """

    def __init__(self, types: RosTypes, layout: Any, sensors: Sequence[Mapping[str, Any]], *, c: float,
                 tick_hz: int, timing_sigma: float, frame_id: str = "base_link",
                 scan_period_s: float = DEFAULT_SCAN_PERIOD_S) -> None:
        if not (scan_period_s > 0 and math.isfinite(scan_period_s)):
            raise RosMsgError(f"scan period {scan_period_s!r} s: must be a positive number of seconds")
        self.types, self.layout, self.frame_id = types, layout, frame_id
        self.c, self.tick_hz, self.timing_sigma = float(c), int(tick_hz), float(timing_sigma)
        self.sensors = {int(s["id"]): dict(s) for s in sensors}
        self._limits: dict[int, RangeLimits] = {}
        self.fov = float(2 * layout.transducer.beam_half_angle)
        self.ring = RingGeometry.from_layout(layout)
        lims = [self.limits(v) for v in self.sensors] or [self.limits(-1)]
        # +inf on a beam must mean "nothing in [range_min, range_max]": the interval every
        # configured sensor's open window covers
        self.scan = ScanWindows(self.ring, max(1, int(round(scan_period_s * self.tick_hz))),
                                max(lim.max_tof for lim in lims) + self.tick_hz // 100,
                                self.ring.radius + max(lim.min_range for lim in lims),
                                self.ring.radius + min(lim.max_range for lim in lims))
        self.scan_period_s = self.scan.period / self.tick_hz
        self._last: dict[str, int] = {}
        self.clamped = 0  #: stamps moved forward to keep a channel's stamps increasing
        self.counts: dict[str, int] = {k: 0 for k in ("range", "range_echo", "range_no_return", "miss_skipped",
                                                      "gated_skipped", "scans", "clouds", "points", "tf",
                                                      "diagnostics")}
        self._prev_counters: dict[str, int] | None = None
        #: Range readings and clouds waiting until no earlier acquisition can come: (tick, order,
        #: ("range", rx, RangeReading) | ("cloud", builder))
        self._pending: list[tuple[int, int, tuple[Any, ...]]] = []
        self._order = itertools.count()
        #: (vs, t0 tick) -> the latest accepted first echo of that pulse's ToF frame (ticks), for the
        #: stamp of its geometry frame
        self._latest_echo: dict[tuple[int, int], int] = {}

    # -- helpers ------------------------------------------------------------------------------
    def limits(self, vs: int) -> RangeLimits:
        if vs not in self._limits:
            self._limits[vs] = sensor_limits(self.sensors.get(vs, {}), c=self.c, tick_hz=self.tick_hz,
                                             ring_down_s=self.layout.transducer.ring_down_s,
                                             timing_sigma_s=self.timing_sigma)
        return self._limits[vs]

    def receivers(self) -> list[int]:
        """Receivers of the configured sensors (their Range channels)."""
        return sorted({int(r) for s in self.sensors.values() for r in s.get("rx", [])})

    def channels(self) -> list[tuple[str, str]]:
        return channels(self.receivers())

    def _stamp(self, topic: str, ns: int) -> int:
        """``ns``, or 1 ns after the channel's previous stamp if it is not later."""
        last = self._last.get(topic)
        ns = int(ns)
        if last is not None and ns <= last:
            self.clamped += 1
            ns = last + 1
        self._last[topic] = ns
        return ns

    def _msg(self, topic: str, typename: str, build: Any, ns: int) -> Message:
        ns = self._stamp(topic, ns)
        return Message(topic, typename, build(ns), ns)

    def _hold(self, tick: int, item: tuple[Any, ...]) -> None:
        heapq.heappush(self._pending, (int(tick), next(self._order), item))

    def _release(self, before_tick: int | None, to_ns: Callable[[int], int]) -> list[Message]:
        """The held Range messages and clouds acquired before ``before_tick`` (None: all), in
        acquisition order, stamped ``to_ns(tick)``; their readings go into the scan windows."""
        out = []
        while self._pending and (before_tick is None or self._pending[0][0] < before_tick):
            tick, _, item = heapq.heappop(self._pending)
            ns = int(to_ns(tick))
            if item[0] == "cloud":
                out.append(self._msg(POINTS_TOPIC, CLOUD_TYPE, item[1], ns))
                continue
            _, rx, reading = item
            out.append(self._msg(RANGE_TOPIC.format(rx), RANGE_TYPE, self._range(rx, reading), ns))
            if 0 <= rx < self.ring.n:
                self.scan.add(tick, rx, reading, ns)
        return out

    # -- messages -----------------------------------------------------------------------------
    def static_tf(self, stamp_ns: int) -> Message:
        """The robot frame -> every element (position, yaw = axis) and -> the ring's centre."""
        T = self.types.types
        TransformStamped, Transform = T["geometry_msgs/msg/TransformStamped"], T["geometry_msgs/msg/Transform"]
        Vector3, Quaternion = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]

        def build(ns: int) -> Any:
            def tf(child: str, x: float, y: float, yaw: float) -> Any:
                return TransformStamped(header=self.types.header(ns, self.frame_id), child_frame_id=child,
                                        transform=Transform(translation=Vector3(x=float(x), y=float(y), z=0.0),
                                                            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                                                w=math.cos(yaw / 2))))
            tfs = [tf(ELEMENT_FRAME.format(i), x, y, a)
                   for i, ((x, y), a) in enumerate(zip(self.layout.positions, self.layout.axes))]
            tfs.append(tf(RING_FRAME, *self.ring.centre, 0.0))
            return T[TF_TYPE](transforms=tfs)

        self.counts["tf"] += self.layout.n + 1
        return self._msg(TF_TOPIC, TF_TYPE, build, stamp_ns)

    def frame(self, f: P.Frame, t0_tick: int, to_ns: Callable[[int], int]) -> list[Message]:
        """Messages whose time has come with this frame: Range messages (per first echo / empty
        open window) and clouds (of geometry records) acquired before its t0 - ``scan.lag``, of
        this frame and earlier ones, and the scans its arrival closes. ``t0_tick``: the frame's
        t0 as a 64-bit device tick; ``to_ns``: 64-bit device tick -> host ns (the time base)."""
        lim = self.limits(int(f.vs))
        latest_echo = 0
        for r in f.tof:
            flags, tof, rx = int(r["flags"]), int(r["tof"]), int(r["rx"])
            kind = window_kind(flags)
            reading = range_reading(flags, tof, lim)
            if reading is None:  # a tracking window's miss or gated echo, or a later echo
                if kind is not None:
                    self.counts[f"{kind}_skipped"] += 1
                continue
            if kind == "echo":
                latest_echo = max(latest_echo, tof)
            self._hold(int(t0_tick) + tof, ("range", rx, reading))
            self.counts["range"] += 1
            self.counts[f"range_{kind}"] += 1
        key = (int(f.vs), int(t0_tick))
        if len(f.tof):
            self._latest_echo[key] = latest_echo
            while len(self._latest_echo) > 256:  # a geometry frame follows its ToF frame closely
                self._latest_echo.pop(next(iter(self._latest_echo)))
        elif len(f.geo):  # a geometry frame (the board's): its pulse's ToF frame came before
            latest_echo = self._latest_echo.get(key, 0)
        if len(f.geo):
            self._hold(int(t0_tick) + latest_echo, ("cloud", self._cloud(f)))
        return self._release(int(t0_tick) - self.scan.lag, to_ns) + self._scans(self.scan.close(int(t0_tick)))

    def flush(self, to_ns: Callable[[int], int]) -> list[Message]:
        """The held messages and the scans still open (end of a recording, a lost device)."""
        return self._release(None, to_ns) + self._scans(self.scan.close(None))

    def reset(self, to_ns: Callable[[int], int]) -> list[Message]:
        """A new device session (ticks restart): flush what the old one left (``to_ns``: its time
        base), forget the counters' previous values. Channel stamps stay increasing."""
        out = self.flush(to_ns)
        self.scan.reset()
        self._latest_echo.clear()
        self._prev_counters = None
        return out

    def _range(self, rx: int, reading: RangeReading) -> Any:
        """The builder of a Range message (header stamp -> Range)."""
        Range = self.types.types[RANGE_TYPE]

        def build(ns: int) -> Any:
            fields = dict(header=self.types.header(ns, ELEMENT_FRAME.format(rx)), radiation_type=Range.ULTRASOUND,
                          field_of_view=self.fov, min_range=reading.min_range, max_range=reading.max_range,
                          range=reading.range)
            if self.types.has_variance:
                fields["variance"] = reading.variance
            return Range(**fields)

        return build

    def _cloud(self, f: P.Frame) -> Any:
        """The builder of a frame's cloud (header stamp -> PointCloud2)."""
        T = self.types.types
        pts = np.zeros(len(f.geo), POINT_DTYPE)
        pts["x"] = f.geo["x_mm"] / 1000.0
        pts["y"] = f.geo["y_mm"] / 1000.0
        pts["normal"] = P.from_binary_angle(f.geo["normal"])
        pts["quality"] = f.geo["quality"] / 255.0
        pts["cls"] = f.geo["cls"]
        pts["vs"] = f.vs
        pfields = [T["sensor_msgs/msg/PointField"](name=n, offset=POINT_DTYPE.fields[n][1],
                                                   datatype=_UINT8 if POINT_DTYPE[n] == np.uint8 else _FLOAT32,
                                                   count=1)
                   for n in POINT_DTYPE.names]

        def build(ns: int) -> Any:
            return T[CLOUD_TYPE](header=self.types.header(ns, self.frame_id), height=1, width=len(pts), fields=pfields,
                                 is_bigendian=False, point_step=POINT_DTYPE.itemsize,
                                 row_step=POINT_DTYPE.itemsize * len(pts),
                                 data=np.frombuffer(pts.tobytes(), np.uint8), is_dense=True)

        self.counts["clouds"] += 1
        self.counts["points"] += len(pts)
        return build

    def _scans(self, closed: list[tuple[int, np.ndarray, int]]) -> list[Message]:
        Scan = self.types.types[SCAN_TYPE]
        ring, sc = self.ring, self.scan
        out = []
        for _, ranges, first_ns in closed:
            def build(ns: int, ranges: np.ndarray = ranges) -> Any:
                return Scan(header=self.types.header(ns, RING_FRAME), angle_min=ring.angle_min,
                            angle_max=ring.angle_min + (ring.n - 1) * ring.increment, angle_increment=ring.increment,
                            time_increment=0.0, scan_time=self.scan_period_s, range_min=sc.range_min,
                            range_max=sc.range_max, ranges=ranges, intensities=np.zeros(0, np.float32))

            out.append(self._msg(SCAN_TOPIC, SCAN_TYPE, build, first_ns))
            self.counts["scans"] += 1
        return out

    def diagnostics(self, stamp_ns: int, *, hardware_id: str, link_level: int, link_message: str,
                    link_values: Mapping[str, Any], counters: Mapping[str, int] | None, period_s: float) -> Message:
        """One DiagnosticArray: ``multisonar/link`` (``link_level``/``link_message`` from the
        caller: streaming, reconnecting, ...), ``multisonar/counters`` (WARN when a watched
        counter rose since the previous call, ERROR for the watchdog, STALE without a device),
        ``multisonar/ranging`` (messages built, stamps moved, late scan readings)."""
        T = self.types.types
        Status, KeyValue = T["diagnostic_msgs/msg/DiagnosticStatus"], T["diagnostic_msgs/msg/KeyValue"]

        def kv(d: Mapping[str, Any]) -> list[Any]:
            return [KeyValue(key=str(k), value=str(v)) for k, v in d.items()]

        if counters is None:
            c_level, c_msg, c_vals = STALE, "no device: counters unknown", {}
        else:
            prev = self._prev_counters or {}
            rose = {k: int(counters[k]) - int(prev.get(k, 0)) for k in WATCHED_COUNTERS
                    if k in counters and int(counters[k]) > int(prev.get(k, 0))}
            self._prev_counters = {k: int(v) for k, v in counters.items()}
            c_level = max((WATCHED_COUNTERS[k] for k in rose), default=OK)
            c_msg = (", ".join(f"+{v} {k}" for k, v in rose.items()) + f" in the last {period_s:.1f} s") if rose \
                else "no losses, overflows or watchdog expiries"
            # every counter but the tick and the firmware's cycle maxima (docs/protocol.md)
            c_vals = {k: v for k, v in counters.items() if k != "timestamp" and not k.startswith("fw_cycles")}
        ranging = {"scan_period_s": f"{self.scan_period_s:g}", "range_min_m": f"{self.scan.range_min:.3f}",
                   "range_max_m": f"{self.scan.range_max:.3f}", "stamps_moved_forward": self.clamped,
                   "scan_late_readings": self.scan.late, **self.counts}
        statuses = [
            Status(level=int(link_level), name="multisonar/link", message=link_message, hardware_id=hardware_id,
                   values=kv(link_values)),
            Status(level=int(c_level), name="multisonar/counters", message=c_msg, hardware_id=hardware_id,
                   values=kv(c_vals)),
            Status(level=OK, name="multisonar/ranging", message=f"{self.counts['scans']} scans, "
                   f"{self.counts['range']} ranges, {self.counts['clouds']} clouds", hardware_id=hardware_id,
                   values=kv(ranging)),
        ]
        self.counts["diagnostics"] += 1

        def build(ns: int) -> Any:
            return T[DIAGNOSTICS_TYPE](header=self.types.header(ns, ""), status=statuses)

        return self._msg(DIAGNOSTICS_TOPIC, DIAGNOSTICS_TYPE, build, stamp_ns)
