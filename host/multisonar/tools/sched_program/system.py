"""The world around the engine for a whole-program run: what the sonar core's hardware gives
the scheduler. Today the receive path; the work queue, the close detector and the WIN read
port join it with the main loop.

:class:`EchoPath`: the echoes of fired pulses and the acoustic noise on each receiver's
comparator line, filtered as the receive conditioner does (``_Line.rises``, the golden
model's own filter), giving the edges the scheduler sees: receiver r rises at tick n + L
(L = 1 + max(glitch_min, 1)) for a run starting at n.
"""

from __future__ import annotations

import heapq
from typing import Any

from ...fastfiring import _Line, _rows


class EchoPath:
    """Comparator lines of ``n_el`` receivers fed by ``source`` (an EchoSource)."""

    def __init__(self, n_el: int, source: Any, glitch_min: int) -> None:
        self.source = source
        self.g = max(int(glitch_min), 1)
        self.latency = 1 + self.g
        self.lines = [_Line() for _ in range(n_el)]
        self._pending: list[tuple[int, int, int]] = []   # (detection tick, receiver, run start)

    def _add(self, rx: int, start: int, width: int) -> None:
        if width <= 0 or not 0 <= rx < len(self.lines):
            return
        self.lines[rx].insert(start, start + width)
        heapq.heappush(self._pending, (start + self.latency, rx, start))

    def noise(self, t_start: int, t_end: int) -> None:
        """The source's noise pulses of [t_start, t_end) on the lines."""
        noise = getattr(self.source, "noise", None)
        if callable(noise):
            for rx, st, w in _rows(noise(t_start, t_end)):
                self._add(int(rx), max(int(st), t_start), int(w))

    def fire(self, t0: int, elements: Any, delays: Any) -> None:
        """A pulse fired at t0 (its tx elements, their phasing delays): its echoes on the lines."""
        for rx, st, w in _rows(self.source.fire(t0, elements, delays)):
            self._add(int(rx), max(int(st), t0), int(w))

    def rises(self, tick: int) -> list[tuple[int, int]]:
        """The (receiver, run start n) that rise at ``tick``, receivers ascending; every earlier
        tick must have been asked for first."""
        out = []
        while self._pending and self._pending[0][0] <= tick:
            t, rx, n = heapq.heappop(self._pending)
            if t < tick:
                raise ValueError(f"EchoPath: tick {t} was skipped (asked for {tick})")
            if self.lines[rx].rises(n, self.g):
                out.append((rx, n))
        return out

    def next_tick(self) -> int | None:
        """The next tick with a pending run, or None."""
        return self._pending[0][0] if self._pending else None
