"""Safety property of fast firing under randomised person-crossing scenes (issue #9).

DESIGN.md section 1: a virtual sensor tracking a wall listens only inside predicted windows;
K empty windows in a row send it back to an initialisation ping with an open window. The
safety property: **a person who steps between the robot and the tracked wall is reported**,
and soon. This module states that as a measurable trial on the golden model
(:class:`~multisonar.fastfiring.FastFiringModel`, tick-identical to the RTL scheduler by the
scoreboards of ``tests/rtl/test_ms_scheduler.py``) with the acoustic model in the loop:

* the scene is ``person_crossing`` with randomised geometry and speeds (wall distance, the
  person's lane, radius, speed and direction, robot speed), noise as the scene states
  (spurious pulses, jitter, fading) or raised with ``spurious_rate_hz``;
* the sensor is the left-facing one (transmitter 6, receivers 5, 6, 7), order and K random
  among what the validator accepts for the wall distance;
* **onset** = the first pulse of the sensor whose ground truth (:meth:`AcousticModel.truth`,
  exact paths, before fading) has the person's echo on the transmitting element above the
  comparator threshold by ``margin_db`` and earlier than the wall's: from then on the person
  blocks the tracked window or precedes it;
* **detected** = the first event of the sensor, on any of its receivers, whose time of flight
  is the person's (within ``tol_ticks`` of the truth of its own pulse); its pulse counts;
* **latency** in pulses of the sensor between the onset pulse and the detecting pulse. The
  bound the design promises: the pulses already in flight at the onset (order N, each with a
  window that the person now blocks), K empty windows, one initialisation ping:
  ``latency_pulses <= N + K + 1``; a trial passes when the person is detected within it.

A trial where the person never reaches the onset condition (e.g. too small an echo on that
lane) is reported as ``no_onset`` and not counted either way; the run is long enough for the
person to cross the whole beam.
"""

from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import yaml

from .constants import DEVICE_DECISION_LEAD, TICK_HZ
from .fastfiring import DEFAULT_MISS_GATE, FastFiringModel, SceneEchoSource
from .layout import load_layout
from .schedule import Schedule, ScheduleError, VirtualSensor
from .scene import parse_scene

__all__ = ["TrialResult", "run_trial", "random_trial_params", "summarise"]

_SCENE_FILE = Path(__file__).resolve().parents[2] / "sim" / "scenes" / "person_crossing.yaml"
TX, RX = 6, (5, 6, 7)  # element 6 faces +y (the wall side) on ring24


@dataclass(frozen=True)
class TrialResult:
    seed: int
    wall_y: float
    person_y: float
    person_radius: float
    person_speed: float  # signed, m/s along x
    robot_speed: float
    order: int
    miss_limit: int
    spurious_rate_hz: float
    pulses: int
    init_pings: int
    in_front_pulse: int  # first tracking pulse with the person in front of the wall on a receiver
    front_latency_pulses: int  # from in_front_pulse to the person's report (-1: never)
    onset_pulse: int  # first tracking pulse with the wall hidden by the person on a receiver
    detect_pulse: int  # -1: not detected
    latency_pulses: int  # -1 when no onset or not detected
    latency_ms: float
    bound_pulses: int  # order + miss_limit + 1
    samples: int  # first echoes in tracked windows
    alias_samples: int  # first echoes that are another pulse's echo (interlacing)
    false_samples: int  # first echoes that match no true echo path (spurious, crosstalk)
    outcome: str  # "detected", "late", "missed", "no_onset"

    @property
    def ok(self) -> bool:
        return self.outcome in ("detected", "no_onset")


def random_trial_params(seed: int) -> dict[str, Any]:
    """Scene and sensor parameters of trial ``seed`` (a pure function of the seed)."""
    rng = np.random.default_rng(seed)
    wall_y = float(rng.uniform(1.3, 2.5))
    radius = float(rng.uniform(0.15, 0.3))
    lo, hi = 0.35 + radius + 0.2, wall_y - radius - 0.15  # ring radius 0.35 m; lo < hi on this domain
    person_y = float(rng.uniform(lo, hi))
    robot = float(rng.uniform(0.3, 2.0))
    # relative speed person - robot along x: at least 1.5 m/s so the person starts outside the
    # beam; either sign (oncoming, or overtaking from behind); a person walks at most 2.2 m/s
    rel = float(rng.uniform(1.5, 3.0)) * (1 if rng.random() < 0.5 else -1)
    speed = float(np.clip(robot + rel, -2.2, 2.2))
    return dict(seed=seed, wall_y=wall_y, person_y=person_y, person_radius=radius, person_speed=speed,
                robot_speed=robot, order=int(rng.integers(1, 4)),
                miss_limit=int(rng.integers(1, 4)))


def _scene(p: dict[str, Any], t_cross: float, duration: float, spurious_rate_hz: float | None):
    doc = yaml.safe_load(_SCENE_FILE.read_text())
    doc = copy.deepcopy(doc)
    vr, vp = p["robot_speed"], p["person_speed"]
    # person x(t) = x0 + vp t crosses the robot x(t) = vr t at t_cross
    x0 = (vr - vp) * t_cross
    x_end = x0 + vp * (duration + 1.0)
    doc["parameters"].update(wall_y=p["wall_y"], robot_speed=vr, person_y=p["person_y"], person_speed=abs(vp))
    doc["trajectory"] = [{"t": 0, "x": 0, "y": 0, "heading_deg": 0},
                         {"speed": "robot_speed", "x": vr * (duration + 1.0), "y": 0}]
    doc["walls"] = [{"name": "wall", "a": [-5.0, "wall_y"], "b": [12.0, "wall_y"]}]
    doc["people"][0].update(radius=p["person_radius"],
                            path=[{"t": 0, "x": x0, "y": "person_y"}, {"speed": "person_speed", "x": x_end, "y": "person_y"}])
    doc["duration_s"] = duration + 1.0
    doc["seed"] = int(p["seed"])
    if spurious_rate_hz is not None:
        doc.setdefault("noise", {})["spurious_rate_hz"] = float(spurious_rate_hz)
    return parse_scene(doc, source=f"<person trial {p['seed']}>")


def _schedule(layout, order: int, miss_limit: int, wall_y: float) -> Schedule:
    """The left sensor at the highest order <= ``order`` that validates for this wall."""
    last: Exception | None = None
    for n in range(order, 0, -1):
        s = Schedule(layout, [VirtualSensor("left", tx=[TX], rx=list(RX), order=n, miss_limit=miss_limit,
                                            nominal_range_m=wall_y - 0.35)])
        try:
            s.validate()
            return s
        except ScheduleError as e:
            last = e
    raise ValueError(f"no order schedules a wall at {wall_y:.2f} m: {last}")


def run_trial(seed: int, *, spurious_rate_hz: float | None = None, t_cross: float = 0.8,
              duration: float = 1.6, margin_db: float = 6.0, tol_ticks: int = 600,
              params: dict[str, Any] | None = None, miss_gate: int | None = DEFAULT_MISS_GATE,
              reinit_every: int | None = None) -> TrialResult:
    """One randomised person-crossing trial (see the module docstring). ``miss_gate``: the
    gated miss rule, ticks (RX_FILTER.miss_gate; default its reset value, 0 or None = off);
    ``reinit_every``: the golden model's experimental forced re-initialisation (not in the RTL)."""
    p = dict(params) if params is not None else random_trial_params(seed)
    layout = load_layout()
    scene = _scene(p, t_cross, duration, spurious_rate_hz)
    sched = _schedule(layout, p["order"], p["miss_limit"], p["wall_y"])
    order = sched.sensors[0].order
    src = SceneEchoSource(scene, rng=np.random.default_rng(p["seed"]))
    model = FastFiringModel(sched, src, decision_lead=DEVICE_DECISION_LEAD, miss_gate=miss_gate,
                            reinit_every=reinit_every)
    res = model.run(int(duration * TICK_HZ))
    pulses = [q for q in res.pulses if q.sensor == 0]
    ac = src.model
    person = scene.reflector_index("person")
    wall = scene.reflector_index("wall")
    thr = scene.noise.threshold * 10 ** (margin_db / 20)

    # ground truth per pulse: exact first-order arrivals (absolute ticks) and amplitudes per
    # (reflector, receiver), before jitter and fading
    from .acoustics import Firing, PulseKind
    truth: list[dict[tuple[int, int], tuple[float, float]]] = []
    for q in pulses:
        d: dict[tuple[int, int], tuple[float, float]] = {}
        for row in ac.truth(Firing.single(q.t0 / TICK_HZ, TX)):
            key = (int(row["source"]), int(row["rx"]))
            at = float(row["arrival"]) * TICK_HZ
            if row["kind"] == PulseKind.ECHO and at < d.get(key, (math.inf, 0.0))[0]:
                d[key] = (at, float(row["amplitude"]))
        truth.append(d)

    def blocks(i: int) -> tuple[bool, bool]:
        """(person in front of the wall on some receiver, person hides the wall on some receiver)"""
        front = hide = False
        for rx in RX:
            pa = truth[i].get((person, rx))
            if pa is None or pa[1] < thr:
                continue
            wa = truth[i].get((wall, rx))
            if wa is None or wa[1] < scene.noise.threshold:
                hide = True
            elif pa[0] < wa[0]:
                front = True
        return front or hide, hide

    first_track = next((i for i, q in enumerate(pulses) if not q.init), len(pulses))
    onset = next((i for i in range(first_track, len(pulses)) if blocks(i)[1]), -1)
    in_front = next((i for i in range(first_track, len(pulses)) if blocks(i)[0]), -1)

    by_seq: dict[int, int] = {}
    pi = 0
    detect = detect_front = -1
    samples = false_samples = alias_samples = 0
    for e in sorted((e for e in res.events if e.sensor == 0), key=lambda e: e.tick):
        while pi < len(pulses) and pulses[pi].t0 <= e.tick:
            by_seq[pulses[pi].seq % 256] = pi
            pi += 1
        k = by_seq.get(e.seq)
        if k is None or not e.first_echo:
            continue
        edge = pulses[k].t0 + e.tof

        def near(i: int, src_i: int | None = None) -> bool:
            return any(abs(edge - a) <= tol_ticks for (s_i, rx), (a, _) in truth[i].items()
                       if rx == e.rx and (src_i is None or s_i == src_i))
        if not e.init_ping:
            samples += 1
            if not near(k):
                if any(near(i) for i in range(max(0, k - 4), min(len(pulses), k + 2)) if i != k):
                    alias_samples += 1  # an echo of another pulse in flight (interlacing)
                else:
                    false_samples += 1  # spurious pulse or crosstalk
        if near(k, person):
            if detect < 0 and 0 <= onset <= k:
                detect = k
            if detect_front < 0 and 0 <= in_front <= k:
                detect_front = k
    bound = order + p["miss_limit"] + 1
    if onset < 0:
        outcome, lat, lat_ms = "no_onset", -1, float("nan")
    elif detect < 0:
        outcome, lat, lat_ms = "missed", -1, float("nan")
    else:
        lat = detect - onset
        lat_ms = (pulses[detect].t0 - pulses[onset].t0) / TICK_HZ * 1e3
        outcome = "detected" if lat <= bound else "late"
    return TrialResult(seed=seed, wall_y=p["wall_y"], person_y=p["person_y"], person_radius=p["person_radius"],
                       person_speed=p["person_speed"], robot_speed=p["robot_speed"], order=order,
                       miss_limit=p["miss_limit"], spurious_rate_hz=float(scene.noise.spurious_rate_hz),
                       pulses=len(pulses), init_pings=sum(q.init for q in pulses), in_front_pulse=in_front,
                       front_latency_pulses=(detect_front - in_front) if detect_front >= 0 else -1, onset_pulse=onset,
                       detect_pulse=detect, latency_pulses=lat, latency_ms=lat_ms, bound_pulses=bound,
                       samples=samples, alias_samples=alias_samples, false_samples=false_samples, outcome=outcome)


def summarise(results: Iterable[TrialResult]) -> dict[str, Any]:
    rs = list(results)
    counted = [r for r in rs if r.outcome != "no_onset"]
    lat = np.array([r.latency_pulses for r in counted if r.latency_pulses >= 0])
    lat_ms = np.array([r.latency_ms for r in counted if r.latency_pulses >= 0])
    samples = sum(r.samples for r in rs)
    return dict(trials=len(rs), counted=len(counted), detected=sum(r.outcome == "detected" for r in rs),
                late=sum(r.outcome == "late" for r in rs), missed=sum(r.outcome == "missed" for r in rs),
                no_onset=sum(r.outcome == "no_onset" for r in rs),
                latency_pulses_max=int(lat.max()) if lat.size else -1,
                latency_pulses_median=float(np.median(lat)) if lat.size else float("nan"),
                latency_ms_max=float(lat_ms.max()) if lat_ms.size else float("nan"),
                latency_ms_median=float(np.median(lat_ms)) if lat_ms.size else float("nan"),
                samples=samples, alias_samples=sum(r.alias_samples for r in rs),
                false_samples=sum(r.false_samples for r in rs),
                false_sample_rate=(sum(r.false_samples for r in rs) / samples) if samples else 0.0)


def as_rows(results: Iterable[TrialResult]) -> list[dict[str, Any]]:
    return [asdict(r) | {"ok": r.ok} for r in results]
