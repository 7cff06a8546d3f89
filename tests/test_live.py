"""`multisonar live` (issue #31): a Foxglove WebSocket server of ROS 2 messages.

A WebSocket client (the ``websockets`` package, Foxglove's ``foxglove.sdk.v1`` subprotocol)
connects to ``multisonar live --url sim://corridor``, checks the advertised channels (topic,
schema name, ``ros2msg`` schema text of the rosbags type store, ``cdr``), subscribes to the ring
scan and decodes it with rosbags' CDR deserialiser: 24 beams 15 degrees apart, every value within
[range_min, range_max] or a REP 117 special (+inf, NaN), increasing stamps. The session survives
a device that goes away (an injected fake device scheme: the driver never imports it) and says
so in its diagnostics. The scan rule and the ring geometry on their own; the shipped Foxglove
layout is the generator's.
"""

from __future__ import annotations

import asyncio
import json
import math
import signal
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from multisonar.layout import load_layout
from multisonar.rosmsgs import (DIAGNOSTICS_TOPIC, ERROR, OK, RANGE_TOPIC, SCAN_TOPIC, STALE, RangeReading,
                                RingGeometry, RosMsgError, RosTypes, ScanWindows, channels)

pytest.importorskip("rosbags")
websockets = pytest.importorskip("websockets")
pytest.importorskip("foxglove")

ROOT = Path(__file__).resolve().parents[1]
SUBPROTOCOL = "foxglove.sdk.v1"
DEMO_RX = (23, 0, 1, 2, 3, 4, 5, 6, 7, 17, 18, 19, 20, 21, 22)  # receivers of the demo sensors
TIMEOUT = 20.0  # s: the longest any single wait of these tests may take


class MemorySink:
    """A rosmsgs.Sink keeping (topic, bytes, log time); decodes with rosbags."""

    def __init__(self) -> None:
        self.types = RosTypes("jazzy")
        self.channels: dict[str, str] = {}
        self.messages: list[tuple[str, bytes, int]] = []
        self.lock = threading.Lock()

    def add_channel(self, topic: str, typename: str, msgdef: str) -> None:
        assert msgdef == self.types.msgdef(typename)
        self.channels[topic] = typename

    def write(self, topic: str, data: bytes, log_time_ns: int) -> None:
        with self.lock:
            self.messages.append((topic, data, log_time_ns))

    def decoded(self, topic: str) -> list:
        with self.lock:
            mine = [(d, t) for tp, d, t in self.messages if tp == topic]
        return [(self.types.deserialize(d, self.channels[topic]), t) for d, t in mine]


def _stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _check_scan(scan, lay) -> None:
    """A LaserScan of the ring: one beam per element along its axis; REP 117 values."""
    assert scan.header.frame_id == "sonar_ring"
    assert len(scan.ranges) == lay.n == 24
    assert scan.angle_increment == pytest.approx(math.radians(15.0), rel=1e-6)
    assert scan.angle_min == pytest.approx(math.remainder(lay.axes[0], 2 * math.pi), abs=1e-6)
    assert scan.angle_max == pytest.approx(scan.angle_min + 23 * scan.angle_increment, rel=1e-6)
    # range_min: the ring's radius + the blanking's range; range_max: + 4.3 m (the sensors' MAX_TOF)
    assert 0.35 + 0.2 < scan.range_min < 0.35 + 0.3 and 0.35 + 4.2 < scan.range_max < 0.35 + 4.4
    for r in scan.ranges:
        assert math.isnan(r) or r == math.inf or scan.range_min <= r <= scan.range_max, r


# --------------------------------------------------------------------------------------------
# the command, over WebSocket
# --------------------------------------------------------------------------------------------

def _start_live(*args: str, sigint_ignored: bool = False) -> tuple[subprocess.Popen, int]:
    """``sigint_ignored``: started as a non-interactive shell starts a background job, with SIGINT
    ignored (inherited through exec)."""
    proc = subprocess.Popen([sys.executable, "-m", "multisonar", "live", "--port", "0", "--seconds", "60", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            preexec_fn=(lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if sigint_ignored
                            else None)
    line: list[str] = []
    reader = threading.Thread(target=lambda: line.append(proc.stdout.readline()), daemon=True)
    reader.start()
    reader.join(TIMEOUT)
    if not line or "ws://" not in line[0]:
        proc.kill()
        raise AssertionError(f"multisonar live did not start: {line} {proc.stderr.read()}")
    return proc, int(line[0].split("ws://", 1)[1].split()[0].rsplit(":", 1)[1])


def _stop_live(proc: subprocess.Popen, sig: int = signal.SIGINT) -> str:
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError(f"multisonar live did not stop on {signal.Signals(sig).name}") from None
    assert proc.returncode == 0, err
    return err


async def _session(port: int, want_topics: set[str], subscribe: list[str], n_messages: dict[str, int]):
    """Connect, collect the advertised channels until ``want_topics`` are there, subscribe to
    ``subscribe`` and collect ``n_messages`` of each: (server info, channels by topic,
    {topic: [payload bytes]})."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=TIMEOUT,
                                  max_size=None) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        info, chans = None, {}
        while info is None or not want_topics <= set(chans):
            m = json.loads(await asyncio.wait_for(ws.recv(), TIMEOUT))
            if m["op"] == "serverInfo":
                info = m
            elif m["op"] == "advertise":
                chans.update({c["topic"]: c for c in m["channels"]})
        sub_ids = {k + 1: chans[t]["id"] for k, t in enumerate(subscribe)}
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": s, "channelId": c}
                                                                        for s, c in sub_ids.items()]}))
        topic_of = {s: chans_topic for s, chans_topic in zip(sub_ids, subscribe)}
        got: dict[str, list[bytes]] = {t: [] for t in subscribe}
        deadline = time.monotonic() + TIMEOUT
        while any(len(got[t]) < n for t, n in n_messages.items()):
            left = deadline - time.monotonic()
            assert left > 0, f"messages after {TIMEOUT} s: { {t: len(v) for t, v in got.items()} }"
            m = await asyncio.wait_for(ws.recv(), left)
            if isinstance(m, bytes) and m[0] == 1:  # MessageData: opcode, subscription id, log time, payload
                sub, _log_time = struct.unpack_from("<IQ", m, 1)
                got[topic_of[sub]].append(m[13:])
        return info, chans, got


def test_live_sim_corridor_over_websocket():
    """`multisonar live --url sim://corridor`: every channel advertised with its ROS 2 type
    (ros2msg schema, CDR); the ring scan decodes with rosbags: 24 beams, REP 117 values,
    increasing stamps, the rear beams (no demo sensor listens there) NaN; the diagnostics say
    the link streams."""
    types = RosTypes("jazzy")
    lay = load_layout()
    expected = dict(channels(DEMO_RX))
    proc, port = _start_live("--url", "sim://corridor")
    try:
        info, chans, got = asyncio.run(asyncio.wait_for(
            _session(port, set(expected), [SCAN_TOPIC, DIAGNOSTICS_TOPIC], {SCAN_TOPIC: 4, DIAGNOSTICS_TOPIC: 2}),
            3 * TIMEOUT))
    finally:
        err = _stop_live(proc)
    assert info["name"] == "multisonar"
    # these, and Range channels only besides (the firmware may re-aim a sensor to other receivers)
    assert set(expected) <= set(chans) and all(t.startswith("/multisonar/range/") for t in set(chans) - set(expected))
    for topic, typename in expected.items():
        c = chans[topic]
        assert (c["schemaName"], c["schemaEncoding"], c["encoding"]) == (typename, "ros2msg", "cdr")
        assert c["schema"] == types.msgdef(typename)
    scans = [types.deserialize(b, "sensor_msgs/msg/LaserScan") for b in got[SCAN_TOPIC]]
    stamps = [_stamp_ns(s) for s in scans]
    assert all(b > a for a, b in zip(stamps, stamps[1:])), stamps
    assert abs(stamps[-1] - time.time_ns()) < 120e9  # host time (acquisition mapped), not device ticks
    seen = np.zeros(24, bool)
    for s in scans:
        _check_scan(s, lay)
        r = np.asarray(s.ranges)
        assert np.isnan(r[9:16]).all()  # rear directions: no sensor
        seen |= np.isfinite(r)
    assert seen.sum() >= 6  # the corridor's walls and objects in many directions
    diags = [types.deserialize(b, "diagnostic_msgs/msg/DiagnosticArray") for b in got[DIAGNOSTICS_TOPIC]]
    link = [st for d in diags for st in d.status if st.name == "multisonar/link"]
    assert link and link[-1].level in (OK, 1) and "sim://corridor" in link[-1].message
    assert "streaming from sim://corridor" in err


def test_live_refuses_a_taken_port():
    proc, port = _start_live("--url", "sim://corridor")
    try:
        out = subprocess.run([sys.executable, "-m", "multisonar", "live", "--url", "sim://corridor", "--port",
                              str(port), "--seconds", "1"], capture_output=True, text=True, timeout=TIMEOUT, cwd=ROOT)
    finally:
        _stop_live(proc)
    assert out.returncode == 1 and f"cannot serve on 127.0.0.1:{port}" in out.stderr


@pytest.mark.parametrize("sig,sigint_ignored", [(signal.SIGINT, True), (signal.SIGTERM, False)],
                         ids=["sigint-started-in-background", "sigterm"])
def test_live_stops_cleanly_on_sigint_and_sigterm(sig, sigint_ignored):
    """Ctrl-C and a service manager's SIGTERM end the session with its counts and exit 0, also
    when the process was started with SIGINT ignored (a script's background job)."""
    proc, _ = _start_live("--url", "sim://corridor", sigint_ignored=sigint_ignored)
    time.sleep(1.0)  # streaming
    err = _stop_live(proc, sig)
    assert "multisonar live: frames" in err, err


# --------------------------------------------------------------------------------------------
# a device that goes away
# --------------------------------------------------------------------------------------------

@pytest.fixture()
def flaky_scheme():
    """``flaky://SCENE``: the simulated device, unplugged after 40 bulk IN transfers of the
    first session; the first reopen fails (nothing at the URL), the second works. Registered
    by the test (the pyftdi way): the driver and the live session never import it."""
    from multisonar import urls
    from multisonar.errors import DeviceNotFound
    from multisonar.simdevice import SimDevice
    from multisonar.usb.function import Disconnected

    opens = {"n": 0}

    class Unplugged(SimDevice):
        reads = 0

        def bulk_in(self, ep, length, timeout_s):
            self.reads += 1
            if self.reads > 40:
                raise Disconnected("unplugged by the test")
            return super().bulk_in(ep, length, timeout_s)

    def flaky(url: urls.DeviceUrl) -> urls.Model:
        """flaky://SCENE: a simulated device that is unplugged once (tests)"""
        opens["n"] += 1
        if opens["n"] == 2:
            raise DeviceNotFound(f"{url.url}: nothing there (test)")
        sim = (Unplugged if opens["n"] == 1 else SimDevice)(url.target or "corridor")
        return urls.Model(sim, close=sim.close)

    urls.register_scheme("flaky", model=flaky, help=flaky.__doc__)
    try:
        yield opens
    finally:
        urls.unregister_scheme("flaky")


def test_live_survives_a_lost_device(flaky_scheme):
    """The device goes away mid-stream: the session reports it (link ERROR with the error,
    counters STALE), retries (one failed open, counted), reconnects and streams again (link OK,
    reconnects 1); every channel's stamps keep increasing across the reconnect."""
    from multisonar.device_cli import load_sensors
    from multisonar.live import LiveSession

    sink = MemorySink()
    logs: list[str] = []
    session = LiveSession("flaky://corridor", load_sensors("demo"), [sink], retry_s=0.1, diag_period_s=0.2,
                          log=logs.append)
    stop = threading.Event()
    runner = threading.Thread(target=session.run, args=(stop,), daemon=True)
    runner.start()
    deadline = time.monotonic() + 3 * TIMEOUT

    def scans_after_reconnect() -> int:
        return sum(1 for m, _ in sink.decoded(SCAN_TOPIC) if _stamp_ns(m) > reconnected_at)

    reconnected_at = None
    try:
        while time.monotonic() < deadline:
            if reconnected_at is None and session.reconnects:
                reconnected_at = time.time_ns()
            if reconnected_at is not None and scans_after_reconnect() >= 2 and session.state == "streaming":
                break
            time.sleep(0.05)
    finally:
        stop.set()
        runner.join(TIMEOUT)
    assert not runner.is_alive(), "the live session did not stop"
    assert reconnected_at is not None, f"no reconnect: {logs}"
    assert flaky_scheme["n"] == 3 and session.reconnects == 1 and session.failed_attempts == 1
    assert any("device lost" in s and "unplugged by the test" in s for s in logs)
    arrays = [m for m, _ in sink.decoded(DIAGNOSTICS_TOPIC)]
    link = [next(s for s in a.status if s.name == "multisonar/link") for a in arrays]
    counters = [next(s for s in a.status if s.name == "multisonar/counters") for a in arrays]
    values = [{kv.key: kv.value for kv in s.values} for s in link]
    lost = [k for k, s in enumerate(link) if s.level == ERROR]
    assert lost, [s.message for s in link]
    assert any("unplugged by the test" in link[k].message or "nothing there" in link[k].message for k in lost)
    assert all(values[k]["state"] == "lost" and counters[k].level == STALE for k in lost)
    back = [k for k in range(lost[-1] + 1, len(link)) if values[k]["state"] == "streaming"]
    assert back and values[back[-1]]["reconnects"] == "1" and values[back[-1]]["failed_attempts"] == "1"
    assert "reconnected 1 times" in link[back[-1]].message
    # before the loss it streamed too
    assert any(values[k]["state"] == "streaming" for k in range(lost[0]))
    # the counters are read again every period: the host's frame count grows
    frames_seen = [int({kv.key: kv.value for kv in counters[k].values}["host_frames"]) for k in back]
    assert len(frames_seen) >= 2 and frames_seen[-1] > frames_seen[0] and counters[back[-1]].level == OK
    # every channel's stamps increase across the reconnect; scans on both sides of it
    for topic in sink.channels:
        msgs = sink.decoded(topic)
        stamps = [t for _, t in msgs]  # log time = header stamp (TFMessage: its transforms' stamp)
        assert all(b > a for a, b in zip(stamps, stamps[1:])), topic
        assert all(_stamp_ns(m if hasattr(m, "header") else m.transforms[0]) == t for m, t in msgs)
    scans = [m for m, _ in sink.decoded(SCAN_TOPIC)]
    assert sum(_stamp_ns(m) < reconnected_at for m in scans) >= 1 and scans_after_reconnect() >= 2
    for s in scans:
        _check_scan(s, load_layout())


def test_live_rejects_bad_sensors_before_serving(tmp_path, capsys):
    from multisonar.cli import main

    bad = tmp_path / "bad.yaml"
    bad.write_text("- {name: x, tx: [6], rx: [5, 6, 7], order: 99}\n")
    assert main(["live", "--url", "sim://corridor", "--sensors", str(bad), "--port", "0", "--seconds", "1"]) == 1
    assert "order" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# the scan rule and the ring
# --------------------------------------------------------------------------------------------

def test_ring_geometry_of_the_layout_and_of_a_non_ring(tmp_path):
    ring = RingGeometry.from_layout(load_layout())
    assert ring.n == 24 and ring.radius == pytest.approx(0.35) and ring.centre == pytest.approx((0.0, 0.0))
    assert ring.angle_min == pytest.approx(0.0) and ring.increment == pytest.approx(math.radians(15))
    from multisonar.layout import LAYOUT_DIR

    text = (LAYOUT_DIR / "ring24.yaml").read_text().replace("axis_deg:  90.0", "axis_deg:  80.0")
    (tmp_path / "bent.yaml").write_text(text)
    with pytest.raises(RosMsgError, match="element 6's axis is not radial"):
        RingGeometry.from_layout(load_layout(tmp_path / "bent.yaml"))


def test_scan_windows_rule():
    """Per window: beam i = the nearest first echo of receiver i (radius + range), else +inf if an
    open window covered [range_min, range_max], else NaN; an open window that ended early gives
    no +inf; a window closes once a frame t0 is `lag` past its end; later readings are late."""
    ring = RingGeometry((0.0, 0.0), 0.35, 0.0, math.radians(15), 24)
    w = ScanWindows(ring, period=1000, lag=500, range_min=0.6, range_max=4.65)

    def echo(r):
        return RangeReading(r, 0.25, 4.3, 1e-8, "echo")

    empty_full, empty_short = RangeReading(math.inf, 0.25, 4.3, 1e-8, "no_return"), \
        RangeReading(math.inf, 0.25, 2.0, 1e-8, "no_return")
    w.add(100, 3, echo(2.0), 10)
    w.add(200, 3, echo(1.5), 20)  # nearer: wins
    w.add(300, 3, empty_full, 30)  # an echo beats a clear window
    w.add(400, 4, empty_full, 5)  # clear over the whole range: +inf; the earliest stamp
    w.add(500, 5, empty_short, 50)  # ended at 2 m: nothing to say
    w.add(1100, 3, echo(3.0), 60)  # next window
    assert w.close(1400) == []  # window 0 ends at 1000; closes at t0 >= 1500
    ((k, ranges, stamp),) = w.close(1500)
    assert k == 0 and stamp == 5
    assert ranges[3] == pytest.approx(0.35 + 1.5) and ranges[4] == math.inf
    assert np.isnan(np.delete(ranges, [3, 4])).all()
    w.add(900, 6, echo(1.0), 70)  # window 0 is closed: late
    assert w.late == 1
    ((k, ranges, stamp),) = w.close(None)
    assert k == 1 and ranges[3] == pytest.approx(3.35) and stamp == 60


# --------------------------------------------------------------------------------------------
# the layout file
# --------------------------------------------------------------------------------------------

def test_shipped_foxglove_layout_is_the_generated_one():
    """docs/foxglove/multisonar_layout.json = multisonar.live.foxglove_layout() (regenerate:
    python -c 'from multisonar.live import foxglove_layout; print(foxglove_layout(), end="")'
    > docs/foxglove/multisonar_layout.json); it shows topics the server publishes."""
    from multisonar.live import LAYOUT_FILE, foxglove_layout

    assert (ROOT / LAYOUT_FILE).read_text() == foxglove_layout()
    doc = json.loads(foxglove_layout())
    text = json.dumps(doc)
    topics = {t for t, _ in channels(range(24))}
    for t in (SCAN_TOPIC, "/multisonar/reflectors", DIAGNOSTICS_TOPIC, RANGE_TOPIC.format(0)):
        assert t in topics and t in text
    assert doc["content"]["type"] == "split"


def test_range_topics_use_the_window_rule_of_the_export():
    """live and export share rosmsgs.range_reading: the module export re-exports it."""
    from multisonar import export, rosmsgs

    assert export.range_reading is rosmsgs.range_reading and export.window_kind is rosmsgs.window_kind
