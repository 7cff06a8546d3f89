"""Safety property of fast firing on the golden model (issue #9; multisonar.safety).

A person stepping between the robot and a tracked wall must be reported within the bound the
design promises: the N pulses in flight, K empty windows, one initialisation ping. Echoes of
neighbouring pulses (interlacing aliases) that land in a tracked window used to reset the K-miss
counter; the gated miss rule (RX_FILTER.miss_gate, 10.4 us by default, in RTL and model) makes a
first echo far from the prediction count as a miss. With it the sampled property holds on the
CI seeds, but not on every seed (the strict xfail below keeps a known late seed honest)."""

from __future__ import annotations

import pytest

from multisonar.fastfiring import DEFAULT_MISS_GATE
from multisonar.safety import random_trial_params, run_trial, summarise

BASE = dict(seed=100, wall_y=2.0, person_y=1.2, person_radius=0.25, person_speed=-1.5, robot_speed=1.0)


@pytest.mark.parametrize("order,miss_limit", [(1, 2), (2, 2)])
def test_person_hiding_the_tracked_wall_is_reported_within_n_plus_k_plus_1(order, miss_limit):
    r = run_trial(100, params=BASE | dict(order=order, miss_limit=miss_limit))
    assert r.order == order, "the schedule must run at the requested order"
    assert r.onset_pulse > 0, "the sensor must be tracking the wall before the person hides it"
    assert r.init_pings >= 2, "the wall track must be dropped (K empty windows -> init ping)"
    assert r.outcome == "detected", (
        f"person reported {r.latency_pulses} pulses after hiding the wall, bound {r.bound_pulses} ({r})")
    assert 0 <= r.latency_pulses <= r.bound_pulses
    assert r.false_samples <= 0.01 * r.samples, f"{r.false_samples} of {r.samples} tracking samples match no echo"


def test_trial_parameters_are_reproducible_and_in_domain():
    for seed in range(50):
        p = random_trial_params(seed)
        assert p == random_trial_params(seed)
        assert 0.35 + p["person_radius"] < p["person_y"] < p["wall_y"] - p["person_radius"]
        assert abs(p["person_speed"] - p["robot_speed"]) >= 1.0 or abs(p["person_speed"]) == 2.2


def test_randomised_person_crossings_all_reported_within_the_bound():
    """The sampled property with the default gated miss rule (seeds 0-3, as before the rule
    existed: without the gate seed 0 is late, 7 pulses for a bound of 5, the former strict xfail)."""
    results = [run_trial(seed) for seed in range(4)]
    s = summarise(results)
    assert s["counted"] >= 3
    assert s["detected"] == s["counted"], f"late {s['late']}, missed {s['missed']} of {s['counted']}"


@pytest.mark.xfail(strict=True, reason=(
    "known residual hazard (issues #9, #28): even with the 10.4 us gated miss rule and the smoothed "
    "velocity some crossings are reported late: seed 25 of this generator (order 1, K 3): the "
    "person's echo of the next pulse lands in the tracked window ahead of the wall's, within the "
    "gate, for more pulses than the bound has to spare. The sensor's forced re-init every "
    "M <= N + K + 1 pulses (reinit_every) bounds it."))
def test_known_late_crossing_with_the_gate_is_reported_within_the_bound():
    r = run_trial(25)
    assert r.onset_pulse > 0
    assert r.outcome == "detected", r


def test_gated_miss_rule_removes_an_alias_delay():
    """Seed 12 (order 2, K 3), without the miss hold: without the gate an echo of the
    neighbouring pulse keeps the lost wall track alive (late); with the default gated miss rule (a
    first echo > 10.4 us from the prediction counts as a miss) the person is reported within the
    bound. The miss hold alone (gate off) reports it within the bound too."""
    ungated = run_trial(12, miss_gate=0, miss_hold=False)
    gated = run_trial(12, miss_hold=False)
    assert run_trial(12, miss_gate=0).outcome == "detected"
    assert DEFAULT_MISS_GATE == 500
    assert ungated.outcome == "late" and ungated.alias_samples > 0
    assert gated.outcome == "detected", gated
    assert gated.latency_pulses < ungated.latency_pulses


def test_model_safety_options_are_validated():
    from multisonar.fastfiring import FastFiringModel, SyntheticEchoSource
    from multisonar.layout import load_layout
    from multisonar.schedule import Schedule, VirtualSensor
    sched = Schedule(load_layout(), [VirtualSensor("s", tx=[0], rx=[0])])
    with pytest.raises(ValueError, match="miss_gate"):
        FastFiringModel(sched, SyntheticEchoSource({0: 1.0}), miss_gate=-1)
    with pytest.raises(ValueError, match="miss_gate"):
        FastFiringModel(sched, SyntheticEchoSource({0: 1.0}), miss_gate=1 << 16)  # RX_FILTER.miss_gate is 16 bits
    assert FastFiringModel(sched, SyntheticEchoSource({0: 1.0}), miss_gate=0).miss_gate is None  # 0 = off
    with pytest.raises(ValueError, match="reinit_every"):
        FastFiringModel(sched, SyntheticEchoSource({0: 1.0}), reinit_every=0)


def test_model_default_gate_is_the_register_reset_value():
    from multisonar.generated import sonar_regs as R
    f = R.REGISTERS["RX_FILTER"].fields["MISS_GATE"]
    assert f.reset == DEFAULT_MISS_GATE and f.width == 16


def test_forced_reinit_at_the_bound_reports_the_known_late_crossings_within_it():
    """The sensor's reinit_every (MODE.reinit_every in the RTL): an init ping at the latest after M tracking
    pulses bounds the latency by M pulses by construction (the init ping's open window hears
    the person first), so M = N + K + 1 ("bound") guarantees the bound; the seeds late with the
    gate alone pass. The cost: fewer tracking samples while the wall is tracked."""
    for seed in (6, 16, 25, 57):
        r = run_trial(seed, reinit_every="bound")
        assert r.reinit_every == r.bound_pulses
        assert r.outcome == "detected" and 0 <= r.latency_pulses <= r.reinit_every, r
    base, forced = run_trial(25), run_trial(25, reinit_every="bound")
    assert base.outcome == "late"
    assert forced.pre_onset_samples / forced.pre_onset_s < 0.8 * base.pre_onset_samples / base.pre_onset_s


#: 50 crossings of the wide generator with seeds that neither scripts/bench_safety.py (0..) nor
#: `multisonar experiment safety` (default 0..999) uses (issue #28: CI runs at least 50)
CI_SEEDS = range(900_000, 900_050)


def test_wide_generator_crossings_on_unused_seeds_are_reported_within_the_bound():
    from multisonar.safety import wide_trial_params

    results = [run_trial(seed, params=wide_trial_params(seed)) for seed in CI_SEEDS]
    s = summarise(results)
    assert s["counted"] >= 40, s
    assert len({r.order for r in results}) >= 5, "the wide generator must reach the higher orders"
    late = [(r.seed, r.order, r.miss_limit, r.latency_pulses, r.bound_pulses) for r in results
            if r.outcome in ("late", "missed")]
    assert not late, late
    assert s["false_fixes"] <= 0.001 * s["fixes"], s


def test_wide_trial_parameters_are_reproducible_and_in_domain():
    from multisonar.safety import nearest_lane_m, wide_trial_params

    assert 0.65 < nearest_lane_m() < 0.7  # ring 0.35 m + 0.26 m of ring-down + 5 cm
    orders = set()
    for seed in range(200):
        p = wide_trial_params(seed)
        assert p == wide_trial_params(seed)
        assert 1.45 <= p["wall_y"] <= 4.0 and 1 <= p["miss_limit"] <= 3 and 1.0 <= p["spurious_rate_hz"] <= 50.0
        assert nearest_lane_m() + p["person_radius"] < p["person_y"] < p["wall_y"] - p["person_radius"]
        assert abs(p["person_speed"]) <= 2.5 and 0.0 <= p["robot_speed"] <= 2.0
        orders.add(p["order"])
    assert orders == set(range(1, 9))


def test_gated_echoes_are_flagged_and_never_samples():
    """A rejected first echo carries the gated bit (event bit 45) and is neither a tracking
    sample nor a geometry input: seed 12 with the default gate flags some."""
    r = run_trial(12)
    assert r.gated > 0 and r.samples > 0
    from multisonar.safety import run_false_fix_trial
    f = run_false_fix_trial(12, spurious_rate_hz=20.0)
    assert f.gated > 0 and f.gated_false + f.gated_alias > 0
