"""multisonar.clock: 64-bit tick extension across the 32-bit wrap and the tick -> host time
mapping the driver keeps from command round trips."""

from __future__ import annotations

import random

from multisonar.clock import WRAP, DeviceClock


def test_extend_across_wraps_and_late_frames():
    c = DeviceClock()
    t = WRAP - 1000
    assert c.extend(t) == t
    seen = []
    for step in range(1, 40):
        t += 400_000_000  # ~8 s of ticks per step: a wrap every ~11 steps
        seen.append(c.extend(t % WRAP))
        # a frame stamped 5 s earlier arrives late: it stays earlier, no wrap is added
        assert c.extend((t - 240_000_000) % WRAP) == t - 240_000_000
    assert seen == [WRAP - 1000 + 400_000_000 * k for k in range(1, 40)]
    assert seen[-1] > 3 * WRAP


def test_mapping_from_noisy_round_trips_recovers_offset_and_rate():
    rng = random.Random(1)
    tick_hz = 48_000_000
    for rate in (1e9 / tick_hz, 100 * 1e9 / tick_hz):  # a board, and a twin 100x slower than real time
        c = DeviceClock(tick_hz)
        origin_ns = 1_700_000_000 * 10**9
        worst = 0
        for k in range(50):
            tick = 5_000_000 + k * 4_800_000  # a sync every 0.1 s of device time
            true_ns = origin_ns + int(tick * rate)
            before, after = rng.randint(50_000, 2_000_000), rng.randint(50_000, 2_000_000)
            c.sync(tick % WRAP, true_ns - before, true_ns + after)  # asymmetric round trips
            probe = tick + 100_000
            err = abs(c.to_host_ns(c.extend(probe % WRAP)) - (origin_ns + int(probe * rate)))
            if k > 5:
                worst = max(worst, err)
        # the offset is within half the shortest round trip plus the rate error over the span
        assert worst < 2_000_000, (rate, worst)
        assert abs(c.rate_ns / rate - 1) < 0.01, (c.rate_ns, rate)


def test_unsynced_clock_maps_nothing():
    c = DeviceClock()
    assert c.to_host_ns(c.extend(123)) is None and not c.synced
