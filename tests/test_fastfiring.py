"""Tick-exact fast-firing model: windows, interlacing, tracking, safety, sharing, wrap-around."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from multisonar.constants import seconds_to_ticks, speed_of_sound
from multisonar.fastfiring import (EVENT_FIELDS, FastFiringModel, PointEchoSource, SyntheticEchoSource, ToFEvent)
from multisonar.layout import load_layout
from multisonar.fastfiring import MISS_MAX
from multisonar.schedule import Schedule, VirtualSensor

LAYOUT = load_layout()
C20 = speed_of_sound(20.0)
MS = 48_000


def model(*sensors, source, **kw):
    return FastFiringModel(Schedule(LAYOUT, list(sensors)), source, **kw)


def expected_period(te: int, order: int, tv=24000, tn=24000, D=72000) -> tuple[int, int]:
    """Independent restatement of the contract (docs/fast_firing.md section 4)."""
    for n in range(order, 0, -1):
        ts = (te - tv - D) // n
        if ts > 0 and (n + 1) * ts >= te + tn:
            return n, ts
    return 0, te + tn


@pytest.mark.parametrize("order", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("dist", [0.8, 1.2, 2.0, 3.0, 4.0])
def test_static_wall_rate_and_windows(dist, order):
    src = SyntheticEchoSource(dist, ringdown_ticks=60000)
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=order), source=src)
    res = m.run(250 * MS)
    te = src.tof_ticks(dist, 0)
    n, ts = expected_period(te, order)
    p = res.pulses
    assert p[0].init and not any(q.init for q in p[1:])
    track = p[1:]
    assert len(track) >= 10
    assert all(q.order == n and q.period == ts for q in track)
    assert set(np.diff([q.t0 for q in track])) == {ts}  # sample rate 1/T_s exactly, in ticks
    assert not any(e.window_empty for e in res.events)  # every window holds its echo
    for q in track:  # interlacing: window k opens after pulse k+n fired and closes before k+n+1
        i = q.seq
        if i + n + 1 < len(p):
            for _, ws, we in q.windows:
                assert p[i + n].t0 + 72000 <= ws and we <= p[i + n + 1].t0
    samples = [e for e in res.samples() if not e.init_ping]
    assert {e.tof for e in samples} == {te}
    assert len(samples) == 3 * sum(1 for q in track if q.windows[0][2] + 25 <= m.now)


def test_init_ping_open_window_and_first_echo():
    src = SyntheticEchoSource({0: [1.0, 2.5], 1: 1.4}, ringdown_ticks=60000)
    m = model(VirtualSensor("s", tx=[0], rx=[0, 1, 2], order=1), source=src, max_echoes_per_window=4)
    res = m.run(30 * MS)
    ping = res.pulses[0]
    R = m.cfg[0].max_tof
    assert ping.init and ping.windows == ((0, 72000, R), (1, 72000, R), (2, 72000, R))
    ev = [e for e in res.events if e.seq == 0]
    assert [(e.rx, e.tof, e.first_echo) for e in ev if e.in_window] == [
        (0, src.tof_ticks(1.0, 0), True), (1, src.tof_ticks(1.4, 0), True), (0, src.tof_ticks(2.5, 0), False)]
    assert [(e.rx, e.window_empty, e.tof) for e in ev if not e.in_window] == [(2, True, R)]
    assert all(e.init_ping for e in ev)
    # the ring-down on element 0 (inside the dead zone) was never reported
    assert m.predicted_tof(0, 0) == src.tof_ticks(1.0, 0) and m.predicted_tof(0, 2) is None


def test_no_echo_repeats_init_pings():
    m = model(VirtualSensor("s", tx=[4], rx=[4, 5], order=2), source=SyntheticEchoSource({}))
    res = m.run(100 * MS)
    R = m.cfg[0].max_tof
    # the next ping waits for the open window's result: close tick = R - 1 + (1 + glitch_min)
    assert all(p.init for p in res.pulses) and set(np.diff([p.t0 for p in res.pulses])) == {R + 24}
    assert all(e.window_empty and e.init_ping for e in res.events)


def test_init_only_mode():
    m = model(VirtualSensor("s", tx=[4], rx=[4], mode="init"), source=SyntheticEchoSource(1.0))
    res = m.run(120 * MS)
    assert all(p.init for p in res.pulses) and len(res.pulses) == 5
    assert len(res.samples()) == 5


@pytest.mark.parametrize("gate", [None, 0])
@pytest.mark.parametrize("order", [1, 2, 3])
def test_tracks_approaching_reflector_at_2mps(order, gate):
    """gate None: the default gated miss rule; 0: off. At order 3 the switch to order 2 defers
    one pulse by ~4 intervals; the per-pulse velocity then mispredicts the next echo by more
    than the gate and the sensor re-initialises once (docs/fast_firing.md section 4.4)."""
    src = SyntheticEchoSource(3.2, velocity_mps=2.0)  # 3.2 m -> 1.2 m in 1 s
    kw = {} if gate is None else {"miss_gate": gate}
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=order), source=src, **kw)
    res = m.run(1000 * MS)
    inits = sum(p.init for p in res.pulses)
    if order == 3 and gate is None:
        assert inits == 2, "the known cost of the gate: one re-init at the order switch"
        return
    assert inits == 1  # never lost lock
    assert not any(e.window_empty for e in res.events)
    t0 = {p.seq: p.t0 for p in res.pulses}
    samples = res.samples(rx=0)
    for e in samples:  # exact ToF of the reflector at that pulse
        assert e.tof == src.tof_ticks(3.2, t0[e.seq]) - 0
    assert samples[-1].tof < src.tof_ticks(1.35, 0)
    # rate increases as it approaches (period follows the prediction)
    periods = [p.period for p in res.pulses[1:]]
    assert periods[-1] < periods[0]


def test_prediction_is_constant_velocity_and_clamped():
    src = SyntheticEchoSource(2.5, velocity_mps=1.5)
    m = model(VirtualSensor("s", tx=[0], rx=[0], order=2, vmax=1000), source=src)
    m.run(200 * MS)
    for _ in range(40):  # (the bound on the sample measuring v re-initialises it now and then)
        if m.sensors[0].rx[0].tracked:
            break
        m.run(5 * MS)
    st = m.sensors[0].rx[0]
    assert st.tracked
    k = m.sensors[0].seq
    assert st.v == -1000 or st.v == 0  # clamped at vmax (true change is ~2000 ticks/pulse)
    lo, hi = m.cfg[0].te_limits()
    assert m.predicted_tof(0, 0) == max(lo, min(hi, st.tof + (k - st.seq) * st.v))


@pytest.mark.parametrize("order,K", [(1, 3), (2, 2), (3, 4)])
def test_safety_obstacle_steps_in_front_of_tracked_wall(order, K):
    step = 300 * MS
    src = SyntheticEchoSource(3.0, step_tick=step, step_ranges_m=1.1)
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=order, miss_limit=K), source=src)
    res = m.run(600 * MS)
    after = [p for p in res.pulses if p.t0 >= step]
    reinit = next(p for p in after if p.init)
    # every tracking pulse fired since the step ran into an empty window; the init ping went
    # out as soon as the K-th consecutive empty window of a receiver closed (or right after
    # the sensor's own older windows let it).
    tracked_after = [p for p in after if p.t0 < reinit.t0]
    empties = defaultdict(list)
    for e in res.events:
        if e.window_empty and not e.init_ping and e.tick <= reinit.t0:
            empties[e.rx].append(e)
    kth_close = min(v[K - 1].tick for v in empties.values() if len(v) >= K)
    # own pending windows were cancelled; the ping only waits until no echo of an earlier
    # pulse (within max range) can reach its open window
    cfg = m.cfg[0]
    assert reinit.due == kth_close
    assert reinit.t0 == max(reinit.due, tracked_after[-1].t0 + cfg.max_tof - cfg.blank)
    assert len(tracked_after) <= K + order + 1
    # no event for the cancelled windows: every reported empty window belongs to a pulse
    # fired before the re-init decision
    assert all(e.tick <= kth_close for e in res.events if e.window_empty and not e.init_ping and e.tick > step)
    # the new range is reported by the init ping and then tracked
    new_tof = src.tof_ticks(1.1, 0)
    init_samples = [e for e in res.samples() if e.init_ping and e.tick > step]
    assert {e.tof for e in init_samples} == {new_tof}
    later = [e for e in res.samples() if not e.init_ping and e.tick > init_samples[0].tick]
    assert later and {e.tof for e in later} == {new_tof}


def test_sequence_numbers_of_pulses_in_flight_and_wrap():
    src = SyntheticEchoSource(1.0)
    m = model(VirtualSensor("s", tx=[0], rx=[0], order=1), source=src)
    res = m.run(1200 * MS)
    assert len(res.pulses) > 300  # > 2**8 pulses: seq wraps
    t0 = {p.seq: p.t0 for p in res.pulses}
    seqs = [e.seq for e in res.samples()]
    assert max(seqs) == 255 and seqs.count(0) >= 2
    # every event carries the sequence number of the pulse whose echo it is: pulses k+1 was
    # already in flight when the echo of k arrived, yet tof = edge - t0(k)
    for e in res.samples():
        if e.init_ping:
            continue
        k = max(q for q in t0 if q & 0xFF == e.seq and t0[q] < e.tick)
        assert e.tof == src.tof_ticks(1.0, 0)
        later = [q for q in t0 if t0[q] < e.tick - 25 and q > k]
        assert later, "order-1 interlacing: the next pulse fired before this echo"


def test_miss_counter_saturates_at_width():
    assert MISS_MAX == 15


def test_event_word_round_trip_and_widths():
    e = ToFEvent(tick=5, sensor=7, seq=255, rx=23, tof=(1 << 24) - 1, in_window=True, first_echo=False,
                 window_empty=True, init_ping=True)
    w = e.pack()
    assert w < 1 << 44 and ToFEvent.unpack(w, tick=5) == e
    g = e._replace(window_empty=False, first_echo=True, gated=True)
    assert g.pack() == g._replace(gated=False).pack() | 1 << 45 and ToFEvent.unpack(g.pack(), tick=5) == g
    spans = sorted((lsb, lsb + width) for lsb, width in EVENT_FIELDS.values())
    # contiguous except bit 44, the FIFO's overflow flag on every word
    assert [(a[1], b[0]) for a, b in zip(spans, spans[1:]) if a[1] != b[0]] == [(44, 45)]
    with pytest.raises(ValueError):
        e._replace(tof=1 << 24).pack()


def test_timestamp_wrap_does_not_change_results():
    def go(start):
        m = model(VirtualSensor("s", tx=[0], rx=[23, 0], order=2), source=SyntheticEchoSource(1.7), start_tick=start)
        r = m.run(120 * MS)
        return ([(p.t0 - start, p.seq, p.period) for p in r.pulses],
                [(e.tick - start,) + tuple(e[1:]) for e in r.events])

    assert go(0) == go((1 << 32) - 500_000)


def test_glitch_filter_and_edge_rules():
    class Src:
        def fire(self, t0, el, d):
            base = t0 + 300_000
            return [(0, base, 10),  # glitch: shorter than glitch_min -> ignored
                    (0, base + 40, 100), (0, base + 150, 100),  # gap 10 < 24 -> one run, one edge
                    (0, base + 400, 30), (0, base + 430, 50),  # touching pulses -> one edge
                    (1, base, 200), (1, base + 100, 200),  # overlapping -> one edge at base
                    (2, base + 500, 24)]  # exactly glitch_min -> accepted

    m = model(VirtualSensor("s", tx=[12], rx=[0, 1, 2], mode="init"), source=Src(), max_echoes_per_window=8)
    res = m.run(20 * MS)
    got = [(e.rx, e.tof, e.tick - e.tof) for e in res.events if e.in_window]
    # tick = edge + 1 + glitch_min (rx conditioner latency); tof = edge - t0
    assert got == [(1, 300_000, 25), (0, 300_040, 25), (0, 300_400, 25), (2, 300_500, 25)]


def test_point_source_multi_receiver():
    src = PointEchoSource(LAYOUT, (1.5, 0.3))
    m = model(VirtualSensor("s", tx=[23, 0, 1], rx=[22, 23, 0, 1, 2], order=2), source=src)
    res = m.run(300 * MS)
    assert sum(p.init for p in res.pulses) == 1 and not any(e.window_empty for e in res.events)
    tofs = {e.rx: e.tof for e in res.samples()}
    assert len(tofs) == 5 and tofs[1] < tofs[23]  # reflector is to the left (+y)


# ---------------------------------------------------------------------------------------
# several sensors share the ring: no window ever overlaps a window or a blanking interval
# of another pulse on the same element
# ---------------------------------------------------------------------------------------

def check_no_conflicts(pulses, cancelled=()):
    cut = {(s, k, rx): t for s, k, rx, t in cancelled}  # a cancelled window ends when cancelled
    per_el = defaultdict(list)
    for p in pulses:
        for e, a, b in p.windows:
            b = min(b, cut.get((p.sensor, p.seq, e), b))
            if b > a:  # a window cancelled before it opened never existed
                per_el[e].append((a, b, "w", p.sensor, p.seq))
        for e, a, b in p.blanks:
            per_el[e].append((a, b, "b", p.sensor, p.seq))
    for e, ivs in per_el.items():
        ivs.sort()
        wins = [iv for iv in ivs if iv[2] == "w"]
        for x, y in zip(wins, wins[1:]):
            assert x[1] <= y[0], f"windows overlap on element {e}: {x} {y}"
        blanks = [iv for iv in ivs if iv[2] == "b"]
        for w in wins:
            for b in blanks:
                assert not (b[0] < w[1] and w[0] < b[1]), f"blank {b} overlaps window {w} on element {e}"


sensor_st = st.fixed_dictionaries({
    "tx0": st.integers(0, 23), "k": st.integers(1, 3),
    "rx": st.lists(st.integers(0, 23), min_size=1, max_size=4, unique=True),
    "order": st.integers(0, 4), "mode": st.sampled_from(["track", "track", "track", "init"]),
    "phase": st.integers(0, 20 * MS), "range": st.floats(0.5, 4.0), "K": st.integers(1, 4),
})


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(sensor_st, min_size=2, max_size=4), st.floats(-2.0, 2.0))
def test_property_multiple_sensors_never_conflict(cfgs, vel):
    sensors = [VirtualSensor(f"s{i}", tx=[(c["tx0"] + j) % 24 for j in range(c["k"])], rx=c["rx"], order=c["order"],
                             mode=c["mode"], phase=c["phase"], miss_limit=c["K"]) for i, c in enumerate(cfgs)]
    ranges = {rx: cfgs[0]["range"] + 0.05 * (rx % 3) for rx in range(24)}
    src = SyntheticEchoSource(ranges, velocity_mps=vel, ringdown_ticks=50000)
    m = FastFiringModel(Schedule(LAYOUT, sensors, check_plan=False), src)
    res = m.run(150 * MS)
    check_no_conflicts(res.pulses, res.cancelled)
    # every issued pulse waited for its due tick
    assert all(p.t0 >= p.due for p in res.pulses)
    # triggers are the issued pulses' tx elements at t0 + delay
    assert len(res.triggers) == sum(len(m.cfg[p.sensor].tx) for p in res.pulses)
    check_no_tx_overlap(res.triggers, m.cfg)


def check_no_tx_overlap(triggers, cfg):
    """Rule 5: an element is triggered again only after the dead zone of its last trigger
    (T_dead >= the burst, so two bursts never overlap on one element)."""
    last: dict[int, tuple[int, int]] = {}
    for tr in sorted(triggers, key=lambda tr: tr.tick):
        if tr.element in last:
            tick, sensor = last[tr.element]
            assert tr.tick >= tick + cfg[sensor].t_dead, f"element {tr.element} triggered at {tr.tick}, " \
                f"within the dead zone of its trigger at {tick} (sensor {sensor})"
        last[tr.element] = (tr.tick, tr.sensor)


def test_sensors_sharing_a_tx_element_never_overlap_bursts():
    # both fire element 5 at the same range and period: without rule 5 they fire within one burst
    src = SyntheticEchoSource(1.2, ringdown_ticks=50000)
    a = VirtualSensor("a", tx=[4, 5], rx=[4, 5], order=2)
    b = VirtualSensor("b", tx=[5, 6], rx=[7], order=2)
    m = model(a, b, source=src)
    res = m.run(300 * MS)
    check_no_tx_overlap(res.triggers, m.cfg)
    check_no_conflicts(res.pulses, res.cancelled)
    assert len(res.samples(sensor=0)) > 20 and len(res.samples(sensor=1)) > 20


def test_shared_receiver_defers_deterministically():
    # two sensors listen on the same element at the same range: the higher id is deferred
    src = SyntheticEchoSource(1.5)
    a = VirtualSensor("a", tx=[0], rx=[0, 1], order=1)
    b = VirtualSensor("b", tx=[2], rx=[1, 2], order=1)
    r1 = model(a, b, source=src).run(200 * MS)
    r2 = model(a, b, source=src).run(200 * MS)
    assert r1.pulses == r2.pulses and r1.events == r2.events
    check_no_conflicts(r1.pulses, r1.cancelled)
    assert any(p.t0 > p.due for p in r1.pulses if p.sensor == 1)
    assert r1.pulses[0].sensor == 0 and r1.pulses[0].t0 == 0
    assert len(r1.samples(sensor=0)) > 10 and len(r1.samples(sensor=1)) > 10


class _PerTickRetry(FastFiringModel):
    """What the RTL does: a blocked pulse is retried on the very next tick."""

    def _conflict(self, t, blanks, wins, n_tx=0):
        r = super()._conflict(t, blanks, wins, n_tx)
        return None if r is None else t + 1


def test_deferral_jump_equals_per_tick_retry():
    import copy

    src = SyntheticEchoSource({0: 1.3, 1: 1.3, 2: 2.1, 3: 0.9}, ringdown_ticks=50000)
    sensors = [VirtualSensor("a", tx=[0], rx=[0, 1], order=1), VirtualSensor("b", tx=[2], rx=[1, 2], order=2),
               VirtualSensor("c", tx=[3], rx=[3, 2], order=1, phase=3000)]
    fast_m = FastFiringModel(Schedule(LAYOUT, sensors), src)
    fast_m.run(86 * MS)  # past the (long, mutually deferred) init pings
    slow_m = copy.deepcopy(fast_m)
    slow_m.__class__ = _PerTickRetry
    fast, slow = fast_m.run(5 * MS), slow_m.run(5 * MS)
    assert any(p.t0 > p.due for p in fast.pulses)
    assert fast.pulses == slow.pulses and fast.events == slow.events and fast.triggers == slow.triggers


# -- decision lead P (docs/fast_firing.md section 3.1) ------------------------------------

def _replay_prediction(res, m, lead):
    """Independent check of the decision-lead rule: every tracking pulse's windows follow
    from the first-echo samples detected no later than its decision tick t0 - P (the
    prediction rule of docs/fast_firing.md section 4.2, with the model's default gate on)."""
    c = m.cfg[0]
    lo, hi = c.te_limits()
    assert m.miss_gate
    samples = sorted((e.tick, e.rx, e.seq, e.tof, e.init_ping) for e in res.events if e.first_echo and not e.gated)
    seqs = {p.seq & 0xFF: p.seq for p in res.pulses}

    def vclamp(v):
        return max(-c.vmax, min(c.vmax, v))
    for p in res.pulses:
        if p.init:
            continue
        st: dict[int, tuple[int, int, int, bool, bool]] = {}  # rx -> (tof, seq, v, from_init, vel)
        for tick, rx, sq, tof, init in samples:
            if tick > p.t0 - lead:
                break
            k = seqs[sq]
            if init:
                st[rx] = (tof, k, 0, True, False)
            elif rx in st and k > st[rx][1]:
                t_prev, k_prev, v, was_init, vel = st[rx]
                if vel and k - k_prev == 1:   # v plus half the residual from the prediction
                    st[rx] = (tof, k, vclamp(v + ((tof - max(lo, min(hi, t_prev + v))) >> 1)), False, True)
                elif vel:                     # after a skipped pulse: v kept
                    st[rx] = (tof, k, v, False, True)
                elif k - k_prev == 1 and not was_init:
                    st[rx] = (tof, k, vclamp(tof - t_prev), False, True)
                else:
                    st[rx] = (tof, k, 0, False, False)
        want = {rx: max(lo, min(hi, tof + (p.seq - k) * v)) for rx, (tof, k, v, _, _) in st.items()}
        got = {rx: ws - p.t0 + c.t_v for rx, ws, we in p.windows}
        assert got == want, (p.seq, got, want)


@pytest.mark.parametrize("lead", [1, 1024, 30000])
@pytest.mark.parametrize("order", [1, 3])
def test_decision_lead_uses_state_at_t0_minus_lead(lead, order):
    src = SyntheticEchoSource(3.0, velocity_mps=2.0)
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=order), source=src, decision_lead=lead)
    res = m.run(600 * MS)
    assert sum(p.init for p in res.pulses) == 1 and not any(e.window_empty for e in res.events)
    assert res.pulses[0].t0 == lead  # phase 0: decided at tick 0 for t0 = P
    _replay_prediction(res, m, lead)
    t0 = {p.seq: p.t0 for p in res.pulses}
    assert all(e.tof == src.tof_ticks(3.0, t0[e.seq]) for e in res.samples(rx=0))


def test_decision_lead_zero_is_the_default_and_init_period_grows_by_lead():
    src = SyntheticEchoSource({})
    base = model(VirtualSensor("s", tx=[4], rx=[4, 5], order=2), source=src).run(100 * MS)
    zero = model(VirtualSensor("s", tx=[4], rx=[4, 5], order=2), source=src, decision_lead=0).run(100 * MS)
    assert base == zero
    m = model(VirtualSensor("s", tx=[4], rx=[4, 5], order=2), source=src, decision_lead=500)
    res = m.run(100 * MS)
    R = m.cfg[0].max_tof
    assert set(np.diff([p.t0 for p in res.pulses])) == {R + 24 + 500}
    with pytest.raises(ValueError):
        model(VirtualSensor("s", tx=[4], rx=[4]), source=src, decision_lead=-1)


@pytest.mark.parametrize("lead", [0, 1024])
def test_decision_lead_static_wall_same_rate_and_safety(lead):
    src = SyntheticEchoSource(2.0)
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=2), source=src, decision_lead=lead)
    res = m.run(200 * MS)
    track = [p for p in res.pulses if not p.init]
    n, ts = expected_period(src.tof_ticks(2.0, 0), 2)
    assert all(q.order == n and q.period == ts for q in track[1:])
    step = 300 * MS
    src = SyntheticEchoSource(3.0, step_tick=step, step_ranges_m=1.1)
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=2, miss_limit=2), source=src, decision_lead=lead)
    res = m.run(600 * MS)
    reinit = next(p for p in res.pulses if p.t0 >= step and p.init)
    assert any(e.seq == reinit.seq & 0xFF and e.first_echo and e.tof == src.tof_ticks(1.1, reinit.t0)
               for e in res.events)
    assert reinit.t0 - step < 3 * 10 * MS + m.cfg[0].max_tof + lead


def test_record_words_round_trip():
    from multisonar.fastfiring import PulseStart, SensorCancel, unpack_word
    p = PulseStart(tick=3, sensor=5, pulse_id=0xFFFF, t0=0xFFFFFFFF, init_ping=True, n_win=31)
    w = p.pack()
    assert w < 1 << 63 and not w & (1 << 44) and unpack_word(w, 3) == p  # bit 44 is the FIFO's
    assert (w >> 37) & 7 == 5 and (w >> 43) & 1 == 1  # where a ToF event has sensor and init_ping
    c = SensorCancel(tick=0x1_2345_6789, sensor=7)
    assert unpack_word(c.pack()) == SensorCancel(tick=0x2345_6789, sensor=7)
    with pytest.raises(ValueError):
        p._replace(n_win=32).pack()
    with pytest.raises(ValueError):
        PulseStart.unpack(c.pack())


@pytest.mark.parametrize("order,K,lead", [(0, 1, 0), (2, 2, 4096), (4, 3, 4096)])
def test_records_give_exact_t0_and_completion(order, K, lead):
    """What a reader of the FIFO words alone reconstructs (the firmware's rule): every pulse's
    record comes before its events with the true t0, and a pulse is complete when n_win
    terminal events (first echo or window_empty) have arrived or at its sensor's next cancel
    record, after which no event of it comes; safety re-initialisations included."""
    from multisonar.fastfiring import PulseStart, SensorCancel, unpack_word
    src = SyntheticEchoSource(3.0, step_tick=seconds_to_ticks(0.06), step_ranges_m=1.1)
    m = model(VirtualSensor("front", tx=[0], rx=[23, 0, 1], order=order, miss_limit=K),
              VirtualSensor("left", tx=[6], rx=[5, 6, 7], order=order, miss_limit=K, phase=1e-3),
              source=src, decision_lead=lead)
    res = m.run(seconds_to_ticks(0.3))
    assert len(res.words) == len(res.events) + len(res.records)
    assert any(isinstance(r, SensorCancel) for r in res.records), "the scene must trigger a safety cancel"
    t0_true = {(p.sensor, p.seq & 0xFFFF): p.t0 for p in res.pulses}
    open_: dict[tuple[int, int], list[int]] = {}  # (sensor, seq8) -> [n_win, terminal events, pulse id]
    done: set[tuple[int, int]] = set()
    complete = 0
    for w in res.words:
        x = unpack_word(w)
        if isinstance(x, PulseStart):
            assert x.t0 == t0_true[(x.sensor, x.pulse_id)] & 0xFFFFFFFF
            key = (x.sensor, x.pulse_id & 0xFF)
            assert key not in open_
            open_[key] = [x.n_win, 0, x.pulse_id]
            done.discard(key)
        elif isinstance(x, SensorCancel):
            for key in [k for k in open_ if k[0] == x.sensor]:
                done.add(key)
                del open_[key]
        else:
            key = (x.sensor, x.seq)
            assert key in open_ and key not in done, f"event of a pulse without an open record: {x}"
            if x.first_echo or x.window_empty:
                open_[key][1] += 1
                if open_[key][1] == open_[key][0]:
                    done.add(key)
                    del open_[key]
                    complete += 1
    assert complete > 10
