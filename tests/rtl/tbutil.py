"""Small helpers shared by the cocotb testbenches."""

from __future__ import annotations

from cocotb.clock import Clock
from cocotb.triggers import ClockCycles

# 48 MHz is 20.8333 ns; cocotb needs an even number of simulator steps (1 ps), so the
# testbench clock is 20.834 ns. Every RTL test counts in ticks, never in nanoseconds.
CLK_PERIOD_PS = 20834


def start_clock(clk) -> None:
    """Start the system clock in C (impl='gpi'): Python is not woken per edge."""
    Clock(clk, CLK_PERIOD_PS, unit="ps", impl="gpi").start()


async def reset(clk, rst, cycles: int = 4) -> None:
    rst.value = 1
    await ClockCycles(clk, cycles)
    rst.value = 0
    await ClockCycles(clk, 2)


async def start_and_reset(clk, rst, *inputs) -> None:
    """Drive ``inputs`` low, start the clock and reset: the opening of most unit benches."""
    for sig in inputs:
        sig.value = 0
    start_clock(clk)
    await reset(clk, rst)
