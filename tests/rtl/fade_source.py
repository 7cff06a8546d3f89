"""An echo source with one fade: a missed window for the miss hold's tests (the golden model's,
tests/test_miss_hold.py, and the RTL scheduler's, tb_ms_scheduler.miss_hold_fade)."""

from __future__ import annotations

from multisonar.fastfiring import SyntheticEchoSource


class FadeSource(SyntheticEchoSource):
    """Static ranges whose echoes on receiver ``rx`` are lost for the first pulse fired at or
    after ``fade_tick`` (settable once a bench knows its start tick): one missed window, then
    samples."""

    def __init__(self, ranges, rx: int, fade_tick: int = 1 << 62, **kw):
        super().__init__(ranges, **kw)
        self.rx, self.fade_tick, self.faded = rx, fade_tick, False

    def fire(self, t0_tick, elements, delay_ticks):
        rows = super().fire(t0_tick, elements, delay_ticks)
        if self.faded or t0_tick < self.fade_tick:
            return rows
        self.faded = True
        return [r for r in rows if r[0] != self.rx]
