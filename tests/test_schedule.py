"""Virtual-sensor schedule: resolution to ticks, phasing, validation messages, registers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multisonar.constants import DEVICE_DECISION_LEAD, TICK_HZ, seconds_to_ticks, speed_of_sound
from multisonar.layout import load_layout
from multisonar.schedule import (DELAY_W, NUM_VS, REGISTER_FIELDS, Schedule, ScheduleError, VirtualSensor,
                                 analytic_period_s, effective_order, interlace_limit_s, min_tof_for_order,
                                 order_feasible, pause_ticks, phasing_delays, pulse_period)

LAYOUT = load_layout()
C20 = speed_of_sound(20.0)


def sched(*sensors: VirtualSensor, **kw) -> Schedule:
    return Schedule(LAYOUT, list(sensors), **kw)


def test_defaults_resolve_to_ticks():
    r = sched(VirtualSensor("front", tx=[0], rx=[23, 0, 1])).validate()[0]
    assert (r.t_v, r.t_n, r.t_dead, r.t_xtalk) == (24000, 24000, 72000, 72000)
    assert r.max_tof == seconds_to_ticks(2 * 4.3 / C20)
    assert r.blank == 72000 and r.vmax == 24000
    assert list(r.xtalk_elements) == [1, 23]
    # int = ticks, float = seconds
    r2 = sched(VirtualSensor("a", tx=[0], rx=[0], t_v=16000, t_n=0.25e-3)).validate()[0]
    assert (r2.t_v, r2.t_n) == (16000, 12000)


@pytest.mark.parametrize("source", [(0.0, 0.0), (0.2, 0.1), (-0.3, 0.05), (1.0, -0.4)])
@pytest.mark.parametrize("tx", [[0], [23, 0, 1], [10, 11, 12, 13], [22, 23, 0, 1, 2]])
def test_phasing_delays_match_geometry(tx, source):
    c = speed_of_sound(25.0)
    d = phasing_delays(LAYOUT, tx, source, c)
    # independent: time for the imaginary circular wave from the source to reach each element
    t = [math.dist(LAYOUT.positions[e], source) / c for e in tx]
    exact = [(ti - min(t)) * TICK_HZ for ti in t]
    assert np.all(np.abs(d - np.array(exact)) <= 0.5 + 1e-9)
    assert d.min() == 0
    if source == (0.0, 0.0):  # sensors' axes intersect at the origin: all fire together
        assert np.all(d == 0)


def test_wraparound_tx_group_is_adjacent():
    r = sched(VirtualSensor("wrap", tx=[1, 23, 0], rx=[0])).validate()[0]
    assert list(r.tx) == [23, 0, 1]


@pytest.mark.parametrize("sensor, needle", [
    (VirtualSensor("s", tx=[0], rx=[24]), "unknown element(s) [24] in rx group"),
    (VirtualSensor("s", tx=[-1], rx=[0]), "unknown element(s) [-1] in tx group"),
    (VirtualSensor("s", tx=[0, 2], rx=[0]), "not a run of adjacent elements"),
    (VirtualSensor("s", tx=[0, 1, 12, 13], rx=[0]), "not a run of adjacent elements"),
    (VirtualSensor("s", tx=[], rx=[0]), "empty tx group"),
    (VirtualSensor("s", tx=[0], rx=[1, 1]), "lists an element twice"),
    (VirtualSensor("s", tx=[0, 1, 2, 3, 4, 5, 6], rx=[0], source=(0.35, 0.0)), "phasing delay"),
    (VirtualSensor("s", tx=[0], rx=[0], order=4, max_range_m=1.5), "order 4 too high for the range"),
    (VirtualSensor("s", tx=[0], rx=[0], order=1, nominal_range_m=0.6), "order 1 too high for the range"),
    (VirtualSensor("s", tx=[0], rx=[0], order=9), "order 9 outside 0..8"),
    (VirtualSensor("s", tx=[0], rx=[0], nominal_range_m=0.3), "window inside dead zone"),
    (VirtualSensor("s", tx=[0], rx=[0], max_range_m=0.3), "window inside dead zone"),
    (VirtualSensor("s", tx=[0], rx=[0], miss_limit=0), "miss limit K=0"),
    (VirtualSensor("s", tx=[0], rx=[0], miss_limit=16), "miss limit K=16"),
    (VirtualSensor("s", tx=[0], rx=[0], t_v=70000), "T_V = 70000 ticks outside"),
    (VirtualSensor("s", tx=[0], rx=[0], t_dead=2e-3 * 20), "T_dead = 1920000 ticks outside"),
    (VirtualSensor("s", tx=[0], rx=[0], t_dead=1e-4), "shorter than the burst"),
    (VirtualSensor("s", tx=[0], rx=[0], max_range_m=200.0), "exceeds the 24-bit MAX_TOF"),
    (VirtualSensor("s", tx=[0], rx=[0], mode="sweep"), "unknown mode"),
])
def test_validator_rejects(sensor, needle):
    with pytest.raises(ScheduleError) as ei:
        sched(sensor).validate()
    msg = str(ei.value)
    assert needle in msg, msg
    assert "'s'" in msg  # names the sensor


def test_delay_width_boundary():
    # the largest delay of a 7-element group with the source at element 0 exceeds 16 bits
    d = phasing_delays(LAYOUT, [0, 1, 2, 3, 4, 5, 6], (0.35, 0.0), C20)
    assert d.max() >= 2**DELAY_W
    ok = phasing_delays(LAYOUT, [0, 1, 2], (0.35, 0.0), C20)
    assert ok.max() < 2**DELAY_W


def test_table_limits_and_names():
    with pytest.raises(ScheduleError, match="duplicate virtual sensor name"):
        sched(VirtualSensor("a", tx=[0], rx=[0]), VirtualSensor("a", tx=[5], rx=[5])).validate()
    many = [VirtualSensor(f"s{i}", tx=[i], rx=[i], mode="init") for i in range(NUM_VS + 1)]
    with pytest.raises(ScheduleError, match="table holds 8"):
        sched(*many).validate()
    with pytest.raises(ScheduleError, match="no virtual sensors"):
        sched().validate()


def test_windows_of_two_sensors_overlap():
    a = VirtualSensor("left", tx=[6], rx=[6, 7], nominal_range_m=2.0)
    b = VirtualSensor("right", tx=[8], rx=[7], nominal_range_m=2.0, xtalk_neighbours=0)
    with pytest.raises(ScheduleError) as ei:
        sched(a, b).validate()
    msg = str(ei.value)
    assert "'left' and 'right': windows overlap on element 7" in msg, msg


def _phase_into_blank(a_period: int, te_b: int, t_v: int = 24000) -> int:
    # place B's first window start 10000 ticks into the dead zone of A's pulse m
    m = -(-(te_b - t_v) // a_period) + 1
    return m * a_period + 10000 - (te_b - t_v)


def test_dead_zone_overlaps_other_window():
    te_a = seconds_to_ticks(2 * 1.0 / C20)
    r = sched(VirtualSensor("a", tx=[3], rx=[3], nominal_range_m=1.0)).validate()[0]
    n = effective_order(1, te_a, te_a, r.t_v, r.t_n, r.blank)
    per = pulse_period(n, te_a, te_a, r.t_v, r.t_n, r.blank)
    te_b = seconds_to_ticks(2 * 3.0 / C20)
    a = VirtualSensor("a", tx=[3], rx=[3], nominal_range_m=1.0, xtalk_neighbours=0)
    b = VirtualSensor("b", tx=[12], rx=[3], nominal_range_m=3.0, order=0, xtalk_neighbours=0,
                      phase=_phase_into_blank(per, te_b))
    with pytest.raises(ScheduleError) as ei:
        sched(a, b, plan_horizon=_phase_into_blank(per, te_b) + te_b + 100000).validate()
    msg = str(ei.value)
    assert "virtual sensor 'a': transmit dead zone on element 3" in msg and "window of virtual sensor 'b'" in msg, msg


def test_crosstalk_overlaps_other_window():
    te_a = seconds_to_ticks(2 * 1.0 / C20)
    r = sched(VirtualSensor("a", tx=[3], rx=[3], nominal_range_m=1.0)).validate()[0]
    per = pulse_period(effective_order(1, te_a, te_a, r.t_v, r.t_n, r.blank), te_a, te_a, r.t_v, r.t_n, r.blank)
    te_b = seconds_to_ticks(2 * 3.0 / C20)
    a = VirtualSensor("a", tx=[3], rx=[3], nominal_range_m=1.0)  # blanks its neighbours 2 and 4
    b = VirtualSensor("b", tx=[12], rx=[4], nominal_range_m=3.0, order=0, xtalk_neighbours=0,
                      phase=_phase_into_blank(per, te_b))
    with pytest.raises(ScheduleError) as ei:
        sched(a, b, plan_horizon=_phase_into_blank(per, te_b) + te_b + 100000).validate()
    msg = str(ei.value)
    assert "virtual sensor 'a': transmit crosstalk blanking on element 4" in msg, msg


def test_disjoint_sensors_validate():
    s = sched(VirtualSensor("front", tx=[23, 0, 1], rx=[22, 23, 0, 1, 2], order=2, nominal_range_m=2.0),
              VirtualSensor("back", tx=[12], rx=[11, 12, 13], order=1, nominal_range_m=1.5),
              VirtualSensor("side", tx=[6], rx=[6], mode="init"))
    assert len(s.validate()) == 3


def test_registers_fit_their_widths():
    s = sched(VirtualSensor("front", tx=[23, 0, 1], rx=[22, 23, 0, 1, 2], order=2, source=(0.1, 0.0)),
              VirtualSensor("back", tx=[12], rx=[12], mode="init", miss_limit=15))
    regs = s.to_registers()
    assert regs["globals"]["tick_hz"] == TICK_HZ and regs["globals"]["burst_half_period"] == 600
    f0, f1 = regs["sensors"]
    assert f0["tx_mask"] == (1 << 23) | 1 | 2 and f0["rx_mask"] == (1 << 22) | (1 << 23) | 1 | 2 | 4
    assert (f0["mode"], f1["mode"], f0["order"], f1["miss_limit"]) == (1, 2, 2, 15)
    for f in (f0, f1):
        for name, v in f.items():
            assert 0 <= v < 2 ** REGISTER_FIELDS[name][0], name
    r0 = s.resolved[0]
    assert regs["delay_mem"] == {**{0 * 32 + int(e): int(d) for e, d in zip(r0.tx, r0.delays)}, 1 * 32 + 12: 0}
    assert f0["blank"] == max(r0.t_dead, r0.t_xtalk) + int(r0.delays.max())


def test_generalised_equations():
    tv = tn = 24000
    D = 72000
    for n in range(1, 5):
        te_min = min_tof_for_order(n, tv, tn, D)
        assert order_feasible(n, te_min, te_min, tv, tn, D)
        assert not order_feasible(n, te_min - 1, te_min - 1, tv, tn, D)
        assert pause_ticks(n, te_min, tv, tn, D) >= 0
        assert te_min - ((n + 1) * (D + tv) + n * tn) < n  # exact bound up to the floor
    # order 1 is the paper's Eqs. (1)-(2)
    te = 600000
    assert pulse_period(1, te, te, tv, tn, D) == te - D - tv
    assert pause_ticks(1, te, tv, tn, D) == te - 2 * D - 2 * tv - tn
    # the paper's ~70 cm: T_E = 2 T_dead + 2 T_V + T_N = 4.5 ms
    assert 0.7 < C20 * 4.5e-3 / 2 < 0.8
    # Eq. (3): T_s ~ d * 6 ms - 2 ms at order 1; higher orders never beat the interlace limit
    for d in (1.0, 2.0, 3.0, 4.0):
        assert abs(analytic_period_s(d, 1) - (2 * d / C20 - 2e-3)) < 1e-12
        for n in range(1, 5):
            assert analytic_period_s(d, n) >= interlace_limit_s() - 1e-12


def test_blanking_and_window_against_the_decision_lead():
    """D must exceed P (cfg_error LEAD), T_V + T_N must exceed P / 2 (WINDOW_SHORT): the
    boundaries, in ticks."""
    half = DEVICE_DECISION_LEAD // 2
    ok = sched(VirtualSensor("a", tx=[0], rx=[0], t_v=half // 2 + 1, t_n=half // 2)).validate()[0]
    assert ok.t_v + ok.t_n == half + 1
    with pytest.raises(ScheduleError, match="WINDOW_SHORT"):
        sched(VirtualSensor("a", tx=[0], rx=[0], t_v=half // 2, t_n=half // 2)).validate()
    with pytest.raises(ScheduleError, match="cfg_error LEAD"):
        sched(VirtualSensor("a", tx=[0], rx=[0], t_dead=DEVICE_DECISION_LEAD,
                            t_xtalk=DEVICE_DECISION_LEAD)).validate()
