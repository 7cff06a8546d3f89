"""Reflector geometry for one virtual source and N receivers (pure numpy, float64).

All solvers work in the robot frame (x forward, y left, metres, radians CCW). A measurement
is a *path length* per receiver: ``R_i = |source -> reflector| + |reflector -> receiver i|``
(time of flight times the speed of sound).

Formulation (DESIGN.md section 3; the paper's polar form is *not* used, it divides by
``e = c/R`` which blows up when a receiver sits at the source). Coordinates are shifted so
the source is at the origin and ``c_i`` is receiver i relative to the source.

Point reflector (edge, thin rod) at ``x`` with range ``rho = |x|``:
    ``|x - c_i| = R_i - rho``  squares to  ``R_i*rho - c_i.x = (R_i^2 - |c_i|^2)/2``
which is *linear* in ``z = (x, y, rho)``. Two receivers give a line ``z0 + t*n`` in z-space
(``n`` = cross product of the two rows, ``z0`` the minimum-norm point); the constraint
``rho^2 = x^2 + y^2`` (a Lorentz cone) turns it into one quadratic in t, solved with the
cancellation-free root pair. Every solution on the upper nappe (rho > 0) is a true
intersection of the two ellipses when ``R_i > |c_i|`` (one shows ``rho <= (R_i+|c_i|)/2``),
so two receivers give exactly 0, 1 or 2 candidates. Nothing divides by |c_i|.

Wall (infinite line, specular): the mirror image of the source ``m = 2 d n`` satisfies
``|m - c_i| = R_i`` (circle-circle intersection; the half-chord uses Heron's factored
product, no cancellation). ``distance = |m|/2``, ``normal_angle = atan2(m)``.

Cylinder (circle, specular): forward model by Newton on the reflection angle (Alhazen's
problem, convex so Newton is monotone), inverse by Gauss-Newton over
``(bearing, r0, radius)``; ``r0`` = distance from the source to the nearest point of the
circle, so radius -> 0 is the edge and radius -> inf the wall.

Every estimate is polished by Gauss-Newton on the true (unsquared) residuals
``f_i = model_i - R_i``: with N > parameters this is the maximum-likelihood estimate for
i.i.d. Gaussian path noise, with N = parameters it is Newton on the exact system (the noise-
free error is then ``gdop * eps * R``, the conditioning of the problem itself).

Choosing between the two candidates (rules, in order):
  1. A candidate must be physical (rho > 0 / wall in front of the source and receivers).
  2. It must explain the data: RMS misfit <= ``tol`` (default 1 mm, ~3 sigma of 1 us).
     If no candidate does: invalid ('no intersection' for N equal to the number of
     parameters, 'inconsistent data' otherwise).
  3. If both explain the data and are distinct (the mirror ambiguity of two receivers, or
     of receivers on one line), the one whose bearing from the source (wall: whose normal)
     is closer to ``axis`` is taken. ``axis`` defaults to the mean outward direction of the
     receivers seen from the robot origin (the ring's elements face radially outward), so
     a ring pair looks outward. Without a usable axis (receivers spread all round the
     origin, |mean unit vector| < 0.3) or when both candidates are equally far from the
     axis the result is invalid 'ambiguous'.

Validity: ``valid`` is False with a short ``reason`` from :data:`REASONS` when physics gives
no answer; numbers are then zeros (never NaN/Inf). A valid answer also needs
``gdop <= max_gdop`` (position error per unit path error, sqrt(trace((J^T J)^-1))), default
1e4: beyond that the geometry is ill-conditioned ('ill-conditioned'): one 7 um clock tick
would move the answer by > 7 cm, and at exact tangency the answer is not even locally unique.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "REASONS", "PointFit", "WallFit", "CylinderFit", "Classification",
    "PointBatch", "WallBatch", "CylinderBatch",
    "solve_point", "solve_wall", "solve_cylinder", "classify",
    "solve_point_batch", "solve_wall_batch", "solve_cylinder_batch", "classify_batch",
    "point_path_lengths", "wall_path_lengths", "cylinder_path_lengths", "reason_text",
    "KINDS", "ClassifyBatch", "DEFAULT_NOISE_SIGMA", "pair_candidates",
]

#: Reason codes of the batch API (index) and their text in the scalar API.
REASONS: tuple[str, ...] = (
    "",                               # 0 valid
    "path shorter than baseline",     # 1 R_i <= |c_i - s|: no reflection path is that short
    "no intersection",                # 2 ellipses/circles do not meet within tol
    "degenerate receiver geometry",   # 3 receivers coincide / on one ray: no unique answer
    "ambiguous",                      # 4 two physical answers, no axis decides
    "ill-conditioned",                # 5 gdop > max_gdop (grazing, tangency, flat curvature)
    "not physical",                   # 6 e.g. reflector behind the source, receiver inside cylinder
    "inconsistent data",              # 7 best least-squares misfit > tol (model does not fit)
    "invalid input",                  # 8 non-finite or non-positive path length
    "no convergence",                 # 9 iterative fit did not settle
)
#: the codes' symbols, in the same order (the firmware's enum ms_reason: MS_<symbol>, generated
#: by multisonar.tools.gen_contracts into ms_geom_reasons.h with the texts above)
REASON_SYMBOLS: tuple[str, ...] = ("OK", "SHORT", "NOINT", "DEGEN", "AMBIG", "ILLCOND", "UNPHYS", "INCONS", "BADIN",
                                   "NOCONV")
OK, SHORT, NOINT, DEGEN, AMBIG, ILLCOND, UNPHYS, INCONS, BADIN, NOCONV = range(len(REASON_SYMBOLS))
assert len(REASONS) == len(REASON_SYMBOLS)

DEFAULT_TOL = 1e-3
DEFAULT_MAX_GDOP = 1e4
DEFAULT_FOV = math.radians(60.0)
_CHUNK = 131072


def reason_text(code: int) -> str:
    return REASONS[int(code)]


# --------------------------------------------------------------------------------------
# result types
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PointFit:
    valid: bool
    reason: str
    position: np.ndarray  # (2,) robot frame
    range: float  # |position - source|
    bearing: float  # atan2 of position - source
    residual: float  # RMS path misfit, m
    gdop: float = 0.0  # position error (m, RMS) per metre of path noise


@dataclass(frozen=True)
class WallFit:
    valid: bool
    reason: str
    distance: float  # perpendicular distance source -> wall line
    normal_angle: float  # bearing of the foot of the perpendicular from the source
    residual: float
    foot: np.ndarray = None  # (2,) foot of the perpendicular, robot frame
    gdop: float = 0.0


@dataclass(frozen=True)
class CylinderFit:
    valid: bool
    reason: str
    centre: np.ndarray  # (2,)
    radius: float
    residual: float
    range: float = 0.0  # source -> nearest point of the circle
    bearing: float = 0.0  # bearing of the centre from the source
    gdop: float = 0.0


@dataclass(frozen=True)
class PointBatch:
    valid: np.ndarray  # (M,) bool
    reason: np.ndarray  # (M,) int8 codes into REASONS
    position: np.ndarray  # (M,2)
    range: np.ndarray
    bearing: np.ndarray
    residual: np.ndarray
    gdop: np.ndarray


@dataclass(frozen=True)
class WallBatch:
    valid: np.ndarray
    reason: np.ndarray
    distance: np.ndarray
    normal_angle: np.ndarray
    foot: np.ndarray  # (M,2)
    residual: np.ndarray
    gdop: np.ndarray


@dataclass(frozen=True)
class CylinderBatch:
    valid: np.ndarray
    reason: np.ndarray
    centre: np.ndarray  # (M,2)
    radius: np.ndarray
    range: np.ndarray
    bearing: np.ndarray
    residual: np.ndarray
    gdop: np.ndarray


@dataclass(frozen=True)
class Classification:
    """Result of :func:`classify`: ``kind`` in {'edge','wall','cylinder','uncertain'}."""

    kind: str
    why: str
    point: PointFit
    wall: WallFit
    cylinder: CylinderFit
    chi2: dict  # model -> chi-square sum(f^2)/sigma^2
    threshold: dict  # model -> acceptance threshold (chi-square quantile)


# --------------------------------------------------------------------------------------
# input handling
# --------------------------------------------------------------------------------------


def _prepare(receivers, path_lengths, source, min_n: int, what: str):
    c = np.asarray(receivers, dtype=np.float64)
    r = np.asarray(path_lengths, dtype=np.float64)
    if c.ndim not in (2, 3) or c.shape[-1] != 2:
        raise ValueError(f"{what}: receivers must have shape (N, 2) or (M, N, 2), got {c.shape}")
    if r.ndim not in (1, 2):
        raise ValueError(f"{what}: path_lengths must have shape (N,) or (M, N), got {r.shape}")
    scalar = c.ndim == 2 and r.ndim == 1
    if r.ndim == 1:
        r = r[None, :]
    m, n = r.shape
    if c.ndim == 2:
        if c.shape[0] != n:
            raise ValueError(f"{what}: {c.shape[0]} receivers but {n} path lengths")
        c = np.broadcast_to(c[None], (m, n, 2))
    elif c.shape[1] != n or c.shape[0] not in (1, m):
        raise ValueError(f"{what}: receivers {c.shape} do not match path_lengths {r.shape}")
    elif c.shape[0] == 1:
        c = np.broadcast_to(c, (m, n, 2))
    if n < min_n:
        raise ValueError(f"{what}: needs at least {min_n} receivers, got {n}")
    s = np.asarray(source, dtype=np.float64)
    if s.shape == (2,):
        s = np.broadcast_to(s[None], (m, 2))
    elif s.shape != (m, 2):
        raise ValueError(f"{what}: source must have shape (2,) or (M, 2), got {s.shape}")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(s))):
        raise ValueError(f"{what}: receivers and source must be finite")
    bad = ~np.all(np.isfinite(r), axis=1) | np.any(r <= 0.0, axis=1) if m else np.zeros(0, bool)
    r = np.where(bad[:, None], 1.0, r)
    return c, r, s, bad, scalar


def _axis_default(c_abs: np.ndarray):
    """Mean outward direction of the receivers seen from the robot origin (NaN if unusable)."""
    nrm = np.hypot(c_abs[..., 0], c_abs[..., 1])
    ok = nrm > 1e-9
    u = np.where(ok[..., None], c_abs / np.where(ok, nrm, 1.0)[..., None], 0.0)
    cnt = np.maximum(ok.sum(axis=-1), 1)
    mu = u.sum(axis=-2) / cnt[..., None]
    usable = np.hypot(mu[..., 0], mu[..., 1]) >= 0.3
    return np.where(usable, np.arctan2(mu[..., 1], mu[..., 0]), np.nan)


def _axis_array(axis, c_abs, m):
    if axis is None:
        return _axis_default(c_abs)
    a = np.asarray(axis, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(m, float(a))
    if a.shape != (m,):
        raise ValueError(f"axis must be a scalar or shape ({m},), got {a.shape}")
    return a  # NaN entries mean "no axis"


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _norm(v):
    return np.hypot(v[..., 0], v[..., 1])


def _unit(v):
    n = _norm(v)
    ok = n > 0.0
    return np.where(ok[..., None], v / np.where(ok, n, 1.0)[..., None], 0.0), n


# --------------------------------------------------------------------------------------
# forward models (also used by tests and benchmarks)
# --------------------------------------------------------------------------------------


def point_path_lengths(reflector, receivers, source=(0.0, 0.0)) -> np.ndarray:
    """|s-x| + |x-c_i| for reflector(s) (...,2) and receivers (N,2) or (...,N,2)."""
    x = np.asarray(reflector, np.float64)[..., None, :]
    c = np.asarray(receivers, np.float64)
    s = np.asarray(source, np.float64)
    s = s[..., None, :] if s.ndim > 1 else s
    return _norm(x - s) + _norm(x - c)


def wall_path_lengths(distance, normal_angle, receivers, source=(0.0, 0.0)) -> np.ndarray:
    """|mirror(s) - c_i| for the wall line at ``distance`` from the source along ``normal_angle``."""
    d = np.asarray(distance, np.float64)[..., None]
    a = np.asarray(normal_angle, np.float64)[..., None]
    s = np.asarray(source, np.float64)
    s = s[..., None, :] if s.ndim > 1 else s
    c = np.asarray(receivers, np.float64) - s
    return np.hypot(2 * d * np.cos(a) - c[..., 0], 2 * d * np.sin(a) - c[..., 1])


def _specular(p, a, c, iters: int = 8):
    """Specular reflection off circle (centre p (...,2), radius a (...)) from the origin to c (...,2).

    Returns (path length, unit outward normal at the reflection point, cos(incidence), ok).
    ok is False when the origin or c is not outside the circle.
    """
    a = np.asarray(a, np.float64)
    us, ds = _unit(-p)  # direction centre -> source
    uc, dc = _unit(c - p)
    ok = (ds > a) & (dc > a)
    bis, bn = _unit(us + uc)
    # opposite directions (source and receiver on opposite sides): pick the perpendicular
    perp = np.stack([-us[..., 1], us[..., 0]], axis=-1)
    bis = np.where((bn > 1e-12)[..., None], bis, perp)
    phi0 = np.arctan2(bis[..., 1], bis[..., 0])
    half = 0.5 * np.arccos(np.clip(us[..., 0] * uc[..., 0] + us[..., 1] * uc[..., 1], -1.0, 1.0))
    dphi = np.zeros_like(phi0)
    for _ in range(iters):
        phi = phi0 + dphi
        nx, ny = np.cos(phi), np.sin(phi)
        qx, qy = p[..., 0] + a * nx, p[..., 1] + a * ny
        tx, ty = -a * ny, a * nx
        g = 0.0
        gp = 0.0
        for (X, Y) in ((0.0, 0.0), (c[..., 0], c[..., 1])):
            ex, ey = qx - X, qy - Y
            L = np.maximum(np.hypot(ex, ey), 1e-300)
            ex, ey = ex / L, ey / L
            te = tx * ex + ty * ey
            g = g + te
            gp = gp + (a * a - te * te) / L - a * (nx * ex + ny * ey)
        step = -g / np.where(gp > 0.0, gp, 1.0)
        step = np.where(gp > 0.0, step, 0.0)
        dphi = np.clip(dphi + step, -half, half)
    phi = phi0 + dphi
    nx, ny = np.cos(phi), np.sin(phi)
    qx, qy = p[..., 0] + a * nx, p[..., 1] + a * ny
    l1 = np.hypot(qx, qy)
    l2 = np.hypot(qx - c[..., 0], qy - c[..., 1])
    cos_in = -(nx * qx + ny * qy) / np.maximum(l1, 1e-300)
    ok = ok & (cos_in > 0.0)
    n = np.stack([nx, ny], axis=-1)
    return l1 + l2, n, cos_in, ok


def cylinder_path_lengths(centre, radius, receivers, source=(0.0, 0.0)) -> np.ndarray:
    """Specular path lengths source -> circle -> receiver i.

    centre (...,2), radius (...), receivers (N,2) or (...,N,2). Raises ValueError if the
    source or a receiver is not outside the circle.
    """
    s = np.asarray(source, np.float64)
    s_ = s[..., None, :] if s.ndim > 1 else s
    p = np.asarray(centre, np.float64)[..., None, :] - s_
    c = np.asarray(receivers, np.float64) - s_
    a = np.asarray(radius, np.float64)[..., None]
    with np.errstate(all="ignore"):
        L, _, _, ok = _specular(p, a, c, iters=12)
    if not np.all(ok):
        raise ValueError("cylinder_path_lengths: source or receiver inside/grazing the circle")
    return L


# --------------------------------------------------------------------------------------
# small dense least squares, vectorised
# --------------------------------------------------------------------------------------


def _ls_step(J, f):
    """Gauss-Newton step minimising |J d + f| for J (...,N,P), P in (2,3), column-scaled
    normal equations solved by explicit cofactors. Returns (step, gdop_raw) where gdop_raw is
    sqrt(trace((J^T J)^-1)) in the parameter units."""
    P = J.shape[-1]
    s = np.sqrt(np.sum(J * J, axis=-2))  # column norms (...,P)
    s = np.where(s > 0.0, s, 1.0)
    Js = J / s[..., None, :]
    A = np.einsum("...ni,...nj->...ij", Js, Js)
    g = -np.einsum("...ni,...n->...i", Js, f)
    if P == 2:
        a, b, d = A[..., 0, 0], A[..., 0, 1], A[..., 1, 1]
        det = a * d - b * b
        okd = det > 1e-28
        idet = 1.0 / np.where(okd, det, 1.0)
        x0 = (d * g[..., 0] - b * g[..., 1]) * idet
        x1 = (a * g[..., 1] - b * g[..., 0]) * idet
        x = np.stack([x0, x1], axis=-1)
        tr = (d / s[..., 0] ** 2 + a / s[..., 1] ** 2) * idet
    else:
        a, b, c_ = A[..., 0, 0], A[..., 0, 1], A[..., 0, 2]
        d, e, f_ = A[..., 1, 1], A[..., 1, 2], A[..., 2, 2]
        C00 = d * f_ - e * e
        C01 = -(b * f_ - c_ * e)
        C02 = b * e - c_ * d
        C11 = a * f_ - c_ * c_
        C12 = -(a * e - b * c_)
        C22 = a * d - b * b
        det = a * C00 + b * C01 + c_ * C02
        okd = det > 1e-30
        idet = 1.0 / np.where(okd, det, 1.0)
        x0 = (C00 * g[..., 0] + C01 * g[..., 1] + C02 * g[..., 2]) * idet
        x1 = (C01 * g[..., 0] + C11 * g[..., 1] + C12 * g[..., 2]) * idet
        x2 = (C02 * g[..., 0] + C12 * g[..., 1] + C22 * g[..., 2]) * idet
        x = np.stack([x0, x1, x2], axis=-1)
        tr = (C00 / s[..., 0] ** 2 + C11 / s[..., 1] ** 2 + C22 / s[..., 2] ** 2) * idet
    x = np.where(okd[..., None], x / s, 0.0)
    gd = np.where(okd, np.sqrt(np.maximum(tr, 0.0)), np.inf)
    return x, gd


def _gauss_newton(model, p, C, R, iters, scale, project=None):
    """Damped Gauss-Newton on sum(f^2), vectorised with compaction of the unconverged cases.

    model(p (B,P), C (B,N,2), R (B,N)) -> (f (B,N), J (B,N,P), ok (B,)). p has leading shape
    (M,K); C, R broadcast to (M,K,N,...). Returns p, rms, gdop, ok with leading shape (M,K).
    """
    shp = p.shape[:-1]
    P = p.shape[-1]
    N = R.shape[-1]
    p = np.array(p, dtype=np.float64).reshape(-1, P)
    C = np.ascontiguousarray(np.broadcast_to(C, shp + (N, 2))).reshape(-1, N, 2)
    R = np.ascontiguousarray(np.broadcast_to(R, shp + (N,))).reshape(-1, N)
    scale = np.broadcast_to(scale, shp).reshape(-1)
    if project is not None:
        p = project(p)
    f, J, ok = model(p, C, R)
    cost = np.sum(f * f, axis=-1)
    active = np.arange(p.shape[0])
    for _ in range(iters):
        if active.size == 0:
            break
        pa, fa, Ja, oka, ca = p[active], f[active], J[active], ok[active], cost[active]
        p_old, c_old = pa.copy(), ca.copy()
        Ca, Ra = C[active], R[active]
        step, _ = _ls_step(Ja, fa)
        done = np.zeros(active.size, bool)
        t = step
        for _h in range(5):
            sub = np.flatnonzero(~done)
            q = pa[sub] + t[sub]
            if project is not None:
                q = project(q)
            tf, tJ, tok = model(q, Ca[sub], Ra[sub])
            tc = np.sum(tf * tf, axis=-1)
            better = (tc <= ca[sub]) & tok & np.all(np.isfinite(q), axis=-1)
            w = sub[better]
            pa[w], fa[w], Ja[w], oka[w], ca[w] = q[better], tf[better], tJ[better], tok[better], tc[better]
            done[w] = True
            if done.all():
                break
            t = 0.5 * t
        p[active], f[active], J[active], ok[active], cost[active] = pa, fa, Ja, oka, ca
        moved = np.sqrt(np.sum((pa - p_old) ** 2, axis=-1))
        sc = scale[active]
        settled = (moved <= 1e-13 * sc) | (c_old - ca <= 1e-8 * c_old + 1e-32 * sc * sc)
        active = active[done & ~settled]
    _, gd = _ls_step(J, f)
    rms = np.sqrt(cost / f.shape[-1])
    return p.reshape(shp + (P,)), rms.reshape(shp), gd.reshape(shp), ok.reshape(shp), None


def _point_model(x, C, R):
    xe = x[..., None, :]
    u0, r0 = _unit(xe)
    u1, r1 = _unit(xe - C)
    f = r0 + r1 - R
    J = u0 + u1
    ok = _norm(x) > 0.0
    return f, J, ok


def _wall_model(m, C, R):
    u, r = _unit(m[..., None, :] - C)
    f = r - R
    ok = _norm(m) > 0.0
    return f, u, ok


# --------------------------------------------------------------------------------------
# candidate pairs
# --------------------------------------------------------------------------------------


def _cross3(a, b):
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def _point_pair(c1, c2, R1, R2):
    """Two candidate points from two ellipses sharing the focus at the origin.

    Returns cand (M,2,2), ok (M,2), degenerate (M,)."""
    n1, n2 = _norm(c1), _norm(c2)
    r1 = np.stack([-c1[:, 0], -c1[:, 1], R1], axis=-1)
    r2 = np.stack([-c2[:, 0], -c2[:, 1], R2], axis=-1)
    a1 = 0.5 * (R1 - n1) * (R1 + n1)
    a2 = 0.5 * (R2 - n2) * (R2 + n2)
    n = _cross3(r1, r2)
    nn = np.sqrt(np.sum(n * n, axis=-1))
    scale = np.sqrt(np.sum(r1 * r1, -1) * np.sum(r2 * r2, -1))
    deg = nn <= 1e-12 * scale
    nns = np.where(deg, 1.0, nn)
    nh = n / nns[:, None]
    z0 = _cross3(a1[:, None] * r2 - a2[:, None] * r1, nh) / nns[:, None]

    def Q(u, v):
        return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1] - u[..., 2] * v[..., 2]

    A, B, Cq = Q(nh, nh), Q(z0, nh), Q(z0, z0)
    disc = np.maximum(B * B - A * Cq, 0.0)
    sq = np.sqrt(disc)
    q = -(B + np.where(B >= 0.0, sq, -sq))
    okq = q != 0.0
    okA = np.abs(A) > 1e-15
    t1 = np.where(okA, q / np.where(okA, A, 1.0), 0.0)
    t2 = np.where(okq, Cq / np.where(okq, q, 1.0), 0.0)
    # q == 0 means B == 0 and disc == 0: double root at t = 0 (both already 0)
    z1 = z0 + t1[:, None] * nh
    z2 = z0 + t2[:, None] * nh
    cand = np.stack([z1[:, :2], z2[:, :2]], axis=1)
    rho = np.stack([z1[:, 2], z2[:, 2]], axis=1)
    ok = (rho > 0.0) & np.stack([okA | ~okq, np.ones_like(okA)], axis=1) & ~deg[:, None]
    return cand, ok, deg


def _circle_pair(c1, c2, R1, R2):
    """Intersections of circles (c1, R1), (c2, R2): cand (M,2,2), degenerate (M,)."""
    e = c2 - c1
    D = _norm(e)
    deg = D <= 1e-12 * (1.0 + _norm(c1) + _norm(c2))
    Ds = np.where(deg, 1.0, D)
    eh = e / Ds[:, None]
    ep = np.stack([-eh[:, 1], eh[:, 0]], axis=-1)
    a = (R1 - R2) * (R1 + R2) / (2 * Ds) + 0.5 * Ds
    h2 = (Ds + R1 - R2) * (Ds - R1 + R2) * (R1 + R2 - Ds) * (R1 + R2 + Ds) / (4 * Ds * Ds)
    h = np.sqrt(np.maximum(h2, 0.0))
    base = c1 + a[:, None] * eh
    cand = np.stack([base + h[:, None] * ep, base - h[:, None] * ep], axis=1)
    return cand, deg


def _pick_pair_far(V):
    """Greedy pair (i, j) of rows of V (M,N,k) far apart: i farthest from the mean, j from i."""
    M = V.shape[0]
    mu = V.mean(axis=1, keepdims=True)
    i = np.argmax(np.sum((V - mu) ** 2, axis=-1), axis=1)
    vi = V[np.arange(M), i][:, None, :]
    j = np.argmax(np.sum((V - vi) ** 2, axis=-1), axis=1)
    return i, j


def _pick_pair_point(C, R):
    rows = np.concatenate([-C, R[..., None]], axis=-1)
    rows = rows / np.sqrt(np.sum(rows * rows, axis=-1, keepdims=True))
    M = rows.shape[0]
    mu = rows.mean(axis=1, keepdims=True)
    i = np.argmax(np.sum((rows - mu) ** 2, axis=-1), axis=1)
    ri = rows[np.arange(M), i][:, None, :]
    cr = _cross3(np.broadcast_to(ri, rows.shape), rows)
    j = np.argmax(np.sum(cr * cr, axis=-1), axis=1)
    return i, j


# --------------------------------------------------------------------------------------
# candidate selection shared by point and wall
# --------------------------------------------------------------------------------------


def _select(cand, ok, rms, gd, angle, axis, n_params, N, tol, max_gdop, pre_reason, scale, fov):
    """cand (M,K,2), ok/rms/gd/angle (M,K); returns index (M,), reason (M,)."""
    M = cand.shape[0]
    acc = ok & (rms <= tol)
    nacc = acc.sum(axis=1)
    big = np.where(ok, rms, np.inf)
    best_res = np.argmin(big, axis=1)
    idx = best_res.copy()
    reason = np.zeros(M, np.int8)
    none_ok = ~ok.any(axis=1)
    reason[none_ok] = UNPHYS
    reason[(nacc == 0) & ~none_ok] = NOINT if N == n_params else INCONS
    one = nacc == 1
    idx[one] = np.argmax(acc[one], axis=1)
    two = nacc == 2
    dist = _norm(cand[:, 0] - cand[:, 1])
    distinct = dist > 1e-6 * scale
    tie = two & ~distinct
    idx[tie] = best_res[tie]
    amb = two & distinct
    off = np.abs(_wrap(angle - axis[:, None]))
    inside = np.isfinite(off) & (off <= fov)
    decide = amb & (inside.sum(axis=1) == 1)
    idx[decide] = np.argmax(inside[decide], axis=1)
    reason[amb & ~decide] = AMBIG
    sel_gd = gd[np.arange(M), idx]
    reason[(reason == OK) & ~(sel_gd <= max_gdop)] = ILLCOND
    reason = np.where(pre_reason != OK, pre_reason, reason).astype(np.int8)
    return idx, reason


# --------------------------------------------------------------------------------------
# point
# --------------------------------------------------------------------------------------


def _short_paths(C, R):
    """Reason codes SHORT where a path is not longer than its receiver's distance from the
    source (no reflector can explain it), else OK."""
    pre = np.zeros(C.shape[0], np.int8)
    pre[np.any(R <= _norm(C) * (1.0 + 1e-15), axis=1)] = SHORT
    return pre


def _point_core(C, R, axis, tol, max_gdop, fov=None):
    M, N, _ = C.shape
    pre = _short_paths(C, R)
    if N == 2:
        i, j = np.zeros(M, int), np.ones(M, int)
    else:
        i, j = _pick_pair_point(C, R)
    ar = np.arange(M)
    cand, ok0, deg = _point_pair(C[ar, i], C[ar, j], R[ar, i], R[ar, j])
    scale = np.max(R, axis=1)
    # second chance for N > 2: if the chosen pair is degenerate, try the pair (i, other)
    K = 2
    Ck = np.broadcast_to(C[:, None], (M, K, N, 2))
    Rk = np.broadcast_to(R[:, None], (M, K, N))
    p, rms, gd, okm, _ = _gauss_newton(_point_model, cand, Ck, Rk, iters=6 if N == 2 else 12,
                                       scale=scale[:, None])
    ok = ok0 & okm & (_norm(p) > 0.0)
    # the polished point must still satisfy rho <= R_i (upper nappe, |x - c_i| = R_i - rho)
    ang = np.arctan2(p[..., 1], p[..., 0])
    # a degenerate best pair means all pairs are degenerate
    pre = np.where((pre == OK) & deg, DEGEN, pre).astype(np.int8)
    idx, reason = _select(p, ok, rms, gd, ang, axis, 2, N, tol, max_gdop, pre, scale, fov)
    x = p[ar, idx]
    return x, rms[ar, idx], gd[ar, idx], reason


def solve_point_batch(receivers, path_lengths, source=(0.0, 0.0), *, axis=None,
                      tol: float = DEFAULT_TOL, max_gdop: float = DEFAULT_MAX_GDOP,
                fov: float = DEFAULT_FOV) -> PointBatch:
    """Vectorised :func:`solve_point`. receivers (N,2) or (M,N,2), path_lengths (M,N) or (N,),
    source (2,) or (M,2), axis None, scalar or (M,) (rad, NaN = none). Returns arrays; reason
    codes index :data:`REASONS`."""
    C, R, S, bad, _ = _prepare(receivers, path_lengths, source, 2, "solve_point")
    out_x, out_res, out_gd, out_reason = _run_chunked(_point_core, C, R, S, axis, tol, max_gdop, fov)
    return _finish_point(out_x, out_res, out_gd, out_reason, bad, S)


def _run_chunked(core, C, R, S, axis, tol, max_gdop, fov):
    """Run a two-receiver-family solver core over the batch in chunks (bounded memory), in
    the source's frame. Returns (solution (M,2), rms, gdop, reason codes)."""
    M = R.shape[0]
    ax = _axis_array(axis, C, M)
    out = np.zeros((M, 2))
    out_res = np.zeros(M)
    out_gd = np.zeros(M)
    out_reason = np.zeros(M, np.int8)
    with np.errstate(all="ignore"):
        for k in range(0, M, _CHUNK):
            sl = slice(k, min(M, k + _CHUNK))
            Cr = C[sl] - S[sl][:, None, :]
            out[sl], out_res[sl], out_gd[sl], out_reason[sl] = core(Cr, R[sl], ax[sl], tol, max_gdop, fov)
    return out, out_res, out_gd, out_reason


def _finish_point(x, res, gd, reason, bad, S):
    reason = np.where(bad, BADIN, reason).astype(np.int8)
    fin = np.all(np.isfinite(x), axis=1) & np.isfinite(res)
    reason = np.where((reason == OK) & ~fin, NOCONV, reason).astype(np.int8)
    valid = reason == OK
    x = np.where(valid[:, None], x, 0.0)
    rng = np.where(valid, _norm(x), 0.0)
    brg = np.where(valid, np.arctan2(x[:, 1], x[:, 0]), 0.0)
    pos = np.where(valid[:, None], x + S, 0.0)
    return PointBatch(valid=valid, reason=reason, position=pos, range=rng, bearing=brg,
                      residual=np.where(valid, res, 0.0), gdop=np.where(valid, gd, 0.0))


def solve_point(receivers, path_lengths, source=(0.0, 0.0), *, axis=None,
                tol: float = DEFAULT_TOL, max_gdop: float = DEFAULT_MAX_GDOP,
                fov: float = DEFAULT_FOV) -> PointFit:
    """Point reflector (edge, thin rod) from N >= 2 path lengths; see the module docstring.

    Two receivers: the two ellipse intersections are both exact; the one whose bearing from
    the source is closer to ``axis`` (default: receivers' mean outward direction from the
    robot origin) is returned. N >= 3: Gauss-Newton least squares from both candidates of
    the best-conditioned pair, lowest misfit wins, the axis only breaks true ties.
    """
    c = np.asarray(receivers, np.float64)
    r = np.asarray(path_lengths, np.float64)
    if c.ndim != 2 or r.ndim != 1:
        raise ValueError(f"solve_point: receivers (N,2) and path_lengths (N,) expected, got {c.shape}, {r.shape}")
    b = solve_point_batch(c, r, source, axis=axis, tol=tol, max_gdop=max_gdop, fov=fov)
    return PointFit(valid=bool(b.valid[0]), reason=REASONS[b.reason[0]], position=b.position[0].copy(),
                    range=float(b.range[0]), bearing=float(b.bearing[0]), residual=float(b.residual[0]),
                    gdop=float(b.gdop[0]))


# --------------------------------------------------------------------------------------
# wall
# --------------------------------------------------------------------------------------


def _wall_core(C, R, axis, tol, max_gdop, fov=None):
    M, N, _ = C.shape
    pre = _short_paths(C, R)
    if N == 2:
        i, j = np.zeros(M, int), np.ones(M, int)
    else:
        i, j = _pick_pair_far(C)
    ar = np.arange(M)
    cand, deg = _circle_pair(C[ar, i], C[ar, j], R[ar, i], R[ar, j])
    scale = np.max(R, axis=1)
    Ck = np.broadcast_to(C[:, None], (M, 2, N, 2))
    Rk = np.broadcast_to(R[:, None], (M, 2, N))
    m, rms, gd, okm, _ = _gauss_newton(_wall_model, cand, Ck, Rk, iters=6 if N == 2 else 12,
                                       scale=scale[:, None])
    d = 0.5 * _norm(m)
    nh, _ = _unit(m)
    # physical: source and every receiver strictly on the near side of the wall line
    proj = np.einsum("mkj,mnj->mkn", nh, C)
    ok = okm & (d > 0.0) & np.all(proj < d[..., None], axis=-1) & ~deg[:, None]
    ang = np.arctan2(m[..., 1], m[..., 0])
    pre = np.where((pre == OK) & deg, DEGEN, pre).astype(np.int8)
    idx, reason = _select(m, ok, rms, gd, ang, axis, 2, N, tol, max_gdop, pre, scale, fov)
    return m[ar, idx], rms[ar, idx], 0.5 * gd[ar, idx], reason


def solve_wall_batch(receivers, path_lengths, source=(0.0, 0.0), *, axis=None,
                     tol: float = DEFAULT_TOL, max_gdop: float = DEFAULT_MAX_GDOP,
                fov: float = DEFAULT_FOV) -> WallBatch:
    """Vectorised :func:`solve_wall` (same conventions as :func:`solve_point_batch`)."""
    C, R, S, bad, _ = _prepare(receivers, path_lengths, source, 2, "solve_wall")
    out_m, out_res, out_gd, out_reason = _run_chunked(_wall_core, C, R, S, axis, tol, max_gdop, fov)
    reason = np.where(bad, BADIN, out_reason).astype(np.int8)
    fin = np.all(np.isfinite(out_m), axis=1) & np.isfinite(out_res)
    reason = np.where((reason == OK) & ~fin, NOCONV, reason).astype(np.int8)
    valid = reason == OK
    m = np.where(valid[:, None], out_m, 0.0)
    return WallBatch(valid=valid, reason=reason, distance=0.5 * _norm(m),
                     normal_angle=np.where(valid, np.arctan2(m[:, 1], m[:, 0]), 0.0),
                     foot=np.where(valid[:, None], 0.5 * m + S, 0.0),
                     residual=np.where(valid, out_res, 0.0), gdop=np.where(valid, out_gd, 0.0))


def solve_wall(receivers, path_lengths, source=(0.0, 0.0), *, axis=None,
               tol: float = DEFAULT_TOL, max_gdop: float = DEFAULT_MAX_GDOP,
                fov: float = DEFAULT_FOV) -> WallFit:
    """Infinite specular wall from N >= 2 path lengths (mirror-image method).

    ``distance`` is the perpendicular distance from the source to the wall line,
    ``normal_angle`` the bearing of the foot of that perpendicular. With two receivers (or
    receivers on one line) the mirror image has two solutions symmetric about the receivers'
    line; the one whose normal is closer to ``axis`` is returned (see module docstring).
    """
    c = np.asarray(receivers, np.float64)
    r = np.asarray(path_lengths, np.float64)
    if c.ndim != 2 or r.ndim != 1:
        raise ValueError(f"solve_wall: receivers (N,2) and path_lengths (N,) expected, got {c.shape}, {r.shape}")
    b = solve_wall_batch(c, r, source, axis=axis, tol=tol, max_gdop=max_gdop, fov=fov)
    return WallFit(valid=bool(b.valid[0]), reason=REASONS[b.reason[0]], distance=float(b.distance[0]),
                   normal_angle=float(b.normal_angle[0]), residual=float(b.residual[0]),
                   foot=b.foot[0].copy(), gdop=float(b.gdop[0]))


# --------------------------------------------------------------------------------------
# cylinder
# --------------------------------------------------------------------------------------

_A_MAX = 1e3  # radius cap (m): a fit pinned here is a wall
_CYL_START = (0.1, 3.0)  # start radii: x point range, x wall distance
_CYL_INNER = 4  # Newton iterations of the reflection angle inside the fit


def _cyl_model(th, C, R):
    """th (B,3) = (bearing, r0, radius); p = (r0 + a) u(bearing)."""
    beta, r0, a = th[:, 0], th[:, 1], th[:, 2]
    ux, uy = np.cos(beta), np.sin(beta)
    d = r0 + a
    p = np.stack([d * ux, d * uy], axis=-1)[:, None, :]
    L, n, cosi, ok = _specular(p, a[:, None], C, iters=_CYL_INNER)
    g = -2.0 * cosi
    nu = n[..., 0] * ux[:, None] + n[..., 1] * uy[:, None]
    nperp = -n[..., 0] * uy[:, None] + n[..., 1] * ux[:, None]
    J = np.stack([g * d[:, None] * nperp, g * nu, g * (nu + 1.0)], axis=-1)
    return L - R, J, np.all(ok, axis=-1)


def _cyl_project(th):
    return np.stack([th[:, 0], np.maximum(th[:, 1], 1e-6), np.clip(th[:, 2], 0.0, _A_MAX)], axis=-1)


def _cylinder_core(C, R, axis, tol, max_gdop, fov, radius=None, starts=None):
    M, N, _ = C.shape
    pre = _short_paths(C, R)
    scale = np.max(R, axis=1)
    if starts is None:
        xp, _, _, _ = _point_core(C, R, axis, np.inf, np.inf, fov)
        mw, _, _, _ = _wall_core(C, R, axis, np.inf, np.inf, fov)
        bp, rp = np.arctan2(xp[:, 1], xp[:, 0]), _norm(xp)
        bw, dw = np.arctan2(mw[:, 1], mw[:, 0]), 0.5 * _norm(mw)
        rp = np.where(rp > 0, rp, 0.5 * scale)
        dw = np.where(dw > 0, dw, 0.5 * scale)
        starts = np.stack([np.stack([bp, rp, _CYL_START[0] * rp], -1),
                           np.stack([bw, dw, _CYL_START[1] * dw], -1)], axis=1)
    K = starts.shape[1]
    if radius is not None:
        starts = starts.copy()
        starts[..., 2] = radius[:, None]
    Ck = np.broadcast_to(C[:, None], (M, K, N, 2))
    Rk = np.broadcast_to(R[:, None], (M, K, N))
    if radius is None:
        th, rms, _, ok, _ = _gauss_newton(_cyl_model, starts, Ck, Rk, iters=30,
                                          scale=scale[:, None], project=_cyl_project)
    else:
        # known radius: two parameters (bearing, r0); the radius rides along as an extra
        # column of R (and a dummy receiver row of C) so the compacting GN keeps it per row
        def model_pinned(t, Cc, Rr):
            th3 = np.concatenate([t, Rr[:, -1:]], axis=-1)
            f, J, ok_ = _cyl_model(th3, Cc[:, :-1], Rr[:, :-1])
            return f, J[..., :2], ok_

        def pin(t):
            return np.stack([t[:, 0], np.maximum(t[:, 1], 1e-6)], axis=-1)

        Cx = np.concatenate([Ck, np.zeros((M, K, 1, 2))], axis=2)
        Rx = np.concatenate([Rk, np.broadcast_to(radius[:, None, None], (M, K, 1))], axis=2)
        t2, rms, _, ok, _ = _gauss_newton(model_pinned, starts[..., :2], Cx, Rx, iters=30,
                                          scale=scale[:, None], project=pin)
        th = np.concatenate([t2, np.broadcast_to(radius[:, None, None], (M, K, 1))], axis=-1)
    ar = np.arange(M)
    big = np.where(ok, rms, np.inf)
    k = np.argmin(big, axis=1)
    th_b = th[ar, k]
    # several distinct solutions that all explain the data (exactly determined N = 3 can
    # have more than one): ambiguous
    dd = th[..., 1] + th[..., 2]
    cen = np.stack([dd * np.cos(th[..., 0]), dd * np.sin(th[..., 0])], -1)
    fits = ok & (rms <= tol)
    dist = np.maximum(_norm(cen - cen[ar, k][:, None]), np.abs(th[..., 2] - th_b[:, None, 2]))
    n_distinct = np.sum(fits & (dist > 1e-6 * scale[:, None]), axis=1)
    rms_b = rms[ar, k]
    ok_b = ok[ar, k]
    # metric gdop: bearing column in metres of arc
    f, J, _ = _cyl_model(th_b, C, R)
    Jm = J.copy()
    d = th_b[:, 1] + th_b[:, 2]
    Jm[..., 0] = J[..., 0] / np.where(d > 0, d, 1.0)[:, None]
    if radius is not None:
        _, gd = _ls_step(Jm[..., :2], f)
    else:
        _, gd = _ls_step(Jm, f)
    reason = np.zeros(M, np.int8)
    reason[~ok_b] = UNPHYS
    reason[(reason == OK) & ~(rms_b <= tol)] = INCONS if N > 3 - (radius is not None) else NOINT
    reason[(reason == OK) & (n_distinct > 0)] = AMBIG
    reason[(reason == OK) & ~(gd <= max_gdop)] = ILLCOND
    off = np.abs(_wrap(th_b[:, 0] - axis))
    reason[(reason == OK) & np.isfinite(axis) & ~(off <= fov + 0.5 * np.pi)] = UNPHYS
    reason = np.where(pre != OK, pre, reason).astype(np.int8)
    return th_b, rms_b, gd, reason


def solve_cylinder_batch(receivers, path_lengths, source=(0.0, 0.0), *, radius=None, axis=None,
                         tol: float = DEFAULT_TOL, max_gdop: float = DEFAULT_MAX_GDOP,
                         fov: float = DEFAULT_FOV) -> CylinderBatch:
    """Vectorised :func:`solve_cylinder`. ``radius`` None (fit it, N >= 3), scalar or (M,)."""
    C, R, S, bad, _ = _prepare(receivers, path_lengths, source, 2 if radius is not None else 3,
                               "solve_cylinder")
    M = R.shape[0]
    ax = _axis_array(axis, C, M)
    rad = None
    if radius is not None:
        rad = np.broadcast_to(np.asarray(radius, np.float64), (M,)).copy()
        if not np.all(np.isfinite(rad)) or np.any(rad < 0):
            raise ValueError("solve_cylinder: radius must be finite and >= 0")
    out = np.zeros((M, 3))
    out_res = np.zeros(M)
    out_gd = np.zeros(M)
    out_reason = np.zeros(M, np.int8)
    with np.errstate(all="ignore"):
        for k in range(0, M, _CHUNK // 4):
            sl = slice(k, min(M, k + _CHUNK // 4))
            Cr = C[sl] - S[sl][:, None, :]
            th, res, gd, rsn = _cylinder_core(Cr, R[sl], ax[sl], tol, max_gdop, fov,
                                              radius=None if rad is None else rad[sl])
            out[sl], out_res[sl], out_gd[sl], out_reason[sl] = th, res, gd, rsn
    reason = np.where(bad, BADIN, out_reason).astype(np.int8)
    fin = np.all(np.isfinite(out), axis=1) & np.isfinite(out_res) & np.isfinite(out_gd)
    reason = np.where((reason == OK) & ~fin, NOCONV, reason).astype(np.int8)
    valid = reason == OK
    th = np.where(valid[:, None], out, 0.0)
    d = th[:, 1] + th[:, 2]
    centre = np.stack([d * np.cos(th[:, 0]), d * np.sin(th[:, 0])], -1)
    return CylinderBatch(valid=valid, reason=reason, centre=np.where(valid[:, None], centre + S, 0.0),
                         radius=th[:, 2], range=th[:, 1], bearing=th[:, 0],
                         residual=np.where(valid, out_res, 0.0), gdop=np.where(valid, out_gd, 0.0))


def solve_cylinder(receivers, path_lengths, source=(0.0, 0.0), radius=None, *, axis=None,
                   tol: float = DEFAULT_TOL, max_gdop: float = DEFAULT_MAX_GDOP,
                   fov: float = DEFAULT_FOV) -> CylinderFit:
    """Specular circle (pillar, person, rod with non-zero radius).

    Unknown radius (N >= 3): Gauss-Newton over (bearing, r0, radius) from three starts (the
    point fit with radius 0 and 0.3*range, the wall fit with radius 3*distance), best misfit
    wins; radius is kept in [0, 1000 m] (0 = an edge, 1000 m = a wall). Known radius: two
    unknowns, N >= 2. ``range`` is the distance from the source to the nearest point of the
    circle, ``bearing`` that of the centre from the source.
    """
    c = np.asarray(receivers, np.float64)
    r = np.asarray(path_lengths, np.float64)
    if c.ndim != 2 or r.ndim != 1:
        raise ValueError(f"solve_cylinder: receivers (N,2) and path_lengths (N,) expected, got {c.shape}, {r.shape}")
    b = solve_cylinder_batch(c, r, source, radius=radius, axis=axis, tol=tol, max_gdop=max_gdop, fov=fov)
    return CylinderFit(valid=bool(b.valid[0]), reason=REASONS[b.reason[0]], centre=b.centre[0].copy(),
                       radius=float(b.radius[0]), residual=float(b.residual[0]), range=float(b.range[0]),
                       bearing=float(b.bearing[0]), gdop=float(b.gdop[0]))


# --------------------------------------------------------------------------------------
# classification
# --------------------------------------------------------------------------------------

KINDS: tuple[str, ...] = ("edge", "wall", "cylinder", "uncertain")
#: Default path-length noise: 1 us of time of flight at 20 degC (~0.34 mm).
DEFAULT_NOISE_SIGMA = 331.3 * math.sqrt(1.0 + 20.0 / 273.15) * 1e-6
#: With the edge and the wall model both accepted, the one whose chi-square is lower by more
#: than this wins (likelihood ratio 100 between equal-size models), else 'uncertain'.
LR_GAP = 9.21


def decide_kind(edge: Any, wall: Any, cylinder: Any, gap: Any) -> np.ndarray:
    """KINDS index of :func:`classify`'s decision from the accept tests of the edge, wall and
    cylinder models and the chi-square gap edge - wall (arrays of one shape, or scalars)."""
    e, w, cy = np.asarray(edge, bool), np.asarray(wall, bool), np.asarray(cylinder, bool)
    both = e & w
    return np.select([e & ~w, w & ~e, both & (gap < -LR_GAP), both & (gap > LR_GAP), ~e & ~w & cy],
                     [0, 1, 0, 1, 2], 3).astype(np.int8)


def _chi2_quantile(p: float, k: np.ndarray) -> np.ndarray:
    """Chi-square quantile (Wilson-Hilferty, good to ~1% for k >= 1); 0 for k <= 0."""
    # inverse normal by bisection on erf (scalar p)
    lo, hi = -10.0, 10.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if 0.5 * (1.0 + math.erf(mid / math.sqrt(2.0))) < p:
            lo = mid
        else:
            hi = mid
    z = 0.5 * (lo + hi)
    k = np.asarray(k, np.float64)
    ks = np.maximum(k, 1.0)
    q = ks * (1.0 - 2.0 / (9.0 * ks) + z * np.sqrt(2.0 / (9.0 * ks))) ** 3
    return np.where(k > 0, q, 0.0)


@dataclass(frozen=True)
class ClassifyBatch:
    kind: np.ndarray  # (M,) int8 codes into KINDS
    chi2: np.ndarray  # (M,3) edge, wall, cylinder: sum(f^2)/sigma^2
    threshold: np.ndarray  # (3,) acceptance thresholds
    accepted: np.ndarray  # (M,3) bool: model explains the data within the noise


def classify_batch(receivers, path_lengths, source=(0.0, 0.0), *, noise_sigma: float = DEFAULT_NOISE_SIGMA,
                   axis=None, confidence: float = 0.999, fov: float = DEFAULT_FOV) -> ClassifyBatch:
    """Vectorised :func:`classify` (N >= 3)."""
    if not (noise_sigma > 0 and math.isfinite(noise_sigma)):
        raise ValueError(f"classify: noise_sigma must be a positive finite number, got {noise_sigma!r}")
    if not 0.5 < confidence < 1.0:
        raise ValueError(f"classify: confidence must be in (0.5, 1), got {confidence!r}")
    C, R, S, bad, _ = _prepare(receivers, path_lengths, source, 3, "classify")
    M, N = R.shape
    ax = _axis_array(axis, C, M)
    thr = np.array([_chi2_quantile(confidence, N - 2), _chi2_quantile(confidence, N - 2),
                    _chi2_quantile(confidence, N - 3)])
    if N == 3:  # exactly determined cylinder: accept an exact (converged) fit only
        thr[2] = 1e-6
    chi2 = np.zeros((M, 3))
    acc = np.zeros((M, 3), bool)
    kind = np.full(M, 3, np.int8)
    with np.errstate(all="ignore"):
        for k in range(0, M, _CHUNK // 4):
            sl = slice(k, min(M, k + _CHUNK // 4))
            Cr = C[sl] - S[sl][:, None, :]
            Rs = R[sl]
            _, rp, _, sp = _point_core(Cr, Rs, ax[sl], np.inf, np.inf, fov)
            _, rw, _, sw = _wall_core(Cr, Rs, ax[sl], np.inf, np.inf, fov)
            th, rc, _, sc = _cylinder_core(Cr, Rs, ax[sl], np.inf, np.inf, fov)
            x2 = np.stack([rp, rw, rc], -1) ** 2 * N / noise_sigma ** 2
            x2 = np.where(np.isfinite(x2), x2, np.inf)
            okm = np.stack([(sp == OK) | (sp == AMBIG), (sw == OK) | (sw == AMBIG),
                            (sc == OK) & (th[:, 2] > 0.0) & (th[:, 2] < 0.5 * _A_MAX)], -1)
            a = okm & (x2 <= thr)
            kd = decide_kind(a[:, 0], a[:, 1], a[:, 2], x2[:, 0] - x2[:, 1])
            chi2[sl], acc[sl], kind[sl] = np.where(np.isfinite(x2), x2, 1e300), a, kd
    kind = np.where(bad, 3, kind).astype(np.int8)
    return ClassifyBatch(kind=kind, chi2=chi2, threshold=thr, accepted=acc & ~bad[:, None])


def classify(receivers, path_lengths, source=(0.0, 0.0), noise_sigma: float = DEFAULT_NOISE_SIGMA, *,
             axis=None, confidence: float = 0.999, fov: float = DEFAULT_FOV) -> Classification:
    """Edge / wall / cylinder decision from N >= 3 path lengths.

    Rule (simplest model that explains the data within the noise): fit all three models by
    least squares; model k is *accepted* when it is physical and its chi-square
    ``sum(f_i^2)/noise_sigma^2`` is within the ``confidence`` quantile of chi-square with
    N - p_k degrees of freedom (p = 2 for edge and wall, 3 for cylinder; with N = 3 the
    cylinder is exactly determined and accepted only if it fits exactly, radius in (0, 500 m)).
      * only the edge accepted -> 'edge'; only the wall -> 'wall';
      * both accepted -> the one whose chi-square is lower by more than LR_GAP = 9.21 (likelihood
        ratio 100) or else 'uncertain' (the array cannot see the curvature difference);
      * neither accepted but the cylinder -> 'cylinder' (edge and wall are its limits
        radius -> 0 and radius -> inf, so it is only chosen when both are rejected);
      * nothing accepted -> 'uncertain'.
    """
    c = np.asarray(receivers, np.float64)
    r = np.asarray(path_lengths, np.float64)
    if c.ndim != 2 or r.ndim != 1:
        raise ValueError(f"classify: receivers (N,2) and path_lengths (N,) expected, got {c.shape}, {r.shape}")
    b = classify_batch(c, r, source, noise_sigma=noise_sigma, axis=axis, confidence=confidence, fov=fov)
    kind = KINDS[b.kind[0]]
    names = ("edge", "wall", "cylinder")
    accd = [n for n, a in zip(names, b.accepted[0]) if a]
    chi = {n: float(x) for n, x in zip(names, b.chi2[0])}
    why = (f"accepted: {', '.join(accd) or 'none'}; chi2 " +
           ", ".join(f"{n}={chi[n]:.3g} (<= {t:.3g})" for n, t in zip(names, b.threshold)))
    big = np.inf
    return Classification(
        kind=kind, why=why,
        point=solve_point(c, r, source, axis=axis, tol=big, max_gdop=big, fov=fov),
        wall=solve_wall(c, r, source, axis=axis, tol=big, max_gdop=big, fov=fov),
        cylinder=solve_cylinder(c, r, source, axis=axis, tol=big, max_gdop=big, fov=fov),
        chi2=chi, threshold={n: float(t) for n, t in zip(names, b.threshold)})


def pair_candidates(receivers, path_lengths, source=(0.0, 0.0), kind: str = "point"):
    """Both exact solutions of a two-receiver system (before any choice).

    Returns (cand (M,2,2) in the robot frame — points, or wall feet for kind='wall',
    ok (M,2) bool: candidate exists and is physical). Used to audit 'ambiguous' answers.
    """
    C, R, S, bad, _ = _prepare(receivers, path_lengths, source, 2, "pair_candidates")
    if R.shape[1] != 2:
        raise ValueError("pair_candidates: exactly two receivers expected")
    C = C - S[:, None, :]
    with np.errstate(all="ignore"):
        if kind == "point":
            cand, ok, _ = _point_pair(C[:, 0], C[:, 1], R[:, 0], R[:, 1])
        elif kind == "wall":
            cand, deg = _circle_pair(C[:, 0], C[:, 1], R[:, 0], R[:, 1])
            ok = np.broadcast_to(~deg[:, None], (len(R), 2)).copy()
            cand = 0.5 * cand
        else:
            raise ValueError(f"pair_candidates: kind must be 'point' or 'wall', got {kind!r}")
    ok &= ~bad[:, None] & np.all(np.isfinite(cand), axis=-1)
    cand = np.where(ok[..., None], cand + S[:, None, :], 0.0)
    return cand, ok
