"""Acoustic model: the comparator pulses the analog front end gives for one firing in a scene.

This is the simulator every other part of the project is verified against (DESIGN.md §4).
For a :class:`Firing` (one or more elements triggered with delays, acting as a virtual source)
:meth:`AcousticModel.fire` returns every comparator pulse on every receiver that the firing
causes, in absolute scene time:

* **ring-down** (``RINGDOWN``): each firing element's comparator is high from its trigger for
  the transducer's ``ring_down_s`` (the dead zone);
* **direct crosstalk** (``CROSSTALK``): element i's burst reaches element j after
  ``|c_i - c_j| / c`` with amplitude ``crosstalk_level * (s_min / |c_i - c_j|) ** exponent``
  (s_min: the smallest element spacing); the elements are rigidly mounted, so robot motion is
  not applied to this path;
* **echoes** (``ECHO``): specular wall reflections (mirror image; only where the reflection
  point lies on the segment, both ends on the same side, and inside the transmit and receive
  beams), point reflectors (edges, thin rods: path ``|s - x| + |x - r|``), cylinders and people
  (specular point on the circle, found by Newton's method on the path length);
* **second-order echoes** (``ECHO2``): wall-wall double reflections (two mirror images);
* spurious pulses come from :meth:`AcousticModel.noise_pulses` (not caused by a firing).

Geometry is exact; the robot moves during flight: element i transmits from its pose at its
trigger time and each receiver listens at its pose at the arrival time, the root of
``t_a = t_tx + L(r(t_a)) / c``: a quadratic predictor (exact for walls under translation), then
Newton steps with dL/dr = unit(r - last reflection point) until the residual is < 0.1 ns. People
are placed where they are when the sound reaches them. Before the exact geometry, (tx, wall)
and (tx, wall pair) combinations are prefiltered by angular intervals (beam, wall windows,
robot disc), (tx, point) and (tx, cylinder) ones by the transmit beam; candidates are then
pruned with margins before the motion is iterated.

Cost: proportional to (transmitters x 24 receivers x reflectors) for first-order paths and to
walls^2 for second order (see scripts/bench_acoustics.py); occlusion tests every surviving
path leg against every wall and cylinder.

Amplitudes are relative to a perfect wall seen on both beam axes over a total path of 1 m:

* wall:      ``refl * b_tx * b_rx / L * absorb(L)`` (image source, spherical spreading)
* wall-wall: ``refl_1 * refl_2 * b_tx * b_rx / L * absorb(L)``
* point:     ``strength * b_tx * b_rx / (r1 * r2) * absorb(L)`` (strength in metres)
* cylinder:  ``refl * b_tx * b_rx / L * sqrt(L / (L + 2 r1 r2 / (a cos(theta)))) * absorb(L)``
  (vertical spreading as from a plane, horizontal divergence of a convex mirror of radius a)

with ``absorb(L) = 10 ** (-absorption_db_per_m * L / 20)`` and the beam pattern
``b(theta) = cos(pi/2 * theta / (m * h)) ** p`` inside ``|theta| < m * h`` (h: the layout's
-6 dB half-angle, m: ``beam_cutoff``, p chosen so that b(h) = 1/2), zero outside (the main lobe
of a piston ends near 2 h; side lobes are not modelled).

Comparator: contributions of the same path (same reflector, same receiver) from the several
elements of a virtual source that arrive within one burst length of each other superpose
(amplitudes add); the comparator goes high at the first arrival at which the running sum
(times a log-normal fading factor, sigma ``fading_db``) reaches the threshold; otherwise the
echo is lost. Pulse width = burst length * (width_min + (width_max - width_min) *
(1 - threshold / amplitude)), i.e. it grows with amplitude and saturates. Acoustic pulse starts
get Gaussian timing jitter (``jitter_s``). Finally, overlapping pulses on one receiver merge
into one comparator pulse (start/kind/source/path of the earliest, the largest amplitude).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from enum import IntEnum
from typing import Any, NamedTuple

import numpy as np

from .constants import TICK_S
from .layout import Layout
from .scene import Scene

__all__ = ["PULSE_DTYPE", "TRUTH_DTYPE", "AcousticModel", "Firing", "PulseKind", "beam_gain"]


class PulseKind(IntEnum):
    RINGDOWN = 0
    CROSSTALK = 1
    ECHO = 2
    ECHO2 = 3  # second order (wall-wall)
    SPURIOUS = 4


PULSE_DTYPE = np.dtype([("rx", "i2"), ("start", "f8"), ("width", "f8"), ("kind", "u1"), ("source", "i4"),
                        ("path", "f8"), ("amplitude", "f8")])
"""One comparator pulse. ``source``: reflector index (``Scene.reflector_names``; the first wall
for ECHO2), the emitting element for RINGDOWN/CROSSTALK, -1 for SPURIOUS. ``path``: metres of
sound path from the transmitting element to the receiver (0 for ring-down, NaN for spurious)."""

TRUTH_DTYPE = np.dtype([("rx", "i2"), ("tx", "i2"), ("kind", "u1"), ("source", "i4"), ("source2", "i4"),
                        ("t_tx", "f8"), ("arrival", "f8"), ("path", "f8"), ("point", "f8", (2,)),
                        ("point2", "f8", (2,)), ("amplitude", "f8")])
"""Ground truth of one geometric echo path (transmit element -> reflector(s) -> receiver):
exact, without jitter, fading or threshold. ``point``: the (first) reflection point in world
coordinates, ``point2``: the second one for ECHO2 (NaN otherwise); ``source2`` the second wall
(-1 otherwise); ``amplitude`` before fading (compare with ``scene.noise.threshold``)."""


@dataclass(frozen=True, eq=False)
class Firing:
    """One firing: elements triggered at ``t0 + delays`` (a virtual source when k > 1)."""

    t0: float  # s, scene time of the virtual-source emission instant
    elements: np.ndarray  # (k,) int transmit element indices
    delays: np.ndarray  # (k,) float s >= 0, trigger time of each element relative to t0
    burst_cycles: int = 8

    def __post_init__(self) -> None:
        el = np.atleast_1d(np.asarray(self.elements)).astype(np.intp)
        de = np.atleast_1d(np.asarray(self.delays, dtype=np.float64))
        if de.size == 1 and el.size > 1:
            de = np.full(el.size, float(de[0]))
        if el.ndim != 1 or el.size == 0 or de.shape != el.shape:
            raise ValueError(f"Firing: elements {el} and delays {de} must be 1-D of equal, non-zero length")
        if np.unique(el).size != el.size:
            raise ValueError(f"Firing: elements {el.tolist()} repeat")
        if not np.all(np.isfinite(de)) or np.any(de < 0):
            raise ValueError(f"Firing: delays must be finite and >= 0, got {de.tolist()}")
        if int(self.burst_cycles) < 1:
            raise ValueError(f"Firing: burst_cycles must be >= 1, got {self.burst_cycles}")
        object.__setattr__(self, "elements", el)
        object.__setattr__(self, "delays", de)
        object.__setattr__(self, "t0", float(self.t0))
        object.__setattr__(self, "burst_cycles", int(self.burst_cycles))

    @classmethod
    def single(cls, t0: float, element: int, burst_cycles: int = 8) -> Firing:
        """One element fired at t0 (no delay)."""
        return cls(t0, np.array([element]), np.zeros(1), burst_cycles)

    @classmethod
    def phased(cls, t0: float, elements: Any, layout: Layout, c: float, point: Any = (0.0, 0.0),
               quantize: bool = True, burst_cycles: int = 8) -> Firing:
        """Virtual point source at ``point`` (robot frame): element i fires when an imaginary
        circular wave leaving ``point`` at t0 reaches it, t_i = t0 + |c_i - point| / c,
        quantised to one clock tick (DESIGN.md §1)."""
        el = np.atleast_1d(np.asarray(elements, dtype=np.intp))
        d = np.linalg.norm(layout.positions[el] - np.asarray(point, dtype=np.float64), axis=1) / c
        if quantize:
            d = np.round(d / TICK_S) * TICK_S
        return cls(t0, el, d, burst_cycles)


def beam_gain(theta: Any, half_angle: float, cutoff: float = 2.0) -> np.ndarray:
    """Amplitude beam pattern: 1 on axis, 1/2 at ``half_angle``, 0 from ``cutoff*half_angle``."""
    theta = np.abs(np.asarray(theta, dtype=np.float64))
    return _beam_gain_abs(theta, cutoff * half_angle, _beam_exponent(cutoff))


def _beam_exponent(cutoff: float) -> float:
    """p of the beam pattern cos(pi/2 * theta / edge) ** p, chosen so that b(h) = 1/2."""
    return math.log(0.5) / math.log(math.cos(0.5 * math.pi / cutoff)) if cutoff > 1 else 1.0


def _beam_gain_abs(theta: np.ndarray, edge: float, p: float) -> np.ndarray:
    """beam_gain for angles theta >= 0 (float64) with the edge and exponent precomputed."""
    inside = theta < edge
    x = np.where(inside, theta / edge, 0.0)
    return np.where(inside, np.cos(0.5 * np.pi * x) ** p, 0.0)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a0 * b0 + a1 * b1 over the last axis (one multiplication call for both products)."""
    ab = a * b
    return ab[..., 0] + ab[..., 1]


def _norm(v: np.ndarray) -> np.ndarray:
    """Length of vectors v (..., 2): ``np.linalg.norm(v, axis=-1)`` to the bit (numpy computes
    that as sqrt(add.reduce(v * v)), a two-term sum) without its call overhead."""
    sq = v * v
    return np.sqrt(sq[..., 0] + sq[..., 1])


def _off_axis(v: np.ndarray, ux: np.ndarray, uy: np.ndarray) -> np.ndarray:
    """Angle between direction vectors v (...,2) and axes given by the cosines ux and sines uy
    of their angles (...)."""
    return np.abs(np.arctan2(ux * v[..., 1] - uy * v[..., 0], ux * v[..., 0] + uy * v[..., 1]))


class _Mirror:
    """Specular paths S -> wall -> R for walls through a with unit tangent t, normal n.

    The source side (S fixed per candidate) is computed once; :meth:`path` is then evaluated
    for the receiver positions of each iteration."""

    def __init__(self, S, a, t, n, length):
        sa = S - a
        self.ds, self.st = _dot(sa, n), _dot(sa, t)
        self.abs_ds = np.abs(self.ds)
        self.a, self.t, self.n, self.length = a, t, n, length

    def path(self, R, margin=None, with_length=True):
        """(L, P, valid, loose): path length (image distance; None unless ``with_length``),
        reflection point, whether the reflection point lies on the segment with S and R
        strictly on the same side, and the same test with the segment extended by ``margin``
        at both ends (None without a margin)."""
        ra = R - self.a
        dr, rt = _dot(ra, self.n), _dot(ra, self.t)
        h = self.abs_ds + np.abs(dr)
        along = rt - self.st
        L = np.hypot(along, h) if with_length else None
        frac = self.abs_ds / np.where(h > 0, h, 1.0)
        pt = self.st + along * frac
        side = self.ds * dr > 0
        valid = side & (pt >= 0) & (pt <= self.length)
        loose = None if margin is None else side & (pt >= -margin) & (pt <= self.length + margin)
        P = self.a + pt[..., None] * self.t
        return L, P, valid, loose


def _interval(O, a, b):
    """Angular interval (centre, half-width) of segments a-b seen from points O (flat)."""
    ua, ub = a - O, b - O
    na, nb = _norm(ua), _norm(ub)
    with np.errstate(divide="ignore", invalid="ignore"):
        ua, ub = ua / na[:, None], ub / nb[:, None]
        mid = ua + ub
        centre = np.arctan2(mid[:, 1], mid[:, 0])
        half = 0.5 * np.arctan2(np.abs(ua[:, 0] * ub[:, 1] - ua[:, 1] * ub[:, 0]), _dot(ua, ub))
    return np.where(np.isfinite(centre), centre, 0.0), np.where(np.isfinite(half), half, np.pi)


def _disc(O, centre, radius):
    """Angular interval of a disc seen from points O (half-width pi when O is inside)."""
    d = centre - O
    dist = _norm(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        half = np.where(dist > radius, np.arcsin(np.minimum(1.0, radius / dist)), np.pi)
    return np.arctan2(d[:, 1], d[:, 0]), half


def _overlap(i1, i2, margin: float = 1e-9):
    """Whether angular intervals (centre, half-width) overlap."""
    z = np.exp(1j * (i1[0] - i2[0]))
    diff = np.abs(np.arctan2(z.imag, z.real))  # np.angle(z) without its overhead
    return diff <= i1[1] + i2[1] + margin


def _mirror_points(P, a, n):
    """Images of points P in the lines through a with unit normals n."""
    return P - 2.0 * _dot(P - a, n)[:, None] * n


class _TriggerPoses(NamedTuple):
    """A moving robot at a firing's K trigger times: its position (x, y: (K,)) and every
    receiver's position (pos: (K*N, 2)) and axis (cos, sin: (K*N,)), index k * N + n."""

    x: np.ndarray
    y: np.ndarray
    pos: np.ndarray
    cos: np.ndarray
    sin: np.ndarray


class AcousticModel:
    """Comparator pulses for firings in a scene (see the module docstring for the physics)."""

    #: fixed-point iterations for the arrival time of a moving robot / moving people
    MAX_ITER = 6
    ITER_TOL_S = 1e-10  # s; the clock tick is 20.8 ns
    NEWTON_STEPS = 4
    #: pruning margins before iterating a moving geometry: reflection point beyond a wall end
    #: (m) and beam angle (rad); motion during one flight moves them far less
    LOOSE_M = 0.1
    #: cheap angular prefilter of (tx, wall), (tx, wall pair), (tx, point) and (tx, cylinder)
    #: combinations (exactness is tested against the unfiltered model)
    PREFILTER = True
    BEAM_MARGIN = 0.15
    #: firings whose noise-free echo components are kept: a bench that fires a pulse and then
    #: asks for its truth (safety, false fixes) computes the geometry once, not twice
    COMPONENTS_KEPT = 4096

    def __init__(self, scene: Scene, rng: np.random.Generator | None = None):
        self.scene = scene
        self._components: OrderedDict[tuple[Any, ...], dict[str, np.ndarray]] = OrderedDict()
        self.rng = rng if rng is not None else np.random.default_rng(scene.seed)
        lay = scene.layout
        self.layout = lay
        self.n = lay.n
        self.c = scene.speed_of_sound
        self.half_angle = lay.transducer.beam_half_angle
        m, nz = scene.model, scene.noise
        self.threshold = nz.threshold
        self.alpha = m.absorption_db_per_m / 20.0 * math.log(10.0)  # amplitude nepers per metre
        # crosstalk matrix (elements rigidly mounted)
        d = np.linalg.norm(lay.positions[:, None, :] - lay.positions[None, :, :], axis=2)
        self.element_distance = d
        s_min = float(np.min(np.where(np.eye(self.n, dtype=bool), np.inf, d)))
        with np.errstate(divide="ignore"):
            xt = m.crosstalk_level * (s_min / d) ** m.crosstalk_exponent
        xt[np.eye(self.n, dtype=bool)] = 0.0
        self.crosstalk_amplitude = xt
        # walls
        W = scene.walls
        self.n_walls = W.shape[0]
        if self.n_walls:
            self.wall_a = W[:, 0]
            vec = W[:, 1] - W[:, 0]
            self.wall_len = np.linalg.norm(vec, axis=1)
            self.wall_t = vec / self.wall_len[:, None]
            self.wall_n = np.stack([-self.wall_t[:, 1], self.wall_t[:, 0]], axis=1)
            if m.second_order and self.n_walls > 1:
                i, j = np.nonzero(~np.eye(self.n_walls, dtype=bool))
                self.pairs = (i, j)
            else:
                self.pairs = None
        # reflector index offsets: walls, points, cylinders, people
        self.off_points = self.n_walls
        self.off_cyl = self.off_points + len(scene.point_names)
        self.off_people = self.off_cyl + len(scene.cylinder_names)
        self.n_reflectors = scene.n_reflectors
        self._static_robot = scene.is_static
        self._rx_static_pos, self._rx_static_ax = scene.element_poses(float(scene.trajectory_t[0]))
        self._rx_static_cs = (np.cos(self._rx_static_ax), np.sin(self._rx_static_ax))
        # per-scene constants of the per-firing code (fire() runs thousands of times a second)
        self._beam_edge = m.beam_cutoff * self.half_angle
        self._beam_p = _beam_exponent(m.beam_cutoff)
        self._footprint = scene.footprint_radius
        self._index_cache: dict[tuple[Any, ...], tuple[np.ndarray, ...]] = {}
        self._rx_cycle = np.zeros(0, dtype=np.intp)
        self._element_sets: dict[bytes, tuple[np.ndarray, tuple[np.ndarray, ...]]] = {}
        if self.n_walls:
            self.wall_b = W[:, 1]
            self._wall_e = (self.wall_t * self.wall_len[:, None])[None]  # (1,W,2) wall vectors
            self._wall_source = np.arange(self.n_walls)
            if self.pairs is not None:
                pi, pj = self.pairs
                self._pair_refl = scene.wall_reflectivity[pi] * scene.wall_reflectivity[pj]
                self._pair_group = self.n_reflectors + pi * self.n_walls + pj
        self._point_source = self.off_points + np.arange(len(scene.point_names))
        self._n_round = len(scene.cylinder_names) + len(scene.people)  # cylinders and people
        self._round_radius = np.concatenate([scene.cylinder_radius, [p.radius for p in scene.people]])
        self._round_refl = np.concatenate([scene.cylinder_reflectivity, [p.reflectivity for p in scene.people]])
        self._round_source = self.off_cyl + np.arange(self._n_round)

    # ---------------------------------------------------------------- public API
    def burst_s(self, firing: Firing | None = None) -> float:
        cycles = firing.burst_cycles if firing is not None else 8
        return cycles / self.layout.transducer.frequency_hz

    def pulse_width(self, amplitude: Any, burst_s: float) -> np.ndarray:
        """Comparator pulse width for an echo of ``amplitude`` (>= threshold)."""
        m = self.scene.model
        x = np.clip(self.threshold / np.maximum(np.asarray(amplitude, dtype=np.float64), 1e-300), 0.0, 1.0)
        return burst_s * (m.width_min + (m.width_max - m.width_min) * (1.0 - x))

    def truth(self, firing: Firing) -> np.ndarray:
        """All geometric echo paths of this firing (TRUTH_DTYPE, sorted by rx then arrival):
        first- and second-order echoes that exist (on the segment, inside both beams, not
        occluded), with exact arrival times and amplitudes before fading and threshold."""
        comp = self._echo_components(firing)
        out = np.zeros(comp["rx"].size, dtype=TRUTH_DTYPE)
        for k in TRUTH_DTYPE.names:
            out[k] = comp[k]
        return out[np.lexsort((out["arrival"], out["rx"]))]

    def fire(self, firing: Firing) -> np.ndarray:
        """Every comparator pulse on every receiver caused by ``firing`` (PULSE_DTYPE, sorted
        by start, absolute scene times)."""
        burst = self.burst_s(firing)
        t_tx = firing.t0 + firing.delays
        ring, (kk, rr, amp, delay, src, kind, group, dist) = self._element_set(firing.elements)
        # ring-down on each firing element
        ring = ring.copy()
        ring["start"] = t_tx
        # direct crosstalk components
        comp_rx = [rr]
        comp_t = [t_tx[kk] + delay]
        comp_a = [amp]
        comp_kind = [kind]
        comp_src = [src]
        comp_group = [group]
        comp_path = [dist]
        if self.n_reflectors:
            e = self._echo_components(firing)
            comp_rx.append(e["rx"])
            comp_t.append(e["arrival"])
            comp_a.append(e["amplitude"])
            comp_kind.append(e["kind"])
            comp_src.append(e["source"])
            comp_group.append(e["group"])
            comp_path.append(e["path"])
        acoustic = self._cluster(np.concatenate(comp_rx), np.concatenate(comp_t), np.concatenate(comp_a),
                                 np.concatenate(comp_kind), np.concatenate(comp_src),
                                 np.concatenate(comp_group), np.concatenate(comp_path), burst)
        return self._merge(np.concatenate([ring, acoustic]))

    def noise_pulses(self, t_start: float, t_end: float) -> np.ndarray:
        """Spurious comparator pulses on all channels in [t_start, t_end) (Poisson, rate
        ``noise.spurious_rate_hz`` per channel; widths uniform over the echo width range,
        amplitudes 0..20 dB above threshold), sorted by start."""
        span = float(t_end) - float(t_start)
        rate = self.scene.noise.spurious_rate_hz
        if span <= 0 or rate <= 0:
            return np.zeros(0, dtype=PULSE_DTYPE)
        counts = self.rng.poisson(rate * span, size=self.n)
        total = int(counts.sum())
        out = np.zeros(total, dtype=PULSE_DTYPE)
        out["rx"] = np.repeat(np.arange(self.n), counts)
        out["start"] = t_start + self.rng.random(total) * span
        m = self.scene.model
        out["width"] = self.burst_s() * (m.width_min + (m.width_max - m.width_min) * self.rng.random(total))
        out["kind"] = PulseKind.SPURIOUS
        out["source"] = -1
        out["path"] = np.nan
        out["amplitude"] = self.threshold * 10.0 ** (self.rng.random(total))
        return out[np.argsort(out["start"], kind="stable")]

    def _element_set(self, elements: np.ndarray) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """What a firing's pulses owe to its element set alone, kept per element set: the
        ring-down pulses without their start times, and the crosstalk components (tx index
        into elements, rx, amplitude, delay after the trigger, source, kind, group, path)."""
        key = elements.tobytes()
        hit = self._element_sets.get(key)
        if hit is None:
            ring = np.zeros(elements.size, dtype=PULSE_DTYPE)
            ring["rx"] = elements
            ring["width"] = self.layout.transducer.ring_down_s
            ring["kind"] = PulseKind.RINGDOWN
            ring["source"] = elements
            ring["path"] = 0.0
            ring["amplitude"] = self.scene.model.ringdown_amplitude
            xt = self.crosstalk_amplitude[elements]  # (K, N)
            kk, rr = np.nonzero(xt > 0)
            dist = self.element_distance[elements[kk], rr]
            crosstalk = (kk, rr, xt[kk, rr], dist / self.c, elements[kk],
                         np.full(kk.size, PulseKind.CROSSTALK, dtype=np.uint8),
                         np.full(kk.size, -1, dtype=np.int64), dist)
            for v in (ring, *crosstalk):
                v.flags.writeable = False
            if len(self._element_sets) >= 1024:
                self._element_sets.clear()
            hit = self._element_sets[key] = (ring, crosstalk)
        return hit

    # ---------------------------------------------------------------- comparator
    def _cluster(self, rx, t, a, kind, src, group, path, burst) -> np.ndarray:
        """Superpose contributions of one path on one receiver arriving within a burst of each
        other; apply fading, threshold, width and jitter. Returns PULSE_DTYPE (unsorted)."""
        if rx.size == 0:
            return np.zeros(0, dtype=PULSE_DTYPE)
        order = np.lexsort((t, group, rx))
        rx, t, a, kind, src, group, path = (x.take(order) for x in (rx, t, a, kind, src, group, path))
        new = np.ones(rx.size, dtype=bool)
        new[1:] = (rx[1:] != rx[:-1]) | (group[1:] != group[:-1]) | (t[1:] - t[:-1] > burst)
        starts = new.nonzero()[0]
        cl = new.cumsum() - 1
        total = np.add.reduceat(a, starts)
        nz = self.scene.noise
        fade = np.ones(starts.size)
        is_echo = kind.take(starts) >= int(PulseKind.ECHO)
        if nz.fading_db > 0 and is_echo.any():
            g = self.rng.normal(0.0, nz.fading_db, size=int(is_echo.sum()))
            fade[is_echo] = 10.0 ** (g / 20.0)
        cum = a.cumsum()
        before = np.concatenate([[0.0], cum[:-1]])[starts]
        running = (cum - before[cl]) * fade[cl]
        hit = running >= self.threshold
        first = np.minimum.reduceat(np.where(hit, np.arange(rx.size), rx.size), starts)
        ok = first < rx.size
        idx = first[ok]
        amp = total[ok] * fade[ok]
        last_t = np.maximum.reduceat(t, starts)[ok]
        out = np.zeros(idx.size, dtype=PULSE_DTYPE)
        out["rx"] = rx[idx]
        start = t[idx]
        if nz.jitter_s > 0 and idx.size:
            start = start + self.rng.normal(0.0, nz.jitter_s, size=idx.size)
        out["start"] = start
        out["width"] = (last_t - t[idx]) + self.pulse_width(amp, burst)
        out["kind"] = kind[idx]
        out["source"] = src[idx]
        out["path"] = path[idx]
        out["amplitude"] = amp
        return out

    @staticmethod
    def _merge(p: np.ndarray) -> np.ndarray:
        """Merge overlapping pulses on the same receiver into one comparator pulse."""
        if p.size == 0:
            return p
        p = p[np.lexsort((p["start"], p["rx"]))]
        start, rx = p["start"], p["rx"]
        end = start + p["width"]
        new = np.ones(p.size, dtype=bool)
        if p.size > 1:
            # running max of end within each receiver (offset receivers far apart in time)
            first = start.min()
            span = float(end.max() - first) + 1.0
            offset = rx.astype(np.float64) * 2.0 * span
            runmax = np.maximum.accumulate(end - first + offset)
            new[1:] = (rx[1:] != rx[:-1]) | ((start - first + offset)[1:] > runmax[:-1])
        starts = new.nonzero()[0]
        out = p[starts]
        out["width"] = np.maximum.reduceat(end, starts) - out["start"]
        out["amplitude"] = np.maximum.reduceat(p["amplitude"], starts)
        return out[np.argsort(out["start"], kind="stable")]

    # ---------------------------------------------------------------- geometry
    def _rx_velocity(self, t: np.ndarray, R: np.ndarray, x: np.ndarray, y: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """World velocity (x and y components, (Q,) each) of receivers at world positions R
        (Q,2) at times t (Q,), the robot being at (x, y) then."""
        vx, vy, w = self.scene.velocity(t)
        return vx - w * (R[:, 1] - y), vy + w * (R[:, 0] - x)

    def _prune_edge(self, moving_targets: bool) -> float:
        """Beam half-width (rad) at which _paths prunes candidates: with a margin if the
        geometry will still move while the arrival times are iterated."""
        return self._beam_edge + (self.BEAM_MARGIN if moving_targets or not self._static_robot else 0.0)

    def _cached_index(self, key: tuple[Any, ...], make) -> tuple[np.ndarray, ...]:
        """Arrays that depend only on sizes (numbers of elements, reflectors): made once, kept
        read-only (unless large: then made each time)."""
        got = self._index_cache.get(key)
        if got is None:
            got = make()
            if sum(v.size for v in got) <= 1 << 16:
                for v in got:
                    v.flags.writeable = False
                self._index_cache[key] = got
        return got

    def _receiver_cycle(self, count: int) -> np.ndarray:
        """np.tile(np.arange(n), count), read-only (a view of one cached array)."""
        need = count * self.n
        if self._rx_cycle.size < need:
            self._rx_cycle = np.tile(np.arange(self.n), max(count, 2 * self._rx_cycle.size // self.n))
            self._rx_cycle.flags.writeable = False
        return self._rx_cycle[:need]

    def _paths(self, parts: list, firing: Firing, S: np.ndarray, S_cs: tuple[np.ndarray, np.ndarray], t_tx: np.ndarray,
               tx_pose: _TriggerPoses | None, M: int, bind, amp_fn, kind: int, source: np.ndarray,
               source2: np.ndarray | None, group: np.ndarray, moving_targets: bool = False,
               cylinder_base: int | None = None, warm: bool = False,
               cand: tuple[np.ndarray, np.ndarray] | None = None, tx_ok: np.ndarray | None = None) -> None:
        """Evaluate one reflector family for all (tx k, rx n, reflector m) candidates.

        bind(k, m, Sk) prepares the candidates (Sk: their transmitter positions) and returns
        geom(R, t_ref=None, prev=None, prune=False) -> dict(L, P1, P2, valid, [r1], [loose]):
        path length, first reflection point P1, last reflection point P2 (== P1 for one
        bounce), exact validity, the distance |P1 - Sk| if the family needs it while iterating
        (else it is computed at the end) and, with ``prune``, a loose validity (with margins)
        used to prune before iterating. amp_fn(m, res) gives the reflector's amplitude
        factor. ``S_cs``: cos and sin of the transmitters' axes. ``tx_pose``: robot and
        receivers at the trigger times t_tx (None for a static robot). ``source2`` None: -1.
        ``cand``: the (tx, reflector) pairs to evaluate (from a prefilter), or ``tx_ok``: a
        (K*M,) mask of the (tx, reflector) pairs that can pass the transmit-beam pruning
        below (the remaining candidates keep their order, so the result is the same)."""
        K, N = t_tx.size, self.n
        if cand is None:
            k, n, m = self._cached_index(("knm", K, M), lambda: tuple(a.ravel() for a in np.indices((K, N, M))))
            if tx_ok is not None:
                sel = np.repeat(tx_ok.reshape(K, 1, M), N, axis=1).reshape(-1).nonzero()[0]
                if not sel.size:
                    return
                k, n, m = k.take(sel), n.take(sel), m.take(sel)
        else:  # only the (tx, reflector) combinations that passed a cheap prefilter
            kc, mc = cand
            if kc.size == 0:
                return
            k, m = np.repeat(kc, N), np.repeat(mc, N)
            n = self._receiver_cycle(kc.size)
        static = self._static_robot
        iterate = moving_targets or not static
        edge = self._prune_edge(moving_targets)
        # axes as cos, sin (Sc, Ss: transmitters, Rc, Rs: receivers)
        if static:
            R, Rc, Rs = (x.take(n, axis=0) for x in (self._rx_static_pos, *self._rx_static_cs))
        else:  # the receivers at the trigger times (the same for every reflector family)
            kn = k * N + n
            R, Rc, Rs = (x.take(kn, axis=0) for x in (tx_pose.pos, tx_pose.cos, tx_pose.sin))
        Sk, Sc, Ss = S.take(k, axis=0), S_cs[0].take(k), S_cs[1].take(k)
        res = bind(k, m, Sk)(R, prune=True)
        # prune: reflection geometry and beams (with margins if the geometry will still move)
        keep = (res["loose"] if iterate else res["valid"]) & (_off_axis(res["P1"] - Sk, Sc, Ss) < edge)
        keep &= _off_axis(res["P2"] - R, Rc, Rs) < edge
        sel = keep.nonzero()[0]
        if not sel.size:
            return
        k, n, m, Sk, Sc, Ss, R, Rc, Rs = (x.take(sel, axis=0) for x in (k, n, m, Sk, Sc, Ss, R, Rc, Rs))
        res = {key: v.take(sel, axis=0) for key, v in res.items() if key != "loose"}
        t_em = t_tx.take(k)
        c = self.c
        Rax = None  # the receivers' axes, once they have moved
        if iterate:
            geom = bind(k, m, Sk)
            t_arr = t_em
            if not static:
                xr, yr = tx_pose.x.take(k), tx_pose.y.take(k)  # robot position at t_arr
            # solve g(t) = t_tx + L(r(t)) / c - t = 0 by Newton's method: dL/dr = unit(r - P2)
            # (mirror image, point, and by Fermat's principle the circle), dr/dt = the receiver's
            # velocity (robot translation + rotation). Converges in one or two steps.
            for it in range(self.MAX_ITER):
                g = t_em + res["L"] / c - t_arr
                g = np.where(np.isfinite(g), g, 0.0)
                if float(np.abs(g).max()) < self.ITER_TOL_S or it == self.MAX_ITER - 1:
                    break
                if static:  # only the targets move: the receivers stay where they are
                    t_arr = t_arr + g
                else:
                    vx, vy = self._rx_velocity(t_arr, R, xr, yr)
                    P2 = res["P2"]
                    if it == 0:
                        # predictor: the sound reaches the receiver along the last leg from an
                        # apparent source A (the mirror image for walls); with the receiver moving
                        # at constant velocity v, |R0 + v tau - A| = c tau is a quadratic (exact
                        # for walls under translation)
                        leg = R - P2
                        nl = _norm(leg)
                        with np.errstate(divide="ignore", invalid="ignore"):
                            A = P2 - leg / nl[:, None] * (res["L"] - nl)[:, None]
                            D = R - A
                            dv = D[:, 0] * vx + D[:, 1] * vy
                            c2v2 = c ** 2 - (vx * vx + vy * vy)
                            tau = (dv + np.sqrt(dv * dv + c2v2 * _dot(D, D))) / c2v2
                        t_arr = np.where(np.isfinite(tau), t_em + tau, t_arr + g)
                    else:
                        u = R - P2
                        with np.errstate(divide="ignore", invalid="ignore"):
                            dl = (u[:, 0] * vx + u[:, 1] * vy) / _norm(u)
                        dg = np.where(np.isfinite(dl), dl, 0.0) / c - 1.0
                        t_arr = t_arr - g / dg
                    xr, yr, hr = self.scene.pose(t_arr)
                    R, Rax = self.scene.place_elements(xr, yr, hr, n)
                t_ref = t_em + res["r1"] / c if moving_targets else None  # only people use it
                res = geom(R, t_ref, res if warm else None)
        L = res["L"]
        t_arr = t_em + L / c
        P1, P2 = res["P1"], res["P2"]
        if Rax is not None:  # the receivers moved: their axes' cos and sin
            Rc, Rs = np.cos(Rax), np.sin(Rax)
        edge, p = self._beam_edge, self._beam_p
        with np.errstate(divide="ignore", invalid="ignore"):
            amp = (_beam_gain_abs(_off_axis(P1 - Sk, Sc, Ss), edge, p)
                   * _beam_gain_abs(_off_axis(P2 - R, Rc, Rs), edge, p) * amp_fn(m, res) * np.exp(-self.alpha * L))
        ok = res["valid"] & (amp > 0) & np.isfinite(amp)
        sel = ok.nonzero()[0]
        if not sel.size:
            return
        k, n, m, Sk, R, P1, P2, L, t_arr, amp, t_em = (
            x.take(sel, axis=0) for x in (k, n, m, Sk, R, P1, P2, L, t_arr, amp, t_em))
        r1 = res["r1"].take(sel) if "r1" in res else _norm(P1 - Sk)
        t1 = t_em + r1 / c
        t2 = t_arr - _norm(R - P2) / c
        second = kind == PulseKind.ECHO2
        legs = [(Sk, P1, t_em, t1), (P2, R, t2, t_arr)]
        if second:
            legs.insert(1, (P1, P2, t1, t2))
        Q = k.size
        parts.append({
            "rx": n.astype(np.int16), "tx": firing.elements.take(k).astype(np.int16),
            "kind": np.full(Q, int(kind), dtype=np.uint8), "source": source.take(m).astype(np.int32),
            "source2": np.full(Q, -1, dtype=np.int32) if source2 is None else source2.take(m).astype(np.int32),
            "group": group.take(m).astype(np.int64),
            "t_tx": t_em, "arrival": t_arr, "path": L, "point": P1,
            "point2": P2 if second else np.full((Q, 2), np.nan), "amplitude": amp,
            "cyl_self": m.astype(np.int64) if cylinder_base is not None else np.full(Q, -1, dtype=np.int64),
            "legs": legs,
        })

    def _echo_components(self, firing: Firing) -> dict[str, np.ndarray]:
        """The firing's echo components (deterministic: no noise drawn), read-only; the last
        COMPONENTS_KEPT firings' are kept."""
        key = (firing.t0, firing.elements.tobytes(), firing.delays.tobytes(), self.PREFILTER)
        comp = self._components.get(key)
        if comp is not None:
            self._components.move_to_end(key)
            return comp
        comp = self._compute_echo_components(firing)
        for v in comp.values():
            v.flags.writeable = False
        self._components[key] = comp
        if len(self._components) > self.COMPONENTS_KEPT:
            self._components.popitem(last=False)
        return comp

    def _compute_echo_components(self, firing: Firing) -> dict[str, np.ndarray]:
        sc = self.scene
        t_tx = firing.t0 + firing.delays
        K = t_tx.size
        x, y, h = sc.pose(t_tx)
        S, Sax = sc.place_elements(x, y, h, firing.elements)  # (K,2), (K,)
        S_cs = (np.cos(Sax), np.sin(Sax))
        if self._static_robot:
            tx_pose = None
        else:  # every receiver at every trigger time: where each reflector family starts from
            Rg, Raxg = sc.place_elements(x, y, h)  # (K,N,2), (K,N)
            Raxg = Raxg.reshape(-1)
            tx_pose = _TriggerPoses(x, y, Rg.reshape(-1, 2), np.cos(Raxg), np.sin(Raxg))
        parts: list[dict] = []
        W = self.n_walls
        edge = self._beam_edge + (0.0 if self._static_robot else self.BEAM_MARGIN)
        rx_, ry_, _ = sc.pose(float(t_tx.mean()))
        robot = np.array([float(rx_), float(ry_)])
        # receivers stay within this disc during any flight (robot <= 2 m/s, flights < 0.1 s)
        foot = self._footprint + (0.0 if self._static_robot else 0.25)
        loose = self.LOOSE_M if not self._static_robot else 0.0

        if W:
            wa, wb, wt, wn, wl = self.wall_a, self.wall_b, self.wall_t, self.wall_n, self.wall_len
            wr = sc.wall_reflectivity

            def bind_wall(k, m, Sk):
                mirror = _Mirror(Sk, wa.take(m, axis=0), wt.take(m, axis=0), wn.take(m, axis=0), wl.take(m))

                def geom(R, t_ref=None, prev=None, prune=False):
                    L, P, valid, lz = mirror.path(R, loose if prune else None)
                    return {"L": L, "P1": P, "P2": P, "valid": valid, "loose": lz}
                return geom

            # prefilter (tx, wall): the wall within the tx beam, the robot within the window the
            # wall opens for the mirror image
            kk, ii, wa_i, wb_i, wn_i = self._cached_index(("tx-wall", K), lambda: (
                *(x.ravel() for x in np.indices((K, W))),
                np.tile(wa, (K, 1)), np.tile(wb, (K, 1)), np.tile(wn, (K, 1))))
            S_i = S.take(kk, axis=0)  # the transmitter of each (tx, wall) pair
            S1 = _mirror_points(S_i, wa_i, wn_i)  # image of S in the wall
            in_beam = _overlap(_interval(S_i, wa_i, wb_i), (Sax.take(kk), edge))
            window = _interval(S1, wa_i, wb_i)
            ok = in_beam & _overlap(window, _disc(S1, robot, foot))
            self._paths(parts, firing, S, S_cs, t_tx, tx_pose, W, bind_wall, lambda m, r: wr.take(m) / r["L"],
                        PulseKind.ECHO, self._wall_source, None, self._wall_source,
                        cand=(kk[ok], ii[ok]) if self.PREFILTER else None)

            if self.pairs is not None:
                pi, pj = self.pairs

                def bind_w2(k, m, Sk):
                    i, j = pi.take(m), pj.take(m)
                    ai, ni = wa.take(i, axis=0), wn.take(i, axis=0)
                    first = _Mirror(Sk, ai, wt.take(i, axis=0), ni, wl.take(i))
                    # the image of S in wall i, reflected in wall j
                    second = _Mirror(_mirror_points(Sk, ai, ni), wa.take(j, axis=0), wt.take(j, axis=0),
                                     wn.take(j, axis=0), wl.take(j))

                    def geom(R, t_ref=None, prev=None, prune=False):
                        margin = loose if prune else None
                        L, P2, v2, l2 = second.path(R, margin)
                        _, P1, v1, l1 = first.path(P2, margin, with_length=False)
                        return {"L": L, "P1": P1, "P2": P2, "valid": v1 & v2, "loose": l1 & l2 if prune else None}
                    return geom

                # prefilter (tx, wall i, wall j): wall i in the tx beam, wall j seen from the
                # first image through wall i, the robot seen from the second image through wall j.
                # What depends on (tx, wall i) only is taken from the (tx, wall) prefilter above.
                kk2, mm2, ki, wa_j, wb_j, wn_j = self._cached_index(("tx-pair", K), lambda: (
                    *(x.ravel() for x in np.indices((K, pi.size))),
                    (np.arange(K)[:, None] * W + pi[None, :]).ravel(),
                    np.tile(wa[pj], (K, 1)), np.tile(wb[pj], (K, 1)), np.tile(wn[pj], (K, 1))))
                S1 = S1.take(ki, axis=0)
                ok = in_beam.take(ki)
                ok &= _overlap((window[0].take(ki), window[1].take(ki)), _interval(S1, wa_j, wb_j))
                S2 = _mirror_points(S1, wa_j, wn_j)
                ok &= _overlap(_interval(S2, wa_j, wb_j), _disc(S2, robot, foot))
                self._paths(parts, firing, S, S_cs, t_tx, tx_pose, pi.size, bind_w2,
                            lambda m, r: self._pair_refl.take(m) / r["L"], PulseKind.ECHO2, pi, pj,
                            self._pair_group, cand=(kk2[ok], mm2[ok]) if self.PREFILTER else None)

        Pn = len(sc.point_names)
        if Pn:
            X = sc.points
            strength = sc.point_strength

            def bind_pt(k, m, Sk):
                x = X.take(m, axis=0)
                r1 = _norm(x - Sk)
                ones = np.ones(k.size, dtype=bool)

                def geom(R, t_ref=None, prev=None, prune=False):
                    return {"L": r1 + _norm(x - R), "r1": r1, "P1": x, "P2": x, "valid": ones, "loose": ones}
                return geom

            tx_ok = None
            if self.PREFILTER:
                # the transmit-beam test of _paths' pruning depends on (tx, point) only: done
                # here once per pair instead of once per receiver (exact: the same test)
                kk, mm = self._cached_index(("tx-refl", K, Pn), lambda: tuple(x.ravel() for x in np.indices((K, Pn))))
                tx_ok = _off_axis(X.take(mm, axis=0) - S.take(kk, axis=0), S_cs[0].take(kk),
                                     S_cs[1].take(kk)) < self._prune_edge(False)
            self._paths(parts, firing, S, S_cs, t_tx, tx_pose, Pn, bind_pt,
                        lambda m, r: strength.take(m) / (r["r1"] * (r["L"] - r["r1"])), PulseKind.ECHO,
                        self._point_source, None, self._point_source, tx_ok=tx_ok)

        C = self._n_round
        if C:
            n_static = len(sc.cylinder_names)
            radius, refl = self._round_radius, self._round_refl
            people = sc.people

            def bind_cyl(k, m, Sk):
                rad = radius.take(m)
                if not people:
                    cen_static = sc.cylinders.take(m, axis=0)
                else:  # which candidates are which person (and which static cylinders)
                    t_k = t_tx.take(k)
                    st = m < n_static
                    static_cen = sc.cylinders[m[st]]
                    movers = [(p.path, sel) for q, p in enumerate(people) for sel in [m == n_static + q] if sel.any()]

                    def centres(t):
                        out = np.empty((m.size, 2))
                        out[st] = static_cen
                        for path, sel in movers:
                            out[sel] = path.at(t[sel])
                        return out

                def geom(R, t_ref=None, prev=None, prune=False):
                    if people:
                        if t_ref is None:  # people are where they are when the sound reaches them
                            c0 = centres(t_k)
                            t_ref = t_k + np.maximum(_norm(c0 - Sk) - rad, 0.0) / self.c
                        cen = centres(t_ref)
                    else:
                        cen = cen_static
                    Q, r1, r2, cos_i, valid, phi = self._cylinder_specular(
                        Sk, R, cen, rad, None if prev is None else prev["phi"])
                    return {"L": r1 + r2, "r1": r1, "r2": r2, "cos": cos_i, "P1": Q, "P2": Q, "valid": valid,
                            "loose": np.isfinite(r1 + r2) if prune else None, "phi": phi}
                return geom

            def a_cyl(m, r):
                L = r["L"]
                conv = np.sqrt(L / (L + 2.0 * r["r1"] * r["r2"] / (radius.take(m) * np.maximum(r["cos"], 1e-12))))
                return refl.take(m) / L * conv

            tx_ok = None
            if self.PREFILTER and n_static:
                # conservative transmit-beam prefilter of (tx, static cylinder) pairs: every
                # specular point lies on the circle, so its direction from the transmitter is
                # within asin(a / distance) of the centre's; 1e-6 rad covers rounding. People
                # (whose centre depends on the flight time) always pass.
                kk, mm = self._cached_index(("tx-refl", K, C), lambda: tuple(x.ravel() for x in np.indices((K, C))))
                st = mm < n_static
                Sk = S.take(kk[st], axis=0)
                _, half = _disc(Sk, sc.cylinders.take(mm[st], axis=0), radius.take(mm[st]))
                off = _off_axis(sc.cylinders.take(mm[st], axis=0) - Sk, S_cs[0].take(kk[st]), S_cs[1].take(kk[st]))
                tx_ok = np.ones(kk.size, dtype=bool)
                tx_ok[st] = off < self._prune_edge(bool(people)) + half + 1e-6
            self._paths(parts, firing, S, S_cs, t_tx, tx_pose, C, bind_cyl, a_cyl, PulseKind.ECHO,
                        self._round_source, None, self._round_source,
                        moving_targets=bool(people), cylinder_base=0, warm=True, tx_ok=tx_ok)

        if not parts:
            return _empty_components()
        comp = {k: np.concatenate([p[k] for p in parts]) for k in parts[0] if k != "legs"}
        if sc.model.occlusion:
            p0s, p1s, t0s, t1s, selfs, owner = [], [], [], [], [], []
            off = 0
            for p in parts:
                n = p["rx"].size
                for p0, p1, ta, tb in p["legs"]:
                    p0s.append(p0)
                    p1s.append(p1)
                    t0s.append(ta)
                    t1s.append(tb)
                    selfs.append(p["cyl_self"])
                    owner.append(np.arange(off, off + n))
                off += n
            hit = self._occluded(np.concatenate(p0s), np.concatenate(p1s), np.concatenate(t0s),
                                 np.concatenate(t1s), np.concatenate(selfs))
            blocked = np.zeros(off, dtype=bool)
            blocked[np.concatenate(owner)[hit]] = True
            if blocked.any():
                comp = {k: v[~blocked] for k, v in comp.items()}
        return comp

    def _cylinder_specular(self, S, R, C, a, phi=None):
        """Specular point Q on circles (C, a) for paths S -> Q -> R: Newton's method on the
        angle phi of Q minimising |S - Q| + |Q - R| (start: the bisector, exact when
        |S - C| == |R - C|; or a previous solution ``phi``). Flat (Q,) arrays."""
        sx, sy = S[:, 0] - C[:, 0], S[:, 1] - C[:, 1]
        rx, ry = R[:, 0] - C[:, 0], R[:, 1] - C[:, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            if phi is None:
                ns, nr = np.hypot(sx, sy), np.hypot(rx, ry)
                bx, by = sx / ns + rx / nr, sy / ns + ry / nr
                phi = np.arctan2(by, bx)
                steps = self.NEWTON_STEPS
            else:
                steps = 2
            a2 = a * a
            for _ in range(steps):
                cp, sp = np.cos(phi), np.sin(phi)
                qx, qy = a * cp, a * sp
                f1 = 0.0
                f2 = 0.0
                for xx, xy in ((sx, sy), (rx, ry)):
                    dx, dy = qx - xx, qy - xy
                    nd = np.hypot(dx, dy)
                    dq = a * (dy * cp - dx * sp)  # d . Q'
                    f1 = f1 + dq / nd
                    f2 = f2 + (a2 - (dx * qx + dy * qy)) / nd - dq * dq / (nd * nd * nd)
                phi = phi - np.where(f2 > 0, f1 / f2, 0.0)
            cp, sp = np.cos(phi), np.sin(phi)
            qx, qy = a * cp, a * sp
            r1 = np.hypot(sx - qx, sy - qy)
            r2 = np.hypot(rx - qx, ry - qy)
            cos_s = ((sx - qx) * cp + (sy - qy) * sp) / r1
            cos_r = ((rx - qx) * cp + (ry - qy) * sp) / r2
            valid = (cos_s > 0) & (cos_r > 0) & np.isfinite(phi)
        Q = np.empty(S.shape)  # np.stack([C_x + qx, C_y + qy], axis=1), without its overhead
        Q[:, 0] = C[:, 0] + qx
        Q[:, 1] = C[:, 1] + qy
        return Q, r1, r2, np.where(valid, cos_s, 0.0), valid, phi

    def _occluded(self, p0, p1, t0, t1, cyl_self) -> np.ndarray:
        """Whether legs p0 -> p1 (Q,2), travelled from t0 to t1, cross a wall or a cylinder/person."""
        sc = self.scene
        blocked = np.zeros(p0.shape[0], dtype=bool)
        if p0.shape[0] == 0:
            return blocked
        d = p1 - p0
        eps = 1e-9
        if self.n_walls:
            e = self._wall_e  # (1,W,2)
            w = self.wall_a[None] - p0[:, None, :]  # (Q,W,2)
            den = d[:, None, 0] * e[..., 1] - d[:, None, 1] * e[..., 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                s = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / den
                u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / den
            hit = (np.abs(den) > 1e-15) & (s > eps) & (s < 1 - eps) & (u >= 0) & (u <= 1)
            blocked |= hit.any(axis=1)
        C = self._n_round
        if C:
            tm = 0.5 * (t0 + t1)
            cen = np.empty((p0.shape[0], C, 2))
            ns = len(sc.cylinder_names)
            cen[:, :ns] = sc.cylinders[None]
            for q, p in enumerate(sc.people):
                cen[:, ns + q] = p.path.at(tm)
            rad = self._round_radius
            dd = _dot(d, d)[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.clip(_dot(cen - p0[:, None], d[:, None]) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
            closest = p0[:, None] + u[..., None] * d[:, None]
            dist = _norm(cen - closest)
            hit = dist < rad[None] * (1 - 1e-9) - 1e-12
            hit[np.arange(p0.shape[0]), np.clip(cyl_self, 0, C - 1)] &= cyl_self < 0
            blocked |= hit.any(axis=1)
        return blocked


def _empty_components() -> dict[str, np.ndarray]:
    return {"rx": np.zeros(0, np.int16), "tx": np.zeros(0, np.int16), "kind": np.zeros(0, np.uint8),
            "source": np.zeros(0, np.int32), "source2": np.zeros(0, np.int32), "group": np.zeros(0, np.int64),
            "t_tx": np.zeros(0), "arrival": np.zeros(0), "path": np.zeros(0), "point": np.zeros((0, 2)),
            "point2": np.zeros((0, 2)), "amplitude": np.zeros(0), "cyl_self": np.zeros(0, np.int64)}
