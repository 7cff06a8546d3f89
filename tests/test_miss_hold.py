"""The miss hold of the golden model (docs/fast_firing.md section 4.4; RTL: the scheduler
program's decision, RX_FILTER.miss_hold): a sensor with a missed window on a tracked receiver
decides its next tracking pulse only once its last pulse's windows have closed, then at order 0
while the miss is pending. The program's equality with the model is checked by
tests/test_sched_mainloop.py, the RTL's by tests/rtl/tb_ms_scheduler.py and tb_ms_sonar_core.py."""

from __future__ import annotations

import pytest

from multisonar.constants import DEVICE_DECISION_LEAD
from multisonar.device import Device
from multisonar.fastfiring import FastFiringModel
from multisonar.generated import sonar_regs as R
from multisonar.layout import load_layout
from multisonar.safety import run_trial, wide_trial_params
from multisonar.schedule import Schedule, VirtualSensor
from multisonar.simdevice import SimDevice
from fade_source import FadeSource  # tests/rtl (on sys.path, tests/conftest.py)

MS = 48_000
LAYOUT = load_layout()


def _fade_run(hold: bool, order: int):
    sched = Schedule(LAYOUT, [VirtualSensor("s", tx=[10], rx=[9, 10, 11], order=order, miss_limit=3)])
    m = FastFiringModel(sched, FadeSource(2.5, rx=10, fade_tick=60 * MS), decision_lead=DEVICE_DECISION_LEAD,
                         miss_hold=hold)
    res = m.run(120 * MS)
    assert sum(p.init for p in res.pulses) == 1, "one missed window: no re-initialisation"
    empty = [e.tick for e in res.events if e.window_empty and not e.init_ping]
    assert len(empty) == 1, "one missed window"
    k = next(i for i, p in enumerate(res.pulses) if p.t0 - m.lead >= empty[0])
    track = [p for p in res.pulses if not p.init]
    assert all(p.order == order for p in track[2:] if p.t0 - m.lead < empty[0]), "interlaced before"
    assert all(p.order == order for p in track if p.t0 > res.pulses[k].t0 + 30 * MS), "and after"
    return m, res.pulses[k - 1], res.pulses[k], res.pulses[k + 1]


@pytest.mark.parametrize("order", [1, 3])
def test_a_miss_holds_the_next_pulse_until_the_windows_in_flight_have_closed(order):
    """The first pulse decided after the miss is decided at the close tick of its predecessor's
    windows (later than its interlaced due). At order 3 the windows in flight resample the track
    (the miss is cleared): that pulse interlaces again; at order 1 the one window in flight is a
    sample after a skipped pulse, which keeps the miss: that pulse goes at order 0."""
    m, a, b, c = _fade_run(True, order)
    last_close = max(end for _, _, end in a.windows) - 1 + m.latency
    assert b.t0 - m.lead == last_close and b.t0 > a.t0 + a.period
    assert b.order == (order if order > 1 else 0) and c.order == order


def test_without_the_hold_the_sensor_keeps_interlacing_through_the_miss():
    m, a, b, _ = _fade_run(False, 1)
    assert b.t0 == a.t0 + a.period and b.order == 1


@pytest.mark.parametrize("hold,outcome", [(True, "detected"), (False, "late")])
def test_the_alias_that_outlived_the_gate_is_caught_by_the_hold(hold, outcome):
    """Seed 159 of the wide generator (order 4, K = 3): after one empty and one gated window the
    person's echo of pulse k + 3 fell within the gate of the hidden wall's track in two windows
    in a row and reset its misses (late: 11 pulses for a bound of 8). With the hold, pulse k + 3
    is not fired before those windows have closed."""
    r = run_trial(159, params=wide_trial_params(159), miss_hold=hold)
    assert r.outcome == outcome, (r.latency_pulses, r.bound_pulses)


def test_the_register_reaches_the_simulated_device_and_the_driver_sets_it():
    """RX_FILTER.miss_hold, reset 1: the simulated device's model takes it at START;
    Device.set_miss_hold writes it (miss_gate and glitch_min kept) and reads it back."""
    f = R.REGISTERS["RX_FILTER"].fields
    sim = SimDevice("corridor")
    with Device.attach(sim) as dev:
        dev.configure([VirtualSensor("front", tx=[0], rx=[23, 0, 1])])
        assert f["MISS_HOLD"].get(dev.read_regs([R.RX_FILTER_ADDR])[0]) == 1
        for on in (False, True):
            gate = dev.set_miss_gate(1234)
            assert dev.set_miss_hold(on) is on and gate == 1234
            rx = dev.read_regs([R.RX_FILTER_ADDR])[0]
            assert (f["MISS_GATE"].get(rx), f["GLITCH_MIN"].get(rx)) == (1234, 24)
            dev.start()
            assert sim.model.miss_hold is on and sim.model.miss_gate == 1234
            dev.stop()
