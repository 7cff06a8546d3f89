"""Loads for the whole program (tests/test_sched_mainloop.py, scripts/bench_sched_mainloop.py):
each a schedule, an echo source factory (a fresh, identically seeded source per run) and how
long it runs; ``run_scenario`` runs one on the golden model and on EngineSystem. The ring
(``ring8``) is also the RTL lag bench's (tests/rtl/tb_bench_lag.py)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from ...fastfiring import SceneEchoSource, SyntheticEchoSource
from ...schedule import VirtualSensor

MS = 48_000


@dataclass(frozen=True)
class Scenario:
    sensors: Callable[[], list[VirtualSensor]]
    source: Callable[[], Any]
    ms: int
    what: str


def ring8(rx_width: int, order: int = 4, max_range_m: float = 4.5) -> list[VirtualSensor]:
    """Eight sensors, tx 0, 3, .., 21, each receiving on rx_width elements centred on its tx."""
    lo = rx_width // 2
    return [VirtualSensor(f"s{k}", tx=[3 * k], rx=sorted({(3 * k + i) % 24 for i in range(-lo, rx_width - lo)}),
                          order=order, max_range_m=max_range_m) for k in range(8)]


def shared3() -> list[VirtualSensor]:
    return [VirtualSensor("a", tx=[0], rx=[23, 0, 1], order=2),
            VirtualSensor("b", tx=[1], rx=[0, 1, 2], order=3, miss_limit=2),
            VirtualSensor("c", tx=[12, 13], rx=[11, 12, 13, 14], order=4, reinit_every=9)]


def _demo() -> list[VirtualSensor]:
    from ...demo import demo_sensors
    return demo_sensors("demo")


def _corridor() -> Any:
    from ...scene import load_scene
    return SceneEchoSource(load_scene("corridor"))


SCENARIOS: dict[str, Scenario] = {
    "shared3": Scenario(shared3, lambda: SyntheticEchoSource(
        {23: 1.0, 0: 0.9, 1: 1.1, 2: 1.3, 11: 2.0, 12: 2.1, 13: 2.2, 14: 2.0}, velocity_mps=1.5,
        spurious_rate_hz=100, seed=5, step_tick=80 * MS, step_ranges_m={0: 0.5, 1: 0.6, 12: 1.0}), 120,
        "shared elements, moving reflector, occluding step, 100 spurious/s, K = 2, reinit_every 9"),
    "burst8": Scenario(lambda: ring8(3), lambda: SyntheticEchoSource(1.2, spurious_rate_hz=20.0, seed=1), 60,
                       "eight init pings in one tick, 20 spurious/s"),
    "slots_rx24_3m": Scenario(lambda: ring8(24, max_range_m=3.3), lambda: SyntheticEchoSource(3.0), 400,
                              "eight sensors on all 24 receivers tracking at 3 m: full window slots"),
    "echoes_rx24": Scenario(lambda: ring8(24, max_range_m=3.3), lambda: SyntheticEchoSource(
        {r: [1.5, 2.2, 3.0] for r in range(24)}, spurious_rate_hz=20.0, seed=2), 400,
        "three echoes per receiver on all 24, 20 spurious/s"),
    "safety_rx24": Scenario(lambda: ring8(24, max_range_m=3.0), lambda: SyntheticEchoSource(
        2.5, step_tick=60 * MS, step_ranges_m={}, occlude=True), 400,
        "every sensor loses its target: K-miss cancels on all 24 receivers"),
    "corridor": Scenario(_demo, _corridor, 40, "the demo's sensors on the acoustic corridor scene"),
}


def run_scenario(name: str, lead: int, ms: int | None = None) -> tuple[Any, Any]:
    """Scenario ``name`` for ``ms`` milliseconds (default its own) at decision lead ``lead`` on
    the golden model and on the whole program (EngineSystem), each with its own source: the
    model's RunResult and the program's EngineRun."""
    from ...fastfiring import DEFAULT_GLITCH_MIN, DEFAULT_MISS_GATE, FastFiringModel
    from ...layout import load_layout
    from ...schedule import Schedule
    from .system import EngineSystem

    sc = SCENARIOS[name]
    ticks = (sc.ms if ms is None else ms) * MS
    sched = Schedule(load_layout(), sc.sensors())
    res = FastFiringModel(sched, sc.source(), decision_lead=lead).run(ticks)
    eng = EngineSystem(sched, sc.source(), decision_lead=lead, glitch_min=DEFAULT_GLITCH_MIN,
                       miss_gate=DEFAULT_MISS_GATE).run(ticks)
    return res, eng
