"""Benchmark testbench (run by scripts/bench_rtl_sample_rate.py, not by make test): per-sensor
sample rate of the RTL scheduler on a static reflector, next to the golden model's.

Writes build/bench/rtl_sample_rate.json.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cocotb

from multisonar.constants import TICK_HZ
from multisonar.fastfiring import FastFiringModel, SyntheticEchoSource
from multisonar.schedule import Schedule, VirtualSensor
from tb_ms_scheduler import LAYOUT, LEAD, MS, Bench

CASES = [(float(d), int(n)) for d, n in (c.split(":") for c in os.environ.get("RATE_CASES", "2:1,2:3,4:1,4:4").split(","))]
OUT = Path(os.environ.get("RATE_OUT", "build/bench/rtl_sample_rate.json"))


def rate(t0s: list[int]) -> float:
    """Samples per second in the steady state: the last pulses' mean period."""
    tail = t0s[-8:]
    return (len(tail) - 1) * TICK_HZ / (tail[-1] - tail[0])


@cocotb.test(timeout_time=10, timeout_unit="sec")
async def sample_rate_vs_model(dut):
    rows = []
    for d, order in CASES:
        sensor = VirtualSensor("front", tx=[0], rx=[0], order=order, max_range_m=4.5)
        sched = Schedule(LAYOUT, [sensor])
        b = Bench(dut, sched)
        dur = 120 * MS
        e0 = await b.start(SyntheticEchoSource({0: d}, ringdown_ticks=60000), 0)
        await b.run_until(e0 + dur)
        await b.read_logs()
        model = FastFiringModel(sched, SyntheticEchoSource({0: d}, ringdown_ticks=60000), start_tick=e0, decision_lead=LEAD)
        res = model.run(dur)
        # the model also lists pulses decided before the end whose t0 is up to LEAD after it
        m_t0 = [p.t0 for p in res.pulses if not p.init and p.t0 < e0 + dur]
        r_t0 = [t for t, _, _, init in b.pulses if t < e0 + dur and not init][-len(m_t0):]
        used = sorted({p.order for p in res.pulses if not p.init})
        rows.append({"distance_m": d, "order": order, "order_used": used, "rtl_hz": rate(r_t0),
                     "model_hz": rate(m_t0), "identical_pulses": r_t0 == m_t0, "pulses": len(m_t0)})
        dut._log.info("%s", rows[-1])
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(rows, indent=1))
