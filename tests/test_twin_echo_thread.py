"""The twin's echo thread (TwinSim ``echo_thread``; docs/twin.md, "The echo thread"): the echo
source's calls run on a worker thread while the device runs on, their rows handed to the
harness at a fence before the clock reaches their earliest start. It must change nothing the
device does, and a source that breaks its promise or fails is named, not waited for.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from multisonar.twin.check import booted_corridor, fixed_session
from multisonar.twin.sim import TwinError, state_differences

pytestmark = pytest.mark.sim


class _SlowEcho:
    """The scene's echoes, each pulse's 10 ms late: the harness must wait at its fences."""

    rows_from_t0 = True

    def __init__(self, inner: Any) -> None:
        self.inner = inner

    def fire(self, *args: Any) -> Any:
        time.sleep(0.01)
        return self.inner.fire(*args)

    def noise(self, a: int, b: int) -> Any:
        return self.inner.noise(a, b)


def _session(seed: int, thread: bool, seconds: float = 0.08) -> tuple[Any, dict[str, Any]]:
    sim = booted_corridor(seed)
    try:
        sim.echo_thread = thread
        if thread:
            sim.echo_source = _SlowEcho(sim.echo_source)
        boot = dict(sim.echo_stats)
        run = fixed_session(sim, seconds, skip=True)
        rows = sim.echo_rows  # (waits for the thread)
        return run, dict({k: v - boot[k] for k, v in sim.echo_stats.items()}, rows=rows)
    finally:
        sim.close()


def test_a_session_is_the_same_with_and_without_the_echo_thread():
    (a, a_stats), (b, b_stats) = _session(29, False), _session(29, True)
    assert a_stats["threaded"] == 0 and a_stats["calls"] > 50, a_stats
    # every call after the boot's went to the thread, and the harness waited at fences for them
    assert b_stats["threaded"] == b_stats["calls"] and b_stats["fences"] > 20, b_stats
    assert a_stats["rows"] == b_stats["rows"] > 500
    assert a.tick == b.tick and a.bulk_in == b.bulk_in and a.mailbox == b.mailbox
    assert [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in a.fires] == \
           [(t0, vs, el.tolist(), d.tolist()) for t0, vs, el, d in b.fires]
    assert state_differences(a.state, b.state, a.boot_state, b.boot_state) == []


class _EarlyEcho:
    """A source that promises rows from t0 on and gives one before it."""

    rows_from_t0 = True

    def __init__(self, inner: Any) -> None:
        self.inner = inner

    def fire(self, t0: int, elements: np.ndarray, delays: np.ndarray) -> np.ndarray:
        return np.array([[int(elements[0]), t0 - 5, 100]], dtype=np.int64)

    def noise(self, a: int, b: int) -> Any:
        return self.inner.noise(a, b)


class _FailingEcho(_EarlyEcho):
    def fire(self, t0: int, elements: np.ndarray, delays: np.ndarray) -> np.ndarray:
        raise ValueError("the scene has no such reflector")


@pytest.mark.parametrize("source, message", [(_EarlyEcho, "before tick"),
                                             (_FailingEcho, "no such reflector")])
def test_a_broken_echo_source_is_named(source, message):
    sim = booted_corridor(3)
    try:
        sim.echo_source = source(sim.echo_source)
        with pytest.raises(TwinError, match=message):
            fixed_session(sim, 0.05, skip=True)
    finally:
        sim.close()


class _NoSuchReflector:
    rows_from_t0 = True

    def fire(self, t0: int, elements: np.ndarray, delays: np.ndarray) -> np.ndarray:
        raise ValueError("the scene has no such reflector")


def test_a_failing_echo_source_over_usbip_disconnects_with_its_error():
    """The twin's error reaches the driver at once as a disconnected device (the server answers
    -ESHUTDOWN and keeps the error), not as a URB that is never answered."""
    from multisonar.demo import demo_sensors
    from multisonar.errors import DeviceDisconnected
    from multisonar.twin import open_twin

    with open_twin("corridor", echo_source=_NoSuchReflector()) as tw:
        tw.device.configure(demo_sensors())
        t = time.monotonic()
        with pytest.raises(DeviceDisconnected):
            tw.start()  # (its reply may come after the first pulse)
            for _ in tw.device.stream(duration_s=60.0):
                pass
        assert time.monotonic() - t < 30
        assert isinstance(tw.server.failure, TwinError) and "no such reflector" in str(tw.server.failure)
