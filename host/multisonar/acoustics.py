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
robot disc); candidates are then pruned with margins before the motion is iterated.

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
from typing import Any

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
    edge = cutoff * half_angle
    p = math.log(0.5) / math.log(math.cos(0.5 * math.pi / cutoff)) if cutoff > 1 else 1.0
    inside = theta < edge
    x = np.where(inside, theta / edge, 0.0)
    return np.where(inside, np.cos(0.5 * np.pi * x) ** p, 0.0)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def _off_axis(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Angle between direction vectors v (...,2) and axis angles (...)."""
    ux, uy = np.cos(axis), np.sin(axis)
    return np.abs(np.arctan2(ux * v[..., 1] - uy * v[..., 0], ux * v[..., 0] + uy * v[..., 1]))


def _mirror_path(S, R, a, t, n, length, margin=0.0):
    """Specular path S -> wall -> R for walls through a with unit tangent t, normal n.

    Returns (L, P, valid, loose): path length (image distance), reflection point, whether the
    reflection point lies on the segment with S and R strictly on the same side, and the same
    test with the segment extended by ``margin`` at both ends."""
    ds, dr = _dot(S - a, n), _dot(R - a, n)
    st, rt = _dot(S - a, t), _dot(R - a, t)
    h = np.abs(ds) + np.abs(dr)
    L = np.hypot(rt - st, h)
    frac = np.abs(ds) / np.where(h > 0, h, 1.0)
    pt = st + (rt - st) * frac
    side = ds * dr > 0
    valid = side & (pt >= 0) & (pt <= length)
    loose = side & (pt >= -margin) & (pt <= length + margin)
    P = a + pt[..., None] * t
    return L, P, valid, loose


def _interval(O, a, b):
    """Angular interval (centre, half-width) of segments a-b seen from points O (flat)."""
    ua, ub = a - O, b - O
    na, nb = np.linalg.norm(ua, axis=1), np.linalg.norm(ub, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ua, ub = ua / na[:, None], ub / nb[:, None]
        mid = ua + ub
        centre = np.arctan2(mid[:, 1], mid[:, 0])
        half = 0.5 * np.arctan2(np.abs(ua[:, 0] * ub[:, 1] - ua[:, 1] * ub[:, 0]), _dot(ua, ub))
    return np.where(np.isfinite(centre), centre, 0.0), np.where(np.isfinite(half), half, np.pi)


def _disc(O, centre, radius):
    """Angular interval of a disc seen from points O (half-width pi when O is inside)."""
    d = centre - O
    dist = np.linalg.norm(d, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        half = np.where(dist > radius, np.arcsin(np.minimum(1.0, radius / dist)), np.pi)
    return np.arctan2(d[:, 1], d[:, 0]), half


def _overlap(i1, i2, margin: float = 1e-9):
    """Whether angular intervals (centre, half-width) overlap."""
    diff = np.abs(np.angle(np.exp(1j * (i1[0] - i2[0]))))
    return diff <= i1[1] + i2[1] + margin


class AcousticModel:
    """Comparator pulses for firings in a scene (see the module docstring for the physics)."""

    #: fixed-point iterations for the arrival time of a moving robot / moving people
    MAX_ITER = 6
    ITER_TOL_S = 1e-10  # s; the clock tick is 20.8 ns
    NEWTON_STEPS = 4
    #: pruning margins before iterating a moving geometry: reflection point beyond a wall end
    #: (m) and beam angle (rad); motion during one flight moves them far less
    LOOSE_M = 0.1
    #: cheap angular prefilter of (tx, wall) and (tx, wall pair) combinations (exactness is
    #: tested against the unfiltered model)
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
        K = firing.elements.size
        # ring-down on each firing element
        ring = np.zeros(K, dtype=PULSE_DTYPE)
        ring["rx"] = firing.elements
        ring["start"] = t_tx
        ring["width"] = self.layout.transducer.ring_down_s
        ring["kind"] = PulseKind.RINGDOWN
        ring["source"] = firing.elements
        ring["path"] = 0.0
        ring["amplitude"] = self.scene.model.ringdown_amplitude
        # direct crosstalk components
        xt = self.crosstalk_amplitude[firing.elements]  # (K, N)
        kk, rr = np.nonzero(xt > 0)
        dist = self.element_distance[firing.elements[kk], rr]
        comp_rx = [rr]
        comp_t = [t_tx[kk] + dist / self.c]
        comp_a = [xt[kk, rr]]
        comp_kind = [np.full(kk.size, PulseKind.CROSSTALK, dtype=np.uint8)]
        comp_src = [firing.elements[kk]]
        comp_group = [np.full(kk.size, -1, dtype=np.int64)]
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

    # ---------------------------------------------------------------- comparator
    def _cluster(self, rx, t, a, kind, src, group, path, burst) -> np.ndarray:
        """Superpose contributions of one path on one receiver arriving within a burst of each
        other; apply fading, threshold, width and jitter. Returns PULSE_DTYPE (unsorted)."""
        if rx.size == 0:
            return np.zeros(0, dtype=PULSE_DTYPE)
        order = np.lexsort((t, group, rx))
        rx, t, a, kind, src, group, path = (x[order] for x in (rx, t, a, kind, src, group, path))
        new = np.ones(rx.size, dtype=bool)
        new[1:] = (rx[1:] != rx[:-1]) | (group[1:] != group[:-1]) | (t[1:] - t[:-1] > burst)
        starts = np.flatnonzero(new)
        cl = np.cumsum(new) - 1
        total = np.add.reduceat(a, starts)
        nz = self.scene.noise
        fade = np.ones(starts.size)
        is_echo = kind[starts] >= PulseKind.ECHO
        if nz.fading_db > 0 and np.any(is_echo):
            g = self.rng.normal(0.0, nz.fading_db, size=int(is_echo.sum()))
            fade[is_echo] = 10.0 ** (g / 20.0)
        cum = np.cumsum(a)
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
        end = p["start"] + p["width"]
        new = np.ones(p.size, dtype=bool)
        if p.size > 1:
            # running max of end within each receiver (offset receivers far apart in time)
            span = float(np.max(end) - np.min(p["start"])) + 1.0
            key = end - np.min(p["start"]) + p["rx"].astype(np.float64) * 2.0 * span
            runmax = np.maximum.accumulate(key)
            skey = p["start"] - np.min(p["start"]) + p["rx"].astype(np.float64) * 2.0 * span
            new[1:] = (p["rx"][1:] != p["rx"][:-1]) | (skey[1:] > runmax[:-1])
        starts = np.flatnonzero(new)
        out = p[starts].copy()
        out["width"] = np.maximum.reduceat(end, starts) - out["start"]
        out["amplitude"] = np.maximum.reduceat(p["amplitude"], starts)
        return out[np.argsort(out["start"], kind="stable")]

    # ---------------------------------------------------------------- geometry
    def _rx_at(self, t: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World position (Q,2) and axis (Q,) of receiver n (Q,) at times t (Q,)."""
        if self._static_robot:
            return self._rx_static_pos[n], self._rx_static_ax[n]
        return self.scene.element_poses(t, n)

    def _rx_velocity(self, t: np.ndarray, R: np.ndarray) -> np.ndarray:
        """World velocity (Q,2) of receivers at world positions R (Q,2) at times t (Q,)."""
        x, y, _ = self.scene.pose(t)
        vx, vy, w = self.scene.velocity(t)
        return np.stack([vx - w * (R[:, 1] - y), vy + w * (R[:, 0] - x)], axis=1)

    def _paths(self, parts: list, firing: Firing, S: np.ndarray, Sax: np.ndarray, t_tx: np.ndarray, M: int,
               geom, amp_fn, kind: int, source: np.ndarray, source2: np.ndarray, group: np.ndarray,
               moving_targets: bool = False, cylinder_base: int | None = None, warm: bool = False,
               cand: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Evaluate one reflector family for all (tx k, rx n, reflector m) candidates.

        geom(k, m, R, t_ref) -> dict(L, r1, P1, P2, valid, loose): path length, distance to the
        first reflection point P1, last reflection point P2 (== P1 for one bounce), exact
        validity and a loose validity (with margins) used to prune before iterating."""
        K = t_tx.size
        if cand is None:
            k, n, m = (a.ravel() for a in np.indices((K, self.n, M)))
        else:  # only the (tx, reflector) combinations that passed a cheap prefilter
            kc, mc = cand
            if kc.size == 0:
                return
            k, m = np.repeat(kc, self.n), np.repeat(mc, self.n)
            n = np.tile(np.arange(self.n), kc.size)
        iterate = moving_targets or not self._static_robot
        t_arr = t_tx[k]
        R, Rax = self._rx_at(t_arr, n)
        res = geom(k, m, R, None)
        # prune: reflection geometry and beams (with margins if the geometry will still move)
        margin = self.BEAM_MARGIN if iterate else 0.0
        edge = self.scene.model.beam_cutoff * self.half_angle + margin
        keep = res["loose"] if iterate else res["valid"]
        keep &= _off_axis(res["P1"] - S[k], Sax[k]) < edge
        keep &= _off_axis(res["P2"] - R, Rax) < edge
        if not keep.any():
            return
        k, n, m, t_arr = k[keep], n[keep], m[keep], t_arr[keep]
        res = {key: v[keep] for key, v in res.items()}
        R, Rax = R[keep], Rax[keep]
        t_em = t_tx[k]
        if iterate:
            # solve g(t) = t_tx + L(r(t)) / c - t = 0 by Newton's method: dL/dr = unit(r - P2)
            # (mirror image, point, and by Fermat's principle the circle), dr/dt = the receiver's
            # velocity (robot translation + rotation). Converges in one or two steps.
            for it in range(self.MAX_ITER):
                g = t_em + res["L"] / self.c - t_arr
                g = np.where(np.isfinite(g), g, 0.0)
                if float(np.max(np.abs(g))) < self.ITER_TOL_S or it == self.MAX_ITER - 1:
                    break
                if self._static_robot:
                    t_arr = t_arr + g
                elif it == 0:
                    # predictor: the sound reaches the receiver along the last leg from an apparent
                    # source A (the mirror image for walls); with the receiver moving at constant
                    # velocity v, |R0 + v tau - A| = c tau is a quadratic (exact for walls under
                    # translation)
                    vr = self._rx_velocity(t_arr, R)
                    leg = R - res["P2"]
                    nl = np.linalg.norm(leg, axis=1)
                    with np.errstate(divide="ignore", invalid="ignore"):
                        A = res["P2"] - leg / nl[:, None] * (res["L"] - nl)[:, None]
                        D = R - A
                        dv = _dot(D, vr)
                        c2v2 = self.c ** 2 - _dot(vr, vr)
                        tau = (dv + np.sqrt(dv * dv + c2v2 * _dot(D, D))) / c2v2
                    t_arr = np.where(np.isfinite(tau), t_em + tau, t_arr + g)
                else:
                    vr = self._rx_velocity(t_arr, R)
                    u = R - res["P2"]
                    with np.errstate(divide="ignore", invalid="ignore"):
                        dl = _dot(u, vr) / np.linalg.norm(u, axis=1)
                    dg = np.where(np.isfinite(dl), dl, 0.0) / self.c - 1.0
                    t_arr = t_arr - g / dg
                R, Rax = self._rx_at(t_arr, n)
                res = geom(k, m, R, t_em + res["r1"] / self.c, res) if warm else geom(k, m, R, t_em + res["r1"] / self.c)
        L = res["L"]
        t_arr = t_em + L / self.c
        P1, P2 = res["P1"], res["P2"]
        with np.errstate(divide="ignore", invalid="ignore"):
            amp = self._beam(P1 - S[k], Sax[k]) * self._beam(P2 - R, Rax) * amp_fn(k, m, res) * np.exp(-self.alpha * L)
        ok = res["valid"] & (amp > 0) & np.isfinite(amp)
        if not ok.any():
            return
        k, n, m, R, P1, P2, L, t_arr, amp = (x[ok] for x in (k, n, m, R, P1, P2, L, t_arr, amp))
        r1 = res["r1"][ok]
        t1 = t_tx[k] + r1 / self.c
        r_last = np.linalg.norm(R - P2, axis=1)
        t2 = t_arr - r_last / self.c
        second = kind == PulseKind.ECHO2
        legs = [(S[k], P1, t_tx[k], t1), (P2, R, t2, t_arr)]
        if second:
            legs.insert(1, (P1, P2, t1, t2))
        parts.append({
            "rx": n.astype(np.int16), "tx": firing.elements[k].astype(np.int16),
            "kind": np.full(k.size, kind, dtype=np.uint8), "source": source[m].astype(np.int32),
            "source2": source2[m].astype(np.int32), "group": group[m].astype(np.int64),
            "t_tx": t_tx[k], "arrival": t_arr, "path": L, "point": P1,
            "point2": P2 if second else np.full((k.size, 2), np.nan), "amplitude": amp,
            "cyl_self": (m if cylinder_base is not None else np.full(k.size, -1)).astype(np.int64),
            "legs": legs,
        })

    def _beam(self, v: np.ndarray, axis: np.ndarray) -> np.ndarray:
        return beam_gain(_off_axis(v, axis), self.half_angle, self.scene.model.beam_cutoff)

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
        S, Sax = sc.element_poses(t_tx, firing.elements)  # (K,2), (K,)
        parts: list[dict] = []
        W = self.n_walls
        wa, wt, wn, wl, wr = (self.wall_a, self.wall_t, self.wall_n, self.wall_len, sc.wall_reflectivity) if W else (None,) * 5
        wb = sc.walls[:, 1] if W else None
        edge = sc.model.beam_cutoff * self.half_angle + (0.0 if self._static_robot else self.BEAM_MARGIN)
        rx_, ry_, _ = sc.pose(float(np.mean(t_tx)))
        robot = np.array([float(rx_), float(ry_)])
        # receivers stay within this disc during any flight (robot <= 2 m/s, flights < 0.1 s)
        foot = sc.footprint_radius + (0.0 if self._static_robot else 0.25)
        loose = self.LOOSE_M if not self._static_robot else 0.0

        if W:
            def g_wall(k, m, R, _t_ref):
                Sk = S[k]
                L, P, valid, lz = _mirror_path(Sk, R, wa[m], wt[m], wn[m], wl[m], loose)
                return {"L": L, "r1": np.linalg.norm(P - Sk, axis=1), "P1": P, "P2": P, "valid": valid, "loose": lz}

            src = np.arange(W)
            # prefilter (tx, wall): the wall within the tx beam, the robot within the window the
            # wall opens for the mirror image
            kk, ii = (x.ravel() for x in np.indices((S.shape[0], W)))
            S1 = S[kk] - 2.0 * _dot(S[kk] - wa[ii], wn[ii])[:, None] * wn[ii]
            ok = _overlap(_interval(S[kk], wa[ii], wb[ii]), (Sax[kk], np.full(kk.size, edge)))
            ok &= _overlap(_interval(S1, wa[ii], wb[ii]), _disc(S1, robot, foot))
            self._paths(parts, firing, S, Sax, t_tx, W, g_wall, lambda k, m, r: wr[m] / r["L"],
                        PulseKind.ECHO, src, np.full(W, -1), src, cand=(kk[ok], ii[ok]) if self.PREFILTER else None)

            if self.pairs is not None:
                pi, pj = self.pairs

                def g_w2(k, m, R, _t_ref):
                    i, j = pi[m], pj[m]
                    Sk = S[k]
                    S1 = Sk - 2.0 * _dot(Sk - wa[i], wn[i])[:, None] * wn[i]  # image of S in wall i
                    L, P2, v2, l2 = _mirror_path(S1, R, wa[j], wt[j], wn[j], wl[j], loose)
                    _, P1, v1, l1 = _mirror_path(Sk, P2, wa[i], wt[i], wn[i], wl[i], loose)
                    return {"L": L, "r1": np.linalg.norm(P1 - Sk, axis=1), "P1": P1, "P2": P2,
                            "valid": v1 & v2, "loose": l1 & l2}

                # prefilter (tx, wall i, wall j): wall i in the tx beam, wall j seen from the
                # first image through wall i, the robot seen from the second image through wall j
                kk, mm = (x.ravel() for x in np.indices((S.shape[0], pi.size)))
                i, j = pi[mm], pj[mm]
                Sk = S[kk]
                ok = _overlap(_interval(Sk, wa[i], wb[i]), (Sax[kk], np.full(kk.size, edge)))
                S1 = Sk - 2.0 * _dot(Sk - wa[i], wn[i])[:, None] * wn[i]
                ok &= _overlap(_interval(S1, wa[i], wb[i]), _interval(S1, wa[j], wb[j]))
                S2 = S1 - 2.0 * _dot(S1 - wa[j], wn[j])[:, None] * wn[j]
                ok &= _overlap(_interval(S2, wa[j], wb[j]), _disc(S2, robot, foot))
                self._paths(parts, firing, S, Sax, t_tx, pi.size, g_w2,
                            lambda k, m, r: wr[pi[m]] * wr[pj[m]] / r["L"], PulseKind.ECHO2, pi, pj,
                            self.n_reflectors + pi * W + pj, cand=(kk[ok], mm[ok]) if self.PREFILTER else None)

        Pn = len(sc.point_names)
        if Pn:
            X = sc.points
            strength = sc.point_strength

            def g_pt(k, m, R, _t_ref):
                x = X[m]
                r1 = np.linalg.norm(x - S[k], axis=1)
                ones = np.ones(k.size, dtype=bool)
                return {"L": r1 + np.linalg.norm(x - R, axis=1), "r1": r1, "P1": x, "P2": x, "valid": ones, "loose": ones}

            src = self.off_points + np.arange(Pn)
            self._paths(parts, firing, S, Sax, t_tx, Pn, g_pt,
                        lambda k, m, r: strength[m] / (r["r1"] * (r["L"] - r["r1"])), PulseKind.ECHO,
                        src, np.full(Pn, -1), src)

        C = len(sc.cylinder_names) + len(sc.people)
        if C:
            n_static = len(sc.cylinder_names)
            radius = np.concatenate([sc.cylinder_radius, [p.radius for p in sc.people]])
            refl = np.concatenate([sc.cylinder_reflectivity, [p.reflectivity for p in sc.people]])

            def centres(m, t):
                out = np.empty((m.size, 2))
                st = m < n_static
                out[st] = sc.cylinders[m[st]]
                for q, p in enumerate(sc.people):
                    sel = m == n_static + q
                    if sel.any():
                        out[sel] = p.path.at(t[sel])
                return out

            def g_cyl(k, m, R, t_ref, prev=None):
                Sk = S[k]
                if sc.people and t_ref is None:
                    c0 = centres(m, t_tx[k])
                    t_ref = t_tx[k] + np.maximum(np.linalg.norm(c0 - Sk, axis=1) - radius[m], 0.0) / self.c
                cen = centres(m, t_ref) if sc.people else sc.cylinders[m]
                Q, r1, r2, cos_i, valid, phi = self._cylinder_specular(
                    Sk, R, cen, radius[m], None if prev is None else prev["phi"])
                return {"L": r1 + r2, "r1": r1, "r2": r2, "cos": cos_i, "P1": Q, "P2": Q, "valid": valid,
                        "loose": np.isfinite(r1 + r2), "phi": phi}

            def a_cyl(k, m, r):
                L = r["L"]
                conv = np.sqrt(L / (L + 2.0 * r["r1"] * r["r2"] / (radius[m] * np.maximum(r["cos"], 1e-12))))
                return refl[m] / L * conv

            src = self.off_cyl + np.arange(C)
            self._paths(parts, firing, S, Sax, t_tx, C, g_cyl, a_cyl, PulseKind.ECHO, src, np.full(C, -1), src,
                        moving_targets=bool(sc.people), cylinder_base=0, warm=True)

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
        Q = np.stack([C[:, 0] + qx, C[:, 1] + qy], axis=1)
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
            e = (self.wall_t * self.wall_len[:, None])[None]  # (1,W,2)
            w = self.wall_a[None] - p0[:, None, :]  # (Q,W,2)
            den = d[:, None, 0] * e[..., 1] - d[:, None, 1] * e[..., 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                s = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / den
                u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / den
            hit = (np.abs(den) > 1e-15) & (s > eps) & (s < 1 - eps) & (u >= 0) & (u <= 1)
            blocked |= hit.any(axis=1)
        C = len(sc.cylinder_names) + len(sc.people)
        if C:
            tm = 0.5 * (t0 + t1)
            cen = np.empty((p0.shape[0], C, 2))
            ns = len(sc.cylinder_names)
            cen[:, :ns] = sc.cylinders[None]
            for q, p in enumerate(sc.people):
                cen[:, ns + q] = p.path.at(tm)
            rad = np.concatenate([sc.cylinder_radius, [p.radius for p in sc.people]])
            dd = _dot(d, d)[:, None]
            with np.errstate(divide="ignore", invalid="ignore"):
                u = np.clip(_dot(cen - p0[:, None], d[:, None]) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
            closest = p0[:, None] + u[..., None] * d[:, None]
            dist = np.linalg.norm(cen - closest, axis=-1)
            hit = dist < rad[None] * (1 - 1e-9) - 1e-12
            hit[np.arange(p0.shape[0]), np.clip(cyl_self, 0, C - 1)] &= cyl_self < 0
            blocked |= hit.any(axis=1)
        return blocked


def _empty_components() -> dict[str, np.ndarray]:
    return {"rx": np.zeros(0, np.int16), "tx": np.zeros(0, np.int16), "kind": np.zeros(0, np.uint8),
            "source": np.zeros(0, np.int32), "source2": np.zeros(0, np.int32), "group": np.zeros(0, np.int64),
            "t_tx": np.zeros(0), "arrival": np.zeros(0), "path": np.zeros(0), "point": np.zeros((0, 2)),
            "point2": np.zeros((0, 2)), "amplitude": np.zeros(0), "cyl_self": np.zeros(0, np.int64)}
