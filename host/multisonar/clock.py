"""Device ticks to host time: 64-bit tick extension and the tick -> host clock mapping.

The device stamps every pulse with its trigger tick t0 (the scheduler's pulse record, 32 bits,
wrapping every 89.5 s at 48 MHz) and every ToF record with tof ticks after t0. The driver turns
these into host times at acquisition, never at arrival:

* :meth:`DeviceClock.extend` unwraps a 32-bit tick to 64 bits against the latest tick seen
  (ticks up to 2**31 before it count as earlier: frames arrive late, never 44 s late);
* :meth:`DeviceClock.sync` takes one command round trip that read the device's tick counter
  (READ_COUNTERS' ``timestamp``): the tick was read somewhere between sending the command and
  receiving its reply, so host time = the round trip's midpoint, uncertain by half the round
  trip. The mapping host_ns = offset + rate * tick keeps the best (shortest round trip) sync of
  the recent ones for the offset and, once two syncs are far enough apart, the rate between
  them (a simulated device runs far slower than real time; a board's crystal drifts by ppm).
"""

from __future__ import annotations

from dataclasses import dataclass

from .constants import TICK_HZ

WRAP = 1 << 32


@dataclass(frozen=True)
class Sync:
    tick: int  #: device tick (64-bit) read by the command
    host_ns: int  #: midpoint of the round trip
    rtt_ns: int  #: round trip


class DeviceClock:
    """Unwraps device ticks and maps them to host nanoseconds (time.time_ns's epoch)."""

    #: syncs closer than this (ticks) to the reference give no rate (too short a baseline)
    MIN_BASELINE = TICK_HZ // 10

    def __init__(self, tick_hz: int = TICK_HZ) -> None:
        self.tick_hz = int(tick_hz)
        self._last: int | None = None  # latest 64-bit tick seen
        self._ref: Sync | None = None  # the first sync: the rate's baseline
        self._best: Sync | None = None  # the offset's sync (shortest round trip, recent)
        self.rate_ns = 1e9 / self.tick_hz  # host ns per device tick
        self.syncs = 0

    def extend(self, tick32: int) -> int:
        """The 64-bit tick of a 32-bit device tick near the latest one seen."""
        t = int(tick32) & (WRAP - 1)
        if self._last is None:
            self._last = t
            return t
        d = (t - self._last) & (WRAP - 1)
        if d < WRAP // 2:
            self._last += d
            return self._last
        return self._last - ((self._last - t) & (WRAP - 1))

    def sync(self, tick32: int, sent_ns: int, received_ns: int) -> Sync:
        """One round trip that read the device tick ``tick32`` between ``sent_ns`` and
        ``received_ns`` (host time.time_ns)."""
        s = Sync(self.extend(tick32), (sent_ns + received_ns) // 2, max(received_ns - sent_ns, 0))
        self.syncs += 1
        if self._ref is None:
            self._ref = self._best = s
            return s
        if s.tick - self._ref.tick >= self.MIN_BASELINE and s.tick > self._ref.tick:
            self.rate_ns = (s.host_ns - self._ref.host_ns) / (s.tick - self._ref.tick)
        best = self._best
        assert best is not None
        # a better round trip, or the old best has aged (drift): take the new one
        if s.rtt_ns <= best.rtt_ns or s.tick - best.tick > 10 * self.tick_hz:
            self._best = s
        return s

    @property
    def synced(self) -> bool:
        return self._best is not None

    def to_host_ns(self, tick64: int) -> int | None:
        """Host time of a 64-bit device tick, or None before the first sync."""
        b = self._best
        if b is None:
            return None
        return int(b.host_ns + round((int(tick64) - b.tick) * self.rate_ns))

    def uncertainty_ns(self) -> int | None:
        """Half the best sync's round trip: how far off the mapping's offset may be."""
        return None if self._best is None else self._best.rtt_ns // 2
