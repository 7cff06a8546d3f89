"""Comparator pulses on echo_i for closed-loop testbenches.

A pulse that starts at tick n is first sampled high at the clock edge ending cycle n
(docs/sonar_core.md), so each edge is driven a quarter clock into its cycle. Overlapping
pulses on one receiver OR together, as the analog comparator would. Python wakes once per
pulse edge, never per clock.
"""

from __future__ import annotations

from collections.abc import Callable

import cocotb
from cocotb.triggers import Timer
from cocotb.utils import get_sim_time

from tbutil import CLK_PERIOD_PS

QUARTER = CLK_PERIOD_PS // 4


class EchoDriver:
    def __init__(self, echo, n_ch: int, cycle_start_ps: Callable[[int], int]) -> None:
        """echo: the echo_i handle; cycle_start_ps(tick): sim time (ps) of that cycle's first edge."""
        self.echo, self.cycle_start_ps = echo, cycle_start_ps
        self.level, self.count = 0, [0] * n_ch
        self.tasks: list = []

    def drive(self, rx: int, start: int, width: int) -> None:
        if width > 0:
            self.tasks.append(cocotb.start_soon(self._pulse(rx, start, width)))

    def stop(self) -> None:
        for t in self.tasks:
            if not t.done():
                t.cancel()
        self.level, self.count = 0, [0] * len(self.count)
        self.echo.value = 0

    async def _pulse(self, rx: int, start: int, width: int) -> None:
        dt = self.cycle_start_ps(start) + QUARTER - int(get_sim_time("ps"))
        assert dt > 0, f"echo on rx {rx} at tick {start} is already in the past"
        await Timer(dt, unit="ps")
        self._set(rx, +1)
        await Timer(width * CLK_PERIOD_PS, unit="ps")
        self._set(rx, -1)

    def _set(self, rx: int, d: int) -> None:
        self.count[rx] += d
        bit = 1 << rx
        self.level = (self.level | bit) if self.count[rx] > 0 else (self.level & ~bit)
        self.echo.value = self.level
