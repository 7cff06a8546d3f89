"""The scheduler's whole microcode program (sched_program.mainloop) on the engine's model with
the sonar core's hardware around it (sched_program.system.EngineSystem), against the golden
model: every event word in order and every trigger, on noisy scenes with shared elements,
motion, occlusion steps, K-miss cancels, forced re-initialisation and an acoustic scene; and
the timing contract (lateness against P / 2) reported, not assumed."""

from __future__ import annotations

import pytest

from multisonar.fastfiring import (DEFAULT_GLITCH_MIN, DEFAULT_MISS_GATE, FastFiringModel,
                                   SceneEchoSource, SyntheticEchoSource)
from multisonar.layout import load_layout
from multisonar.schedule import Schedule, VirtualSensor
from multisonar.tools.sched_program.system import EngineSystem

MS = 48_000


def ring8(rx_width: int, max_range_m: float) -> list[VirtualSensor]:
    """tb_bench_lag.py's ring: eight sensors, tx 0, 3, .., 21, rx_width receivers each."""
    lo = rx_width // 2
    return [VirtualSensor(f"s{k}", tx=[3 * k], rx=sorted({(3 * k + i) % 24 for i in range(-lo, rx_width - lo)}),
                          order=4, max_range_m=max_range_m) for k in range(8)]


def shared3() -> list[VirtualSensor]:
    return [VirtualSensor("a", tx=[0], rx=[23, 0, 1], order=2),
            VirtualSensor("b", tx=[1], rx=[0, 1, 2], order=3, miss_limit=2),
            VirtualSensor("c", tx=[12, 13], rx=[11, 12, 13, 14], order=4, reinit_every=9)]


def demo() -> list[VirtualSensor]:
    from multisonar.demo import demo_sensors
    return demo_sensors("demo")


def corridor():
    from multisonar.scene import load_scene
    return SceneEchoSource(load_scene("corridor"))


SCENES = {
    # shared elements, a moving reflector, an occluding step, 100 spurious pulses/s/channel,
    # K = 2 misses cancel, reinit_every 9
    "shared3": (shared3, lambda: SyntheticEchoSource(
        {23: 1.0, 0: 0.9, 1: 1.1, 2: 1.3, 11: 2.0, 12: 2.1, 13: 2.2, 14: 2.0}, velocity_mps=1.5,
        spurious_rate_hz=100, seed=5, step_tick=80 * MS, step_ranges_m={0: 0.5, 1: 0.6, 12: 1.0}), 32768, 120),
    # eight init pings in one tick, noisy
    "burst8": (lambda: ring8(3, 4.5), lambda: SyntheticEchoSource(1.2, spurious_rate_hz=20.0, seed=1), 32768, 60),
    # every sensor on all 24 receivers loses its target: K-miss cancels everywhere
    "safety_rx24": (lambda: ring8(24, 3.0), lambda: SyntheticEchoSource(
        2.5, step_tick=60 * MS, step_ranges_m={}, occlude=True), 32768, 300),
    # the demo's sensors on the acoustic corridor scene (its noise model included)
    "corridor": (demo, corridor, 32768, 40),
}


def run_both(name: str, lead: int | None = None):
    sensors, source, default_lead, ms = SCENES[name]
    lead = default_lead if lead is None else lead
    sched = Schedule(load_layout(), sensors())
    model = FastFiringModel(sched, source(), decision_lead=lead)
    res = model.run(ms * MS)
    eng = EngineSystem(sched, source(), decision_lead=lead, glitch_min=DEFAULT_GLITCH_MIN,
                       miss_gate=DEFAULT_MISS_GATE).run(ms * MS)
    return res, eng


@pytest.mark.parametrize("name", sorted(SCENES))
def test_the_program_equals_the_golden_model(name):
    res, eng = run_both(name)
    assert len(res.pulses) >= 6, "the scene must exercise the scheduler"
    first = next((i for i, (a, b) in enumerate(zip(res.words, eng.words)) if a != b), None)
    assert first is None and len(eng.words) == len(res.words), (
        f"{name}: event words differ from word {first} (model {len(res.words)}, engine {len(eng.words)})")
    assert eng.triggers == sorted((t.tick, t.element) for t in res.triggers)
    assert eng.lag_ticks > 0 and not eng.late, eng.late[:3]


def test_the_scenes_cover_the_rules():
    """The scenes above exercise what they claim: cancels, re-initialisation, gated echoes."""
    res, _ = run_both("shared3")
    assert res.cancelled and any(p.init for p in res.pulses[3:]) and any(not p.init for p in res.pulses)
    assert any(e.window_empty for e in res.events) and any(e.first_echo for e in res.events)


def test_a_lead_too_short_for_the_engine_is_reported():
    """Eight decisions in one tick take the engine longer than P / 2 = 2048 ticks: the run
    says so (the hardware raises overrun) instead of passing silently."""
    _, eng = run_both("burst8", lead=4096)
    assert any("late" in x for x in eng.late) and eng.lag_max >= 2048
