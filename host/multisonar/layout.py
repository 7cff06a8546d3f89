"""The sensor layout: one data file is the single source of element positions and axes.

Everything that depends on where the transducers are (golden model, acoustic simulator,
host driver, firmware header, RTL parameters) loads it through :func:`load_layout`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

#: Folder of the shipped layouts (``sim/layouts`` in the source tree).
LAYOUT_DIR = Path(__file__).resolve().parents[2] / "sim" / "layouts"
DEFAULT_LAYOUT = "ring24"


class LayoutError(ValueError):
    """A layout file is missing, malformed or physically inconsistent."""


@dataclass(frozen=True)
class Transducer:
    frequency_hz: float
    beam_half_angle: float  # rad
    ring_down_s: float


@dataclass(frozen=True)
class Layout:
    """Element geometry in the robot frame (x forward, y left, metres, radians CCW)."""

    name: str
    positions: np.ndarray  # (N, 2) float64, metres
    axes: np.ndarray  # (N,) float64, radians
    transducer: Transducer
    source: Path | None = None

    @property
    def n(self) -> int:
        return int(self.positions.shape[0])

    def spacing(self) -> np.ndarray:
        """Distance from each element to the next one (cyclic), metres."""
        return np.linalg.norm(np.roll(self.positions, -1, axis=0) - self.positions, axis=1)

    def neighbours(self, element: int, k: int = 1) -> list[int]:
        """Indices of the k elements on each side of ``element`` around the ring."""
        self._check_element(element)
        return [(element + d) % self.n for d in range(-k, k + 1) if d != 0]

    def _check_element(self, element: int) -> None:
        if not 0 <= element < self.n:
            raise LayoutError(f"element {element} does not exist: layout {self.name!r} has elements 0..{self.n - 1}")


_ELEMENT_KEYS = {"id", "x", "y", "axis_deg"}
_TOP_KEYS = {"name", "units", "transducer", "elements"}
_TRANSDUCER_KEYS = {"frequency_hz", "beam_half_angle_deg", "ring_down_s"}


def _resolve(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml") or p.exists():
        return p
    return LAYOUT_DIR / f"{name_or_path}.yaml"


def load_layout(name_or_path: str | Path = DEFAULT_LAYOUT) -> Layout:
    """Load a layout by name (from ``sim/layouts``) or by path to a YAML file."""
    path = _resolve(name_or_path)
    if not path.is_file():
        known = sorted(p.stem for p in LAYOUT_DIR.glob("*.yaml"))
        raise LayoutError(f"layout {str(name_or_path)!r} not found (looked for {path}); known layouts: {known}")
    doc = yaml.safe_load(path.read_text())
    if not isinstance(doc, dict):
        raise LayoutError(f"{path}: expected a mapping at top level")
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise LayoutError(f"{path}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    units = doc.get("units", {"length": "m", "angle": "deg"})
    if units != {"length": "m", "angle": "deg"}:
        raise LayoutError(f"{path}: units must be {{length: m, angle: deg}}, got {units}")
    td = doc.get("transducer") or {}
    bad = set(td) - _TRANSDUCER_KEYS
    if bad:
        raise LayoutError(f"{path}: unknown transducer key(s) {sorted(bad)}; allowed: {sorted(_TRANSDUCER_KEYS)}")
    transducer = Transducer(
        frequency_hz=float(td.get("frequency_hz", 40e3)),
        beam_half_angle=math.radians(float(td.get("beam_half_angle_deg", 30.0))),
        ring_down_s=float(td.get("ring_down_s", 1.5e-3)),
    )
    elements = doc.get("elements")
    if not isinstance(elements, list) or len(elements) < 1:
        raise LayoutError(f"{path}: 'elements' must be a non-empty list")
    pos, axes = [], []
    for k, e in enumerate(elements):
        if not isinstance(e, dict) or set(e) != _ELEMENT_KEYS:
            raise LayoutError(f"{path}: element #{k} must have exactly the keys {sorted(_ELEMENT_KEYS)}, got {e!r}")
        if e["id"] != k:
            raise LayoutError(f"{path}: element #{k} has id {e['id']}; ids must be 0..N-1 in order")
        vals = [float(e["x"]), float(e["y"]), float(e["axis_deg"])]
        if not all(math.isfinite(v) for v in vals):
            raise LayoutError(f"{path}: element {k} has a non-finite coordinate")
        pos.append(vals[:2])
        axes.append(math.radians(vals[2]))
    positions = np.asarray(pos, dtype=np.float64)
    d = np.linalg.norm(positions[:, None, :] - positions[None, :, :], axis=2) + np.eye(len(pos))
    if np.min(d) < 1e-3:
        i, j = np.unravel_index(np.argmin(d), d.shape)
        raise LayoutError(f"{path}: elements {i} and {j} are closer than 1 mm")
    return Layout(name=str(doc.get("name", path.stem)), positions=positions,
                  axes=np.asarray(axes, dtype=np.float64), transducer=transducer, source=path)
