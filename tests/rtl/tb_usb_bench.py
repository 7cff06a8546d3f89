"""Host-clock-error sweep of the USB device core (scripts/bench_usb_clock.py runs it).

USB_BENCH_SKEW (0..3) delays the host's D- by that many host clocks.
For each error in USB_BENCH_ERRORS (comma-separated fractions, e.g. "-0.01,0.0025") the host
clock is set to 48 MHz * (1 + error), the device is reset and enumerated, and the bulk OUT/IN
checks of tb_usb_device run. One JSON row per error goes to USB_BENCH_OUT: pass/fail with the
first error message, packets, simulated time, wall time and device clocks per wall second.
"""

from __future__ import annotations

import json
import os
import time

import cocotb
from cocotb.triggers import ClockCycles
from cocotb.utils import get_sim_time

from tbutil import start_clock
from tb_usb_device import bulk_in_checks, bulk_out_checks, check_descriptors, enumerate_device, start


@cocotb.test()
async def bench_clock_error(dut):
    errors = [float(e) for e in os.environ.get("USB_BENCH_ERRORS", "0").split(",") if e.strip()]
    skew = int(os.environ.get("USB_BENCH_SKEW", "0"))
    rows = []
    start_clock(dut.clk_i)
    for err in errors:
        t_sim0, t0 = get_sim_time("ns"), time.perf_counter()
        host = await start(dut, clock_error=err, device_clock=False)
        dut.skew_i.value = skew
        ok, msg = True, ""
        try:
            check_descriptors(await enumerate_device(host))
            await bulk_out_checks(dut, host)
            await bulk_in_checks(dut, host)
            if int(dut.collision_o.value):
                raise AssertionError("bus collision")
        except (AssertionError, TimeoutError) as exc:
            ok, msg = False, str(exc).splitlines()[0][:120]
        wall, sim_ns = time.perf_counter() - t0, get_sim_time("ns") - t_sim0
        rows.append({"error": err, "skew": skew, "ok": ok, "msg": msg, "packets": host.packets,
                     "max_delay_bits": host.max_delay_bits, "sim_us": sim_ns / 1e3, "wall_s": wall,
                     "dev_clocks_per_s": sim_ns * 0.048 / wall})
        host.clock.stop()
        dut.go_i.value = 0
        await ClockCycles(dut.clk_i, 10)
    out = os.environ.get("USB_BENCH_OUT")
    if out:
        with open(out, "w") as f:
            json.dump(rows, f, indent=1)
