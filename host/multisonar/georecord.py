"""Geometry records (docs/protocol.md section 6) computed on the host from first echoes.

One function, used wherever the host stands in for the device's geometry or checks it: the
simulated device fills its frames' geometry records with it, and ``multisonar demo`` compares
every firmware geometry record of the twin with the record this gives for the same pulse's
ToF records (``fw_vs_host`` in summary.json).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import protocol as P
from .constants import TICK_HZ


def receiver_shift(rx_cfg: Any, rxs: Any, n: int) -> int | None:
    """The firmware's re-aim shift of a pulse: the rotation round the ring of ``n`` elements,
    smallest in magnitude (ties: positive first), that maps the configured receivers ``rx_cfg``
    onto (a superset of) the receivers ``rxs`` its ToF records name; None if none does."""
    rxs = {int(e) for e in rxs}
    for k in sorted(range(-(n // 2), n - n // 2), key=abs):
        if rxs <= {(int(e) + k) % n for e in rx_cfg}:
            return k
    return None


def sensor_paths(layout: Any, sensor: Any, tofs: np.ndarray, c: float, shift: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Source position and path lengths (m) for ToF ticks ``tofs`` (pulses x receivers) of a
    resolved sensor whose groups are moved by ``shift`` elements round the ring (the firmware's
    re-aiming): a single transmitter is its own source; a phased group's wave leaves the virtual
    source min|c_j - s| / c before t0, and that source turns with the groups."""
    n = layout.n
    tx = [(int(e) + shift) % n for e in sensor.tx]
    pos = layout.positions
    paths = c * np.asarray(tofs, float) / TICK_HZ
    if len(tx) == 1:
        return np.asarray(pos[tx[0]], float), paths
    a = 2 * math.pi * shift / n
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    source = rot @ np.asarray(sensor.source, float)
    return source, paths + np.min(np.linalg.norm(pos[tx] - source, axis=1))


def geo_records(receivers: np.ndarray, paths: np.ndarray, source: np.ndarray) -> list[np.void | None]:
    """One GEO_DTYPE record per row of ``paths`` (m, receivers in ``receivers``' order, >= 3):
    the classification's kind, the winning model's fit (a cylinder reports its point fit), the
    quality 255 * (1 - chi2 / threshold); None where the fit is not finite. ``receivers`` (N,2)
    or one set per row (M,N,2), ``source`` (2,) or (M,2)."""
    from . import geometry

    C = np.asarray(receivers, float)
    paths = np.atleast_2d(np.asarray(paths, float))
    n_rx = paths.shape[1]
    with np.errstate(all="ignore"):
        cb = geometry.classify_batch(C, paths, source)
        pb = geometry.solve_point_batch(C, paths, source, tol=np.inf, max_gdop=np.inf)
        wb = geometry.solve_wall_batch(C, paths, source, tol=np.inf, max_gdop=np.inf)
    out: list[np.void | None] = []
    for m in range(len(paths)):
        g = np.zeros((), P.GEO_DTYPE)
        kind = int(cb.kind[m]) + 1  # KINDS index -> GEO_CLASSES index
        g["cls"], g["n_rx"] = kind, n_rx
        k = 1 if kind == 2 else 0
        thr = max(float(cb.threshold[k]), 1e-12)
        q = 1.0 - min(float(cb.chi2[m, k]) / thr, 1.0) if kind in (1, 2) else 0.0
        if kind == 2 and wb.valid[m]:
            xy, rng, brg, res = wb.foot[m], wb.distance[m], wb.normal_angle[m], wb.residual[m]
            g["normal"] = P.binary_angle(float(wb.normal_angle[m]))
        elif pb.valid[m]:
            xy, rng, brg, res = pb.position[m], pb.range[m], pb.bearing[m], pb.residual[m]
        else:
            g["cls"] = 4
            out.append(g)
            continue
        if not (np.all(np.isfinite(xy)) and math.isfinite(rng) and math.isfinite(res)):
            out.append(None)
            continue
        g["x_mm"], g["y_mm"] = (int(np.clip(round(float(v) * 1000), -32768, 32767)) for v in xy)
        g["range_mm"] = int(np.clip(round(float(rng) * 1000), 0, 65535))
        g["bearing"] = P.binary_angle(float(brg))
        g["quality"] = int(round(255 * max(q, 0.0)))
        g["residual_um"] = int(np.clip(round(float(res) * 1e6), 0, 65535))
        out.append(g)
    return out
