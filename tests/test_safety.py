"""Safety property of fast firing on the golden model (issue #9; multisonar.safety).

A person stepping between the robot and a tracked wall must be reported within the bound the
design promises: the N pulses in flight, K empty windows, one initialisation ping. The
randomised version of the property (scripts/bench_safety.py, 200 seeds) does not hold yet:
echoes of neighbouring pulses (interlacing aliases) land in the tracked windows and reset the
K-miss counter (see the xfail below and the script's table)."""

from __future__ import annotations

import pytest

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


@pytest.mark.xfail(strict=True, reason=(
    "known hazard (issue #9): with interlaced pulses an echo of a neighbouring pulse from the "
    "person lands in the tracked window, counts as a sample and resets the K-miss counter, so "
    "some crossings are reported late or not at all (scripts/bench_safety.py: 148/200 within the "
    "bound, max 87 pulses / 713 ms; with the model's 50 us gated miss rule 192/200, max 13 pulses). "
    "Needs the gated miss rule (and/or a forced re-init every M pulses) in model + RTL."))
def test_randomised_person_crossings_all_reported_within_the_bound():
    results = [run_trial(seed) for seed in range(4)]
    s = summarise(results)
    assert s["counted"] >= 3
    assert s["detected"] == s["counted"], f"late {s['late']}, missed {s['missed']} of {s['counted']}"


def test_gated_miss_rule_model_option_removes_an_alias_delay():
    """Seed 12 (order 2, K 3): an echo of the neighbouring pulse keeps the lost wall track alive
    (late) with the RTL's rule; the model's experimental gated miss rule (a sample > 50 us from
    the prediction counts as a miss) reports the person within the bound."""
    rtl_rule = run_trial(12)
    gated = run_trial(12, miss_gate=2400)
    assert rtl_rule.outcome == "late" and rtl_rule.alias_samples > 0
    assert gated.outcome == "detected", gated
    assert gated.latency_pulses < rtl_rule.latency_pulses


def test_model_safety_options_are_validated():
    from multisonar.fastfiring import FastFiringModel, SyntheticEchoSource
    from multisonar.layout import load_layout
    from multisonar.schedule import Schedule, VirtualSensor
    sched = Schedule(load_layout(), [VirtualSensor("s", tx=[0], rx=[0])])
    with pytest.raises(ValueError, match="miss_gate"):
        FastFiringModel(sched, SyntheticEchoSource({0: 1.0}), miss_gate=-1)
    with pytest.raises(ValueError, match="reinit_every"):
        FastFiringModel(sched, SyntheticEchoSource({0: 1.0}), reinit_every=0)
