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
* **tracking sample rate**: tracking samples (first echoes in tracking windows, all receivers)
  that are the true echo of their own pulse, per second of sonar time; ``pre_onset_*`` counts
  only pulses before the onset (plain wall tracking), the cost measure of ``reinit_every``
  (the sensor's forced re-initialisation every M tracking pulses, ``VirtualSensor(reinit_every=M)``
  = the RTL's MODE.reinit_every; by
  construction it bounds the latency by M pulses, so M <= N + K + 1 guarantees the bound;
  ``reinit_every="bound"`` uses M = N + K + 1 of the trial).

A trial where the person never reaches the onset condition (e.g. too small an echo on that
lane) is reported as ``no_onset`` and not counted either way; the run is long enough for the
person to cross the whole beam.
"""

from __future__ import annotations

import copy
import functools
import math
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, Iterable, Literal

import numpy as np
import yaml

from .constants import DEVICE_DECISION_LEAD, TICK_HZ, speed_of_sound
from .fastfiring import DEFAULT_MISS_GATE, DEFAULT_MISS_HOLD, FastFiringModel, SceneEchoSource
from .layout import load_layout
from .schedule import Schedule, ScheduleError, VirtualSensor
from .scene import parse_scene

__all__ = ["TrialResult", "run_trial", "random_trial_params", "wide_trial_params", "nearest_lane_m", "summarise",
           "as_rows", "FalseFixResult", "run_false_fix_trial", "summarise_false_fixes", "FALSE_FIX_TOL_M"]

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
    samples: int  # first echoes in tracked windows that the gated miss rule accepted
    alias_samples: int  # ... that are another pulse's echo (interlacing)
    false_samples: int  # ... that match no true echo path (spurious, crosstalk)
    outcome: str  # "detected", "late", "missed", "no_onset"
    duration_s: float = 0.0  # sonar time simulated
    reinit_every: int = 0  # model option used (0: none)
    pre_onset_s: float = 0.0  # sonar time from the first pulse to the onset pulse (whole run without onset)
    pre_onset_samples: int = 0  # true tracking samples of pulses before the onset pulse
    gated: int = 0  # first echoes in tracked windows that the gated miss rule rejected (flagged gated)
    fixes: int = 0  # edge / wall fixes of the sensor's pulses, as the firmware makes them (run_false_fix_trial)
    false_fixes: int = 0  # ... farther than FALSE_FIX_TOL_M from every true surface

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


@functools.cache
def nearest_lane_m() -> float:
    """Smallest distance from the ring's centre to the person's near surface the wide generator
    draws: the transmitter's distance from the centre, the sensor's minimum range (its window
    opens after the ring-down T_dead: c T_dead / 2 = 0.26 m; nothing nearer is heard by any rule)
    and 5 cm so that the echo is not at the window's first tick."""
    layout = load_layout()
    return float(np.hypot(*layout.positions[TX])) + layout.transducer.ring_down_s * speed_of_sound() / 2 + 0.05


def wide_trial_params(seed: int) -> dict[str, Any]:
    """Trial ``seed`` of the wide generator (issue #28; a pure function of the seed): wall at
    1.45-4.0 m, person radius 0.15-0.3 m on a lane between the sensor's minimum range
    (:func:`nearest_lane_m`) and the wall, robot 0-2 m/s, the person 1.5-3 m/s faster or slower
    than the robot (at most 2.5 m/s either way), order 1-8 (the highest that schedules the wall
    is taken), K 1-3, spurious pulses log-uniform 1-50 per second and channel. Other seeds than
    :func:`random_trial_params` draws, same keys plus ``spurious_rate_hz``."""
    rng = np.random.default_rng([28, seed])
    wall_y = float(rng.uniform(1.45, 4.0))  # >= 1.45 m: room for a lane beyond the minimum range
    radius = float(rng.uniform(0.15, 0.3))
    lo, hi = nearest_lane_m() + radius, wall_y - radius - 0.15
    person_y = float(rng.uniform(lo, hi))
    robot = float(rng.uniform(0.0, 2.0))
    rel = float(rng.uniform(1.5, 3.0)) * (1 if rng.random() < 0.5 else -1)
    speed = float(np.clip(robot + rel, -2.5, 2.5))
    return dict(seed=seed, wall_y=wall_y, person_y=person_y, person_radius=radius, person_speed=speed,
                robot_speed=robot, order=int(rng.integers(1, 9)), miss_limit=int(rng.integers(1, 4)),
                spurious_rate_hz=float(np.exp(rng.uniform(0.0, math.log(50.0)))))


def _scene(p: dict[str, Any], t_cross: float, duration: float, spurious_rate_hz: float | None,
           crosstalk_level: float | None = None, person: bool = True):
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
    if crosstalk_level is not None:
        doc.setdefault("model", {})["crosstalk_level"] = float(crosstalk_level)
    if not person:
        doc["people"] = []
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


def _truth(ac: Any, pulses: list[Any]) -> list[dict[tuple[int, int], tuple[float, float]]]:
    """Ground truth per pulse: exact first-order arrivals (absolute ticks) and amplitudes per
    (reflector, receiver), before jitter and fading."""
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
    return truth


def run_trial(seed: int, *, spurious_rate_hz: float | None = None, t_cross: float = 0.8,
              duration: float = 1.6, margin_db: float = 6.0, tol_ticks: int = 600,
              params: dict[str, Any] | None = None, miss_gate: int | None = DEFAULT_MISS_GATE,
              reinit_every: int | Literal["bound"] | None = None,
              decision_lead: int = DEVICE_DECISION_LEAD, miss_hold: bool = DEFAULT_MISS_HOLD) -> TrialResult:
    """One randomised person-crossing trial (see the module docstring). ``miss_gate``: the
    gated miss rule, ticks (RX_FILTER.miss_gate; default its reset value, 0 or None = off);
    ``reinit_every``: the sensor's forced re-initialisation after that many tracking pulses
    (``VirtualSensor.reinit_every``, MODE.reinit_every in the RTL; ``"bound"``: N + K + 1 of
    this trial); ``decision_lead``: the scheduler's lead P, ticks (default the device's);
    ``miss_hold``: RX_FILTER.miss_hold (default its reset value, on)."""
    p = dict(params) if params is not None else random_trial_params(seed)
    if spurious_rate_hz is None:
        spurious_rate_hz = p.get("spurious_rate_hz")
    layout = load_layout()
    scene = _scene(p, t_cross, duration, spurious_rate_hz)
    sched = _schedule(layout, p["order"], p["miss_limit"], p["wall_y"])
    order = sched.sensors[0].order
    reinit = order + p["miss_limit"] + 1 if reinit_every == "bound" else reinit_every
    if reinit:  # as a user configures it: on the sensor (the device's MODE.reinit_every)
        sched = Schedule(layout, [replace(sched.sensors[0], reinit_every=int(reinit))])
    src = SceneEchoSource(scene, rng=np.random.default_rng(p["seed"]))
    model = FastFiringModel(sched, src, decision_lead=decision_lead, miss_gate=miss_gate, miss_hold=miss_hold)
    res = model.run(int(duration * TICK_HZ))
    pulses = [q for q in res.pulses if q.sensor == 0]
    ac = src.model
    person = scene.reflector_index("person")
    wall = scene.reflector_index("wall")
    thr = scene.noise.threshold * 10 ** (margin_db / 20)

    truth = _truth(ac, pulses)

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
    samples = false_samples = alias_samples = pre_onset_samples = gated = 0
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
        if e.gated:
            gated += 1
        elif not e.init_ping:
            samples += 1
            if not near(k):
                if any(near(i) for i in range(max(0, k - 4), min(len(pulses), k + 2)) if i != k):
                    alias_samples += 1  # an echo of another pulse in flight (interlacing)
                else:
                    false_samples += 1  # spurious pulse or crosstalk
            elif onset < 0 or k < onset:
                pre_onset_samples += 1
        if near(k, person):
            if detect < 0 and 0 <= onset <= k:
                detect = k
            if detect_front < 0 and 0 <= in_front <= k:
                detect_front = k
    bound = order + p["miss_limit"] + 1
    fx = _fix_stats(scene, layout, pulses, truth, res.events, tol_ticks, FALSE_FIX_TOL_M)
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
                       samples=samples, alias_samples=alias_samples, false_samples=false_samples, outcome=outcome,
                       duration_s=duration, reinit_every=int(reinit or 0),
                       pre_onset_s=((pulses[onset].t0 if onset >= 0 else int(duration * TICK_HZ)) - pulses[0].t0) / TICK_HZ
                       if pulses else 0.0, pre_onset_samples=pre_onset_samples, gated=gated,
                       fixes=fx["fixes"], false_fixes=fx["false_fixes"])


def summarise(results: Iterable[TrialResult]) -> dict[str, Any]:
    rs = list(results)
    counted = [r for r in rs if r.outcome != "no_onset"]
    lat = np.array([r.latency_pulses for r in counted if r.latency_pulses >= 0])
    lat_ms = np.array([r.latency_ms for r in counted if r.latency_pulses >= 0])
    samples = sum(r.samples for r in rs)
    true_samples = samples - sum(r.alias_samples + r.false_samples for r in rs)
    sonar_s, pre_s = sum(r.duration_s for r in rs), sum(r.pre_onset_s for r in rs)
    return dict(trials=len(rs), counted=len(counted), detected=sum(r.outcome == "detected" for r in rs),
                late=sum(r.outcome == "late" for r in rs), missed=sum(r.outcome == "missed" for r in rs),
                no_onset=sum(r.outcome == "no_onset" for r in rs),
                latency_pulses_max=int(lat.max()) if lat.size else -1,
                latency_pulses_median=float(np.median(lat)) if lat.size else float("nan"),
                latency_ms_max=float(lat_ms.max()) if lat_ms.size else float("nan"),
                latency_ms_median=float(np.median(lat_ms)) if lat_ms.size else float("nan"),
                samples=samples, alias_samples=sum(r.alias_samples for r in rs),
                false_samples=sum(r.false_samples for r in rs), gated=sum(r.gated for r in rs),
                false_sample_rate=(sum(r.false_samples for r in rs) / samples) if samples else 0.0,
                init_pings=sum(r.init_pings for r in rs), fixes=sum(r.fixes for r in rs),
                false_fixes=sum(r.false_fixes for r in rs),
                samples_per_s=true_samples / sonar_s if sonar_s else float("nan"),
                pre_onset_samples_per_s=sum(r.pre_onset_samples for r in rs) / pre_s if pre_s else float("nan"))


def as_rows(results: Iterable[TrialResult]) -> list[dict[str, Any]]:
    return [asdict(r) | {"ok": r.ok} for r in results]


# ----------------------------------------------------------------------------------------
# false fixes under spurious pulses and crosstalk (issue #9, scripts/bench_false_fix.py)
# ----------------------------------------------------------------------------------------

#: A fix farther than this from every true reflector surface is false (m).
FALSE_FIX_TOL_M = 0.05


@dataclass(frozen=True)
class FalseFixResult:
    seed: int
    order: int
    spurious_rate_hz: float
    crosstalk_level: float
    person: bool
    duration_s: float
    pulses: int
    samples: int  # first echoes (not gated) in any window of the sensor (init and tracking), all receivers
    alias_samples: int  # ... that are another pulse's echo (interlacing)
    false_samples: int  # ... that match no true echo path (spurious pulse, crosstalk)
    gated: int  # first in-window echoes flagged gated (rejected by the gated miss rule; no geometry input)
    gated_false: int  # ... that match no true echo path
    gated_alias: int  # ... that are another pulse's echo
    fixes: int  # pulses with a first echo on every receiver giving an edge or wall fix
    false_fixes: int  # fixes farther than tol_m from every true reflector surface
    false_fixes_spurious: int  # ... with a false sample among their echoes
    false_fixes_alias: int  # ... with an alias sample (and no false one)
    max_fix_error_m: float  # largest distance of a fix from the truth
    uncertain_points: int  # records classed uncertain that still carry a position (not fixes)
    false_uncertain_points: int  # ... farther than tol_m from every true surface


def _fix_points(rx: list[int], paths: np.ndarray, source: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pulse (rows of ``paths``), as the firmware's geometry record (``firmware/app/sonar/geo.c``
    send_frame): the reported point (robot frame: the wall foot for a valid wall, else the
    point fit's position), whether the record has one, and whether it is a **fix** (class edge
    with a valid point fit, or wall with a valid wall fit). The firmware has no cylinder class
    (Python's 'cylinder' is its 'uncertain'); an uncertain record still carries the point
    fit's position, with quality 0."""
    from . import geometry as G
    C = load_layout().positions[rx]
    with np.errstate(all="ignore"):
        kind = G.classify_batch(C, paths, source).kind
        pb = G.solve_point_batch(C, paths, source, tol=np.inf, max_gdop=np.inf)
        wb = G.solve_wall_batch(C, paths, source, tol=np.inf, max_gdop=np.inf)
    wall = (kind == 1) & wb.valid
    pts = np.where(wall[:, None], wb.foot, pb.position)
    has = (wall | pb.valid) & np.all(np.isfinite(pts), axis=1)
    return pts, has, has & (wall | (kind == 0))


def _surface_distance(scene: Any, t: float, p: np.ndarray) -> float:
    """World point ``p`` to the nearest true reflector surface at scene time ``t``."""
    d = [math.inf]
    if len(scene.walls):
        a, b = scene.walls[:, 0], scene.walls[:, 1]
        ab = b - a
        u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
        d.append(float(np.min(np.linalg.norm(a + u[:, None] * ab - p, axis=1))))
    if len(scene.points):
        d.append(float(np.min(np.linalg.norm(scene.points - p, axis=1))))
    if len(scene.cylinders):
        d.append(float(np.min(np.abs(np.linalg.norm(scene.cylinders - p, axis=1) - scene.cylinder_radius))))
    if scene.people:
        c = scene.people_positions(t)
        r = np.array([q.radius for q in scene.people])
        d.append(float(np.min(np.abs(np.linalg.norm(c - p, axis=1) - r))))
    return min(d)


def _fix_stats(scene: Any, layout: Any, pulses: list[Any], truth: list[dict[tuple[int, int], tuple[float, float]]],
               events: Iterable[Any], tol_ticks: int, tol_m: float) -> dict[str, Any]:
    """The sensor's (id 0) first in-window echoes classed against the truth (own pulse's echo,
    another pulse's, none) and its pulses with a first echo on every receiver put through the
    host geometry as the firmware does (gated echoes skipped): the counts of
    :class:`FalseFixResult` from ``samples`` on."""
    by_seq: dict[int, int] = {}
    pi = 0
    first: list[dict[int, tuple[int, str]]] = [{} for _ in pulses]  # rx -> (tof, "true" | "alias" | "false")
    gated: dict[str, int] = {}
    for e in sorted((e for e in events if e.sensor == 0), key=lambda e: e.tick):
        while pi < len(pulses) and pulses[pi].t0 <= e.tick:
            by_seq[pulses[pi].seq % 256] = pi
            pi += 1
        k = by_seq.get(e.seq)
        if k is None or not (e.first_echo and e.in_window):
            continue
        edge = pulses[k].t0 + e.tof

        def near(i: int) -> bool:
            return any(abs(edge - a) <= tol_ticks for (_, rx), (a, _) in truth[i].items() if rx == e.rx)
        what = "true" if near(k) else "alias" if any(
            near(i) for i in range(max(0, k - 4), min(len(pulses), k + 2)) if i != k) else "false"
        if e.gated:  # no geometry input (the firmware and the host skip it)
            gated[what] = gated.get(what, 0) + 1
        else:
            first[k][e.rx] = (e.tof, what)
    full = [k for k, f in enumerate(first) if len(f) == len(RX)]
    c = scene.speed_of_sound
    false_fixes = false_sp = false_al = fixes = unc = false_unc = 0
    worst = 0.0
    if full:
        tofs = np.array([[first[k][r][0] for r in RX] for k in full], float)
        pts, has, fix = _fix_points(list(RX), c * tofs / TICK_HZ, layout.positions[TX])
        for k, tof, q, h_pos, is_fix in zip(full, tofs, pts, has, fix):
            if not h_pos:
                continue
            t = (pulses[k].t0 + float(np.mean(tof)) / 2) / TICK_HZ
            x, y, h = (float(v) for v in scene.pose(t))
            w = np.array([[math.cos(h), -math.sin(h)], [math.sin(h), math.cos(h)]]) @ q + (x, y)
            err = _surface_distance(scene, t, w)
            if not is_fix:
                unc += 1
                false_unc += err > tol_m
                continue
            fixes += 1
            worst = max(worst, err)
            if err > tol_m:
                false_fixes += 1
                kinds = {first[k][r][1] for r in RX}
                false_sp += "false" in kinds
                false_al += "alias" in kinds and "false" not in kinds
    every = [w for f in first for w in f.values()]
    return dict(samples=len(every), alias_samples=sum(w[1] == "alias" for w in every),
                false_samples=sum(w[1] == "false" for w in every), gated=sum(gated.values()),
                gated_false=gated.get("false", 0), gated_alias=gated.get("alias", 0), fixes=fixes,
                false_fixes=false_fixes, false_fixes_spurious=false_sp, false_fixes_alias=false_al,
                max_fix_error_m=worst, uncertain_points=unc, false_uncertain_points=false_unc)


def run_false_fix_trial(seed: int, *, spurious_rate_hz: float | None = None, crosstalk_level: float | None = None,
                        person: bool = True, t_cross: float = 0.8, duration: float = 1.6, tol_ticks: int = 600,
                        tol_m: float = FALSE_FIX_TOL_M, miss_gate: int | None = DEFAULT_MISS_GATE,
                        params: dict[str, Any] | None = None) -> FalseFixResult:
    """The scene and sensor of safety trial ``seed`` (a tracked wall, optionally the person
    crossing) with the noise raised; every pulse with a first in-window echo on all of the
    sensor's receivers (gated ones skipped) goes through the host geometry (as the firmware does
    per pulse). A fix is **false** when its reported point (edge position or wall foot), placed in
    the world with the robot pose at the reflection instant (t0 + mean ToF / 2), is farther than
    ``tol_m`` from every true reflector surface then. ``params``: the trial's parameters
    (default :func:`random_trial_params` of ``seed``)."""
    p = dict(params) if params is not None else random_trial_params(seed)
    layout = load_layout()
    scene = _scene(p, t_cross, duration, spurious_rate_hz, crosstalk_level, person)
    sched = _schedule(layout, p["order"], p["miss_limit"], p["wall_y"])
    src = SceneEchoSource(scene, rng=np.random.default_rng(p["seed"]))
    model = FastFiringModel(sched, src, decision_lead=DEVICE_DECISION_LEAD, miss_gate=miss_gate)
    res = model.run(int(duration * TICK_HZ))
    pulses = [q for q in res.pulses if q.sensor == 0]
    truth = _truth(src.model, pulses)
    st = _fix_stats(scene, layout, pulses, truth, res.events, tol_ticks, tol_m)
    return FalseFixResult(seed=seed, order=sched.sensors[0].order, spurious_rate_hz=float(scene.noise.spurious_rate_hz),
                          crosstalk_level=float(scene.model.crosstalk_level), person=person, duration_s=duration,
                          pulses=len(pulses), **st)


def summarise_false_fixes(results: Iterable[FalseFixResult]) -> dict[str, Any]:
    rs = list(results)
    n = {k: sum(getattr(r, k) for r in rs) for k in ("samples", "alias_samples", "false_samples", "gated", "gated_false",
                                                    "gated_alias", "fixes", "false_fixes",
                                                    "false_fixes_spurious", "false_fixes_alias", "pulses",
                                                    "uncertain_points", "false_uncertain_points")}
    sonar_s = sum(r.duration_s for r in rs)
    return n | dict(trials=len(rs), sonar_s=sonar_s,
                    false_sample_rate=n["false_samples"] / n["samples"] if n["samples"] else 0.0,
                    false_fix_rate=n["false_fixes"] / n["fixes"] if n["fixes"] else 0.0,
                    false_fixes_per_s=n["false_fixes"] / sonar_s if sonar_s else float("nan"),
                    fixes_per_s=n["fixes"] / sonar_s if sonar_s else float("nan"),
                    max_fix_error_m=max((r.max_fix_error_m for r in rs), default=0.0))
