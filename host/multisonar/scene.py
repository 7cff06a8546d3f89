"""Declarative scenes: the world the acoustic simulator (and every test of the system) runs in.

A scene is a small YAML file under ``sim/scenes`` (or any path) holding the robot's layout and
trajectory, the reflectors (walls, point reflectors, cylinders, walking people), the air
temperature, the noise model and a seed. :func:`load_scene` parses and validates it and gives
a :class:`Scene` whose arrays the acoustic model (:mod:`multisonar.acoustics`) consumes.

File schema (every key optional unless marked; see ``sim/scenes/*.yaml`` for examples)::

    name: str                      # default: file stem
    description: str
    layout: ring24                 # layout name or path (multisonar.layout.load_layout)
    parameters: {name: number}     # defaults; load_scene(..., name=value) overrides them
    temperature_c: 20              # air temperature -> speed of sound
    seed: 0                        # default seed of the acoustic model's RNG
    duration_s: 1.0                # nominal length of the scene (default: end of motion or 1 s)
    footprint_margin: 0.05         # m; nothing may come closer to the robot origin than
                                   # (ring radius + margin) at any time
    trajectory:                    # robot pose waypoints, constant velocity in between
      - {t: 0, x: 0, y: 0, heading_deg: 0}     # first waypoint: t defaults to 0
      - {t: 1.5, x: 2, y: 0}                   # each later one needs t ...
      - {speed: 1.5, x: 2, y: 2, heading_deg: 90}  # ... or the speed of the segment into it
    walls:                         # specular segments (two-sided), world frame
      - {name: w, a: [x, y], b: [x, y], reflectivity: 1.0}
      - {name: w2, through: [x, y], direction_deg: 90, length: 3}
      - {name: room, polyline: [[x, y], [x, y], ...]}    # consecutive segments room.0, room.1..
    points:                        # edges and thin rods: isotropic point scatterers
      - {name: edge, at: [x, y], strength: 0.05}         # strength: m (see acoustics)
    cylinders:
      - {name: pillar, center: [x, y], radius: 0.1, reflectivity: 1.0}
    people:                        # cylinders moving along waypoints (same rules as trajectory)
      - {name: p, radius: 0.2, reflectivity: 0.5, path: [{t: 0, x: 1, y: -1}, {t: 2, x: 1, y: 1}]}
    noise:
      jitter_s: 1.0e-6             # Gaussian sigma of echo/crosstalk pulse start times
      spurious_rate_hz: 2.0        # Poisson rate of spurious comparator pulses per channel
      threshold: 0.01              # comparator threshold (amplitude units, see acoustics)
      fading_db: 1.5               # sigma of log-normal echo amplitude fading (echo loss)
    model:
      absorption_db_per_m: 1.3     # air absorption at 40 kHz
      beam_cutoff: 2.0             # main lobe ends at beam_cutoff * half-angle (zero beyond)
      second_order: true           # wall-wall double reflections
      occlusion: true              # walls, cylinders and people block paths
      crosstalk_level: 0.1         # direct crosstalk amplitude at the smallest element spacing
      crosstalk_exponent: 3.0      # ... falling as (spacing / distance) ** exponent
      ringdown_amplitude: 100.0
      width_min: 0.25              # comparator pulse width at threshold, in burst lengths
      width_max: 1.5               # ... saturating towards this for strong echoes

Numbers may be plain (in the unit the key names: metres for lengths, ``_deg`` degrees,
``_s`` seconds, ``_hz`` hertz, ``_c`` degrees Celsius, ``speed`` m/s), a string with an explicit
unit (``"100 mm"``, ``"0.5 rad"``, ``"2 us"``, ``"40 kHz"``) or an arithmetic expression over
the parameters (``"distance * cos(radians(bearing_deg))"``, optionally followed by a unit).
Every problem raises :class:`SceneError` naming the file, the key and what is wrong.
"""

from __future__ import annotations

import ast
import math
import operator
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .constants import DEFAULT_TEMPERATURE_C, speed_of_sound
from .layout import DEFAULT_LAYOUT, Layout, LayoutError, load_layout

#: Folder of the shipped scenes (``sim/scenes`` in the source tree).
SCENE_DIR = Path(__file__).resolve().parents[2] / "sim" / "scenes"

#: The robot is a 2 m/s platform (paper section I).
MAX_ROBOT_SPEED = 2.0
#: Walking / running people.
MAX_PERSON_SPEED = 3.0
_SPEED_TOL = 1e-9


class SceneError(ValueError):
    """A scene file is missing, malformed or physically inconsistent."""


# --------------------------------------------------------------------------------------------
# Value parsing: numbers, unit strings, expressions over parameters

_UNITS: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3},
    "angle": {"deg": 1.0, "rad": 180.0 / math.pi},  # canonical: degrees (keys end in _deg)
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9},
    "frequency": {"hz": 1.0, "khz": 1e3},
    "speed": {"m/s": 1.0, "km/h": 1.0 / 3.6},
    "temperature": {"degc": 1.0, "c": 1.0},
    "db": {"db": 1.0},
    "db_per_m": {"db/m": 1.0},
    "ratio": {},
    "count": {},
}
_ALL_UNITS = {u for table in _UNITS.values() for u in table}

_FUNCS: dict[str, Any] = {
    "sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin, "acos": math.acos,
    "atan": math.atan, "atan2": math.atan2, "sqrt": math.sqrt, "radians": math.radians,
    "degrees": math.degrees, "abs": abs, "min": min, "max": max, "hypot": math.hypot,
}
_CONSTS = {"pi": math.pi, "e": math.e}
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow, ast.Mod: operator.mod}
_UNOPS = {ast.USub: operator.neg, ast.UAdd: operator.pos}


def _eval_expr(text: str, params: dict[str, float], where: str) -> float:
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise SceneError(f"{where}: cannot parse expression {text!r} ({exc.msg})") from None

    def ev(node: ast.AST) -> float:
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            return _BINOPS[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNOPS:
            return _UNOPS[type(node.op)](ev(node.operand))
        if isinstance(node, ast.Name):
            if node.id in params:
                return float(params[node.id])
            if node.id in _CONSTS:
                return _CONSTS[node.id]
            raise SceneError(f"{where}: unknown name {node.id!r} in expression {text!r}; "
                             f"parameters: {sorted(params)}, constants: {sorted(_CONSTS)}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCS and not node.keywords:
            return float(_FUNCS[node.func.id](*[ev(a) for a in node.args]))
        raise SceneError(f"{where}: expression {text!r} uses unsupported syntax "
                         f"({type(node).__name__}); allowed: numbers, parameters, + - * / ** %, "
                         f"functions {sorted(_FUNCS)}")

    try:
        return ev(tree)
    except SceneError:
        raise
    except (ArithmeticError, ValueError, TypeError) as exc:
        raise SceneError(f"{where}: cannot evaluate {text!r}: {exc}") from None


class _Ctx:
    """Parsing context: file name for messages and the parameter values."""

    def __init__(self, source: str, params: dict[str, float]):
        self.source = source
        self.params = params

    def err(self, where: str, msg: str) -> SceneError:
        return SceneError(f"{self.source}: {where}: {msg}")

    def num(self, value: Any, where: str, dim: str, *, min_value: float | None = None,
            positive: bool = False, max_value: float | None = None) -> float:
        units = _UNITS[dim]
        if isinstance(value, bool) or value is None:
            raise self.err(where, f"expected a number ({_dim_help(dim)}), got {value!r}")
        if isinstance(value, (int, float)):
            x = float(value)
        elif isinstance(value, str):
            text = value.strip()
            scale = 1.0
            head, _, last = text.rpartition(" ")
            unit = (last if head else text).lower()
            if head and unit in _ALL_UNITS or (not head and unit in _ALL_UNITS and unit not in self.params):
                if unit not in units:
                    raise self.err(where, f"wrong unit {unit!r} in {value!r}: expected {_dim_help(dim)}")
                scale = units[unit]
                text = head.strip()
                if not text:
                    raise self.err(where, f"unit {unit!r} without a value")
            else:
                # a trailing token that is neither a known unit nor part of an expression
                if head and last.isalpha() and last not in self.params and last not in _CONSTS:
                    raise self.err(where, f"unknown unit {last!r}: expected {_dim_help(dim)}")
            try:
                x = float(text)
            except ValueError:
                x = _eval_expr(text, self.params, f"{self.source}: {where}")
            x *= scale
        else:
            raise self.err(where, f"expected a number ({_dim_help(dim)}), got {type(value).__name__} {value!r}")
        if not math.isfinite(x):
            raise self.err(where, f"value {value!r} is not finite")
        if positive and x <= 0:
            raise self.err(where, f"must be > 0, got {x:g}")
        if min_value is not None and x < min_value:
            raise self.err(where, f"must be >= {min_value:g}, got {x:g}")
        if max_value is not None and x > max_value:
            raise self.err(where, f"must be <= {max_value:g}, got {x:g}")
        return x

    def xy(self, value: Any, where: str) -> np.ndarray:
        if isinstance(value, dict) and set(value) == {"x", "y"}:
            value = [value["x"], value["y"]]
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise self.err(where, f"expected a point [x, y] in metres, got {value!r}")
        return np.array([self.num(value[0], f"{where}[0]", "length"), self.num(value[1], f"{where}[1]", "length")])

    def mapping(self, value: Any, where: str, allowed: set[str], required: set[str] = frozenset()) -> dict:
        if not isinstance(value, dict):
            raise self.err(where, f"expected a mapping with keys from {sorted(allowed)}, got {value!r}")
        unknown = set(value) - allowed
        if unknown:
            raise self.err(where, f"unknown key(s) {sorted(map(str, unknown))}; allowed: {sorted(allowed)}")
        missing = set(required) - set(value)
        if missing:
            raise self.err(where, f"missing key(s) {sorted(missing)}")
        return value

    def seq(self, value: Any, where: str) -> list:
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.err(where, f"expected a list, got {type(value).__name__} {value!r}")
        return value

    def flag(self, value: Any, where: str) -> bool:
        if not isinstance(value, bool):
            raise self.err(where, f"expected true or false, got {value!r}")
        return value


def _dim_help(dim: str) -> str:
    units = _UNITS[dim]
    return f"{dim} in {sorted(units)}" if units else "a plain number"


# --------------------------------------------------------------------------------------------
# Scene data


@dataclass(frozen=True)
class Noise:
    jitter_s: float = 1.0e-6
    spurious_rate_hz: float = 2.0
    threshold: float = 0.01
    fading_db: float = 1.5


@dataclass(frozen=True)
class ModelOptions:
    absorption_db_per_m: float = 1.3
    beam_cutoff: float = 2.0
    second_order: bool = True
    occlusion: bool = True
    crosstalk_level: float = 0.1
    crosstalk_exponent: float = 3.0
    ringdown_amplitude: float = 100.0
    width_min: float = 0.25
    width_max: float = 1.5


_NOISE_DIMS = {"jitter_s": "time", "spurious_rate_hz": "frequency", "threshold": "ratio", "fading_db": "db"}
_MODEL_DIMS = {"absorption_db_per_m": "db_per_m", "beam_cutoff": "ratio", "second_order": "bool",
               "occlusion": "bool", "crosstalk_level": "ratio", "crosstalk_exponent": "ratio",
               "ringdown_amplitude": "ratio", "width_min": "ratio", "width_max": "ratio"}


@dataclass(frozen=True, eq=False)
class Path2D:
    """Piecewise-linear motion through waypoints (clamped before the first / after the last)."""

    t: np.ndarray  # (K,) strictly increasing (K == 1: static)
    xy: np.ndarray  # (K, 2)

    def at(self, t: Any) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        if self.t.size == 1:
            return np.broadcast_to(self.xy[0], t.shape + (2,)).copy()
        x, y = self._columns
        out = np.empty(t.shape + (2,))  # np.stack of the two interpolations, without its overhead
        out[..., 0] = np.interp(t, self.t, x)
        out[..., 1] = np.interp(t, self.t, y)
        return out

    @cached_property
    def _columns(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y of the waypoints as contiguous arrays (what np.interp works on)."""
        return np.ascontiguousarray(self.xy[:, 0]), np.ascontiguousarray(self.xy[:, 1])

    def speeds(self) -> np.ndarray:
        if self.t.size < 2:
            return np.zeros(0)
        return np.linalg.norm(np.diff(self.xy, axis=0), axis=1) / np.diff(self.t)


@dataclass(frozen=True, eq=False)
class Person:
    name: str
    radius: float
    reflectivity: float
    path: Path2D


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene. All coordinates are world frame, metres, radians, seconds."""

    name: str
    description: str
    layout: Layout
    parameters: dict[str, float]
    temperature_c: float
    seed: int
    duration_s: float
    footprint_margin: float
    trajectory_t: np.ndarray  # (K,)
    trajectory_pose: np.ndarray  # (K, 3): x, y, heading (rad, unwrapped as written)
    walls: np.ndarray  # (W, 2, 2): endpoints a, b
    wall_names: tuple[str, ...]
    wall_reflectivity: np.ndarray  # (W,)
    points: np.ndarray  # (P, 2)
    point_names: tuple[str, ...]
    point_strength: np.ndarray  # (P,) m
    cylinders: np.ndarray  # (C, 2)
    cylinder_radius: np.ndarray  # (C,)
    cylinder_names: tuple[str, ...]
    cylinder_reflectivity: np.ndarray  # (C,)
    people: tuple[Person, ...]
    noise: Noise
    model: ModelOptions
    source: Path | None = None
    doc: dict = field(default_factory=dict, repr=False, compare=False)

    # ---- derived quantities
    @property
    def speed_of_sound(self) -> float:
        return speed_of_sound(self.temperature_c)

    @property
    def footprint_radius(self) -> float:
        return float(np.max(np.linalg.norm(self.layout.positions, axis=1))) + self.footprint_margin

    @property
    def n_reflectors(self) -> int:
        return len(self.wall_names) + len(self.point_names) + len(self.cylinder_names) + len(self.people)

    @property
    def reflector_names(self) -> tuple[str, ...]:
        """Names in reflector-index order: walls, points, cylinders, people (the ``source``
        field of echo pulses indexes this tuple)."""
        return self.wall_names + self.point_names + self.cylinder_names + tuple(p.name for p in self.people)

    def reflector_index(self, name: str) -> int:
        try:
            return self.reflector_names.index(name)
        except ValueError:
            raise KeyError(f"scene {self.name!r} has no reflector {name!r}; reflectors: {self.reflector_names}") from None

    @property
    def is_static(self) -> bool:
        return bool(np.all(self.trajectory_pose == self.trajectory_pose[0]))

    # ---- motion
    # pose(), velocity() and element_poses() run thousands of times per second in the acoustic
    # model's inner loops, so the per-scene constants they need are computed once (a scene's
    # arrays are treated as immutable after loading).
    @cached_property
    def _trajectory_columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x, y, heading of the waypoints as contiguous arrays (what np.interp works on)."""
        return tuple(np.ascontiguousarray(self.trajectory_pose[:, k]) for k in range(3))  # type: ignore[return-value]

    @cached_property
    def _segment_rates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """vx, vy, heading rate of each segment, padded with a zero entry at both ends so that
        ``searchsorted(trajectory_t, t, side="right")`` indexes them directly (no motion before
        the first waypoint and from the last one on)."""
        tt, p = self.trajectory_t, self.trajectory_pose
        rates = np.diff(p, axis=0) / np.diff(tt)[:, None]
        padded = np.concatenate([np.zeros((1, 3)), rates, np.zeros((1, 3))])
        return tuple(np.ascontiguousarray(padded[:, k]) for k in range(3))  # type: ignore[return-value]

    def pose(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Robot pose (x, y, heading) at scene time(s) ``t`` (any shape, vectorised)."""
        t = np.asarray(t, dtype=np.float64)
        tt, p = self.trajectory_t, self.trajectory_pose
        if tt.size == 1:
            return tuple(np.full(t.shape, p[0, k]) for k in range(3))  # type: ignore[return-value]
        return tuple(np.interp(t, tt, col) for col in self._trajectory_columns)  # type: ignore[return-value]

    def velocity(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Robot velocity (vx, vy, heading rate) at ``t`` (right-continuous at waypoints)."""
        t = np.asarray(t, dtype=np.float64)
        tt = self.trajectory_t
        if tt.size == 1:
            return tuple(np.zeros(t.shape) for _ in range(3))  # type: ignore[return-value]
        seg = np.searchsorted(tt, t, side="right")
        if t.ndim == 0:
            return tuple(np.asarray(r[seg]) for r in self._segment_rates)  # type: ignore[return-value]
        return tuple(r.take(seg) for r in self._segment_rates)  # type: ignore[return-value]

    def element_poses(self, t: Any, elements: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """World positions (..., E, 2) and axis angles (..., E) of elements at time(s) t.

        With ``elements`` an int array broadcastable against ``t``, one element per time."""
        return self.place_elements(*self.pose(t), elements)

    def place_elements(self, x: Any, y: Any, h: Any, elements: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`element_poses` for robot poses (x, y, heading) already looked up with
        :meth:`pose` (callers that also need the robot pose look the trajectory up once)."""
        if elements is None:
            pos, ax = self.layout.positions, self.layout.axes
            x, y, h = x[..., None], y[..., None], h[..., None]
        else:
            idx = np.asarray(elements, dtype=np.intp)
            pos, ax = self.layout.positions.take(idx, axis=0), self.layout.axes.take(idx)
        c, s = np.cos(h), np.sin(h)
        px, py = pos[..., 0], pos[..., 1]
        wx = x + c * px - s * py
        wy = y + s * px + c * py
        xy = np.empty(np.shape(wx) + (2,))  # np.stack([wx, wy], axis=-1), without its overhead
        xy[..., 0] = wx
        xy[..., 1] = wy
        return xy, h + ax

    def people_positions(self, t: Any) -> np.ndarray:
        """Centres of all people at time(s) t: shape t.shape + (n_people, 2)."""
        t = np.asarray(t, dtype=np.float64)
        if not self.people:
            return np.zeros(t.shape + (0, 2))
        return np.stack([p.path.at(t) for p in self.people], axis=-2)

    def with_options(self, **changes: Any) -> Scene:
        """Copy with Noise/ModelOptions fields or top-level fields replaced (no re-validation
        of geometry; use load_scene overrides for anything that moves reflectors)."""
        noise = {k: v for k, v in changes.items() if k in _NOISE_DIMS}
        model = {k: v for k, v in changes.items() if k in _MODEL_DIMS}
        top = {k: v for k, v in changes.items() if k not in noise and k not in model}
        return replace(self, noise=replace(self.noise, **noise), model=replace(self.model, **model), **top)


# --------------------------------------------------------------------------------------------
# Loading and validation

_TOP_KEYS = {"name", "description", "layout", "parameters", "temperature_c", "seed", "duration_s",
             "footprint_margin", "trajectory", "walls", "points", "cylinders", "people", "noise", "model"}
_OVERRIDABLE_TOP = {"name", "layout", "temperature_c", "seed", "duration_s", "footprint_margin"}
_WAYPOINT_KEYS = {"t", "speed", "x", "y", "heading_deg"}
_PATH_KEYS = {"t", "speed", "x", "y"}
_WALL_FORMS = ({"a", "b"}, {"through", "direction_deg", "length"}, {"polyline"})
_WALL_KEYS = {"name", "reflectivity"} | set().union(*_WALL_FORMS)
_POINT_KEYS = {"name", "at", "strength"}
_CYL_KEYS = {"name", "center", "radius", "reflectivity"}
_PERSON_KEYS = {"name", "radius", "reflectivity", "path"}


def _resolve(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml") or p.exists():
        return p
    return SCENE_DIR / f"{name_or_path}.yaml"


def available_scenes() -> list[str]:
    """Names of the scenes shipped in ``sim/scenes``."""
    return sorted(p.stem for p in SCENE_DIR.glob("*.yaml"))


def load_scene(name_or_path: str | Path, **overrides: Any) -> Scene:
    """Load and validate a scene by name (``sim/scenes/<name>.yaml``) or path.

    ``overrides``: values for entries of the scene's ``parameters:``, top-level keys
    (name, layout, temperature_c, seed, duration_s, footprint_margin), ``noise=`` / ``model=``
    mappings merged into those sections, or single noise/model keys (``jitter_s=0``).
    """
    path = _resolve(name_or_path)
    if not path.is_file():
        raise SceneError(f"scene {str(name_or_path)!r} not found (looked for {path}); "
                         f"known scenes: {available_scenes()}")
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise SceneError(f"{path}: not valid YAML: {exc}") from None
    return parse_scene(doc, source=path, **overrides)


def parse_scene(doc: Any, source: str | Path = "<scene>", **overrides: Any) -> Scene:
    """Validate a scene given as a mapping (the parsed YAML); see :func:`load_scene`."""
    src = str(source)
    if not isinstance(doc, dict):
        raise SceneError(f"{src}: expected a mapping at top level, got {type(doc).__name__}")
    unknown = set(doc) - _TOP_KEYS
    if unknown:
        raise SceneError(f"{src}: unknown key(s) {sorted(map(str, unknown))}; allowed: {sorted(_TOP_KEYS)}")
    doc = dict(doc)

    # parameters and overrides
    ctx0 = _Ctx(src, {})
    raw_params = doc.get("parameters") or {}
    if not isinstance(raw_params, dict):
        raise ctx0.err("parameters", f"expected a mapping name -> number, got {raw_params!r}")
    params: dict[str, float] = {}
    for k, v in raw_params.items():
        if not isinstance(k, str) or not k.isidentifier() or k in _FUNCS or k in _CONSTS or k.lower() in _ALL_UNITS:
            raise ctx0.err(f"parameters.{k}", "parameter names must be identifiers and not a function, constant or unit name")
        params[k] = ctx0.num(v, f"parameters.{k}", "ratio")
    noise_over: dict[str, Any] = {}
    model_over: dict[str, Any] = {}
    for k, v in overrides.items():
        if k in params:
            params[k] = ctx0.num(v, f"override {k}", "ratio")
        elif k in _OVERRIDABLE_TOP:
            doc[k] = v
        elif k in ("noise", "model"):
            if not isinstance(v, dict):
                raise ctx0.err(f"override {k}", f"expected a mapping, got {v!r}")
            (noise_over if k == "noise" else model_over).update(v)
        elif k in _NOISE_DIMS:
            noise_over[k] = v
        elif k in _MODEL_DIMS:
            model_over[k] = v
        else:
            raise ctx0.err(f"override {k!r}", f"unknown override; parameters of this scene: {sorted(params)}; "
                           f"also allowed: {sorted(_OVERRIDABLE_TOP | {'noise', 'model'} | set(_NOISE_DIMS) | set(_MODEL_DIMS))}")
    ctx = _Ctx(src, params)

    # layout, air
    layout_name = doc.get("layout", DEFAULT_LAYOUT)
    if not isinstance(layout_name, str):
        raise ctx.err("layout", f"expected a layout name or path, got {layout_name!r}")
    lp = Path(layout_name)
    if not lp.is_absolute() and isinstance(source, Path) and lp.suffix in (".yaml", ".yml"):
        lp = source.parent / lp
        layout_name = str(lp)
    try:
        layout = load_layout(layout_name)
    except LayoutError as exc:
        raise ctx.err("layout", str(exc)) from None
    temperature = ctx.num(doc.get("temperature_c", DEFAULT_TEMPERATURE_C), "temperature_c", "temperature",
                          min_value=-50.0, max_value=70.0)
    seed = doc.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ctx.err("seed", f"expected a non-negative integer, got {seed!r}")
    margin = ctx.num(doc.get("footprint_margin", 0.05), "footprint_margin", "length", min_value=0.0)
    name = doc.get("name", Path(src).stem)
    description = doc.get("description", "")
    if not isinstance(name, str) or not isinstance(description, str):
        raise ctx.err("name/description", "must be strings")

    # trajectory
    traj = ctx.seq(doc["trajectory"], "trajectory") if "trajectory" in doc else [{"t": 0.0, "x": 0.0, "y": 0.0}]
    tt, pose = _parse_waypoints(ctx, traj, "trajectory", _WAYPOINT_KEYS, with_heading=True)
    speeds = Path2D(tt, pose[:, :2]).speeds()
    if speeds.size and speeds.max() > MAX_ROBOT_SPEED + _SPEED_TOL:
        k = int(np.argmax(speeds))
        raise ctx.err(f"trajectory[{k + 1}]", f"robot speed {speeds[k]:.3f} m/s from waypoint {k} to {k + 1} "
                      f"exceeds the platform's {MAX_ROBOT_SPEED} m/s")
    duration = ctx.num(doc.get("duration_s", max(float(tt[-1]), 1.0)), "duration_s", "time", positive=True)

    # reflectors
    names: set[str] = set()

    def take_name(item: dict, where: str, default: str) -> str:
        n = item.get("name", default)
        if not isinstance(n, str) or not n:
            raise ctx.err(f"{where}.name", f"expected a non-empty string, got {n!r}")
        if n in names:
            raise ctx.err(f"{where}.name", f"duplicate reflector name {n!r}")
        names.add(n)
        return n

    walls, wall_names, wall_refl = [], [], []
    for i, w in enumerate(ctx.seq(doc.get("walls"), "walls")):
        where = f"walls[{i}]"
        w = ctx.mapping(w, where, _WALL_KEYS)
        form = [f for f in _WALL_FORMS if f & set(w)]
        if len(form) != 1 or not form[0] <= set(w):
            raise ctx.err(where, "a wall is given by exactly one of: {a, b} | {through, direction_deg, length} | "
                          f"{{polyline}}; got keys {sorted(w)}")
        nm = take_name(w, where, f"wall{i}")
        refl = ctx.num(w.get("reflectivity", 1.0), f"{where}.reflectivity", "ratio", positive=True, max_value=1.0)
        if form[0] == {"a", "b"}:
            segs = [(ctx.xy(w["a"], f"{where}.a"), ctx.xy(w["b"], f"{where}.b"))]
            seg_names = [nm]
        elif form[0] == {"polyline"}:
            pts = ctx.seq(w["polyline"], f"{where}.polyline")
            if len(pts) < 2:
                raise ctx.err(f"{where}.polyline", "needs at least 2 points")
            xy = [ctx.xy(p, f"{where}.polyline[{k}]") for k, p in enumerate(pts)]
            segs = list(zip(xy[:-1], xy[1:]))
            seg_names = [f"{nm}.{k}" for k in range(len(segs))]
            for sn in seg_names:
                if sn in names:
                    raise ctx.err(f"{where}.name", f"duplicate reflector name {sn!r}")
                names.add(sn)
        else:
            c = ctx.xy(w["through"], f"{where}.through")
            ang = math.radians(ctx.num(w["direction_deg"], f"{where}.direction_deg", "angle"))
            half = 0.5 * ctx.num(w["length"], f"{where}.length", "length", positive=True)
            u = np.array([math.cos(ang), math.sin(ang)])
            segs = [(c - half * u, c + half * u)]
            seg_names = [nm]
        for k, (a, b) in enumerate(segs):
            if np.linalg.norm(b - a) < 1e-6:
                raise ctx.err(where, f"segment {k} has zero length (a == b == {a.tolist()})")
            walls.append(np.stack([a, b]))
            wall_refl.append(refl)
        wall_names += seg_names

    pts, pt_names, pt_strength = [], [], []
    for i, p in enumerate(ctx.seq(doc.get("points"), "points")):
        where = f"points[{i}]"
        p = ctx.mapping(p, where, _POINT_KEYS, {"at"})
        pt_names.append(take_name(p, where, f"point{i}"))
        pts.append(ctx.xy(p["at"], f"{where}.at"))
        pt_strength.append(ctx.num(p.get("strength", 0.05), f"{where}.strength", "length", positive=True))

    cyls, cyl_r, cyl_names, cyl_refl = [], [], [], []
    for i, c in enumerate(ctx.seq(doc.get("cylinders"), "cylinders")):
        where = f"cylinders[{i}]"
        c = ctx.mapping(c, where, _CYL_KEYS, {"center", "radius"})
        cyl_names.append(take_name(c, where, f"cylinder{i}"))
        cyls.append(ctx.xy(c["center"], f"{where}.center"))
        cyl_r.append(ctx.num(c["radius"], f"{where}.radius", "length", positive=True))
        cyl_refl.append(ctx.num(c.get("reflectivity", 1.0), f"{where}.reflectivity", "ratio", positive=True, max_value=1.0))

    people = []
    for i, p in enumerate(ctx.seq(doc.get("people"), "people")):
        where = f"people[{i}]"
        p = ctx.mapping(p, where, _PERSON_KEYS, {"path"})
        nm = take_name(p, where, f"person{i}")
        radius = ctx.num(p.get("radius", 0.2), f"{where}.radius", "length", positive=True)
        refl = ctx.num(p.get("reflectivity", 0.5), f"{where}.reflectivity", "ratio", positive=True, max_value=1.0)
        pt, pxy = _parse_waypoints(ctx, ctx.seq(p["path"], f"{where}.path"), f"{where}.path", _PATH_KEYS, with_heading=False)
        path = Path2D(pt, pxy[:, :2])
        sp = path.speeds()
        if sp.size and sp.max() > MAX_PERSON_SPEED + _SPEED_TOL:
            raise ctx.err(f"{where}.path", f"person speed {sp.max():.2f} m/s exceeds {MAX_PERSON_SPEED} m/s")
        people.append(Person(nm, radius, refl, path))

    noise = _parse_section(ctx, doc.get("noise"), noise_over, "noise", Noise, _NOISE_DIMS)
    model = _parse_section(ctx, doc.get("model"), model_over, "model", ModelOptions, _MODEL_DIMS)
    if model.width_min > model.width_max:
        raise ctx.err("model", f"width_min {model.width_min} > width_max {model.width_max}")

    scene = Scene(
        name=name, description=description, layout=layout, parameters=params, temperature_c=temperature,
        seed=seed, duration_s=duration, footprint_margin=margin, trajectory_t=tt, trajectory_pose=pose,
        walls=np.array(walls, dtype=np.float64).reshape(-1, 2, 2), wall_names=tuple(wall_names),
        wall_reflectivity=np.array(wall_refl, dtype=np.float64),
        points=np.array(pts, dtype=np.float64).reshape(-1, 2), point_names=tuple(pt_names),
        point_strength=np.array(pt_strength, dtype=np.float64),
        cylinders=np.array(cyls, dtype=np.float64).reshape(-1, 2), cylinder_radius=np.array(cyl_r, dtype=np.float64),
        cylinder_names=tuple(cyl_names), cylinder_reflectivity=np.array(cyl_refl, dtype=np.float64),
        people=tuple(people), noise=noise, model=model,
        source=Path(source) if isinstance(source, Path) else None, doc=doc,
    )
    _check_footprint(scene, src)
    return scene


def _parse_section(ctx: _Ctx, raw: Any, over: dict, where: str, cls: type, dims: dict[str, str]) -> Any:
    raw = dict(ctx.mapping(raw or {}, where, set(dims)))
    bad = set(over) - set(dims)
    if bad:
        raise ctx.err(f"override {where}", f"unknown key(s) {sorted(bad)}; allowed: {sorted(dims)}")
    raw.update(over)
    vals = {}
    for k, v in raw.items():
        if dims[k] == "bool":
            vals[k] = ctx.flag(v, f"{where}.{k}")
        else:
            vals[k] = ctx.num(v, f"{where}.{k}", dims[k], min_value=0.0)
    if where == "noise" and "threshold" in vals and vals["threshold"] <= 0:
        raise ctx.err("noise.threshold", f"must be > 0, got {vals['threshold']:g}")
    return cls(**vals)


def _parse_waypoints(ctx: _Ctx, items: list, where: str, allowed: set[str], *, with_heading: bool
                     ) -> tuple[np.ndarray, np.ndarray]:
    if not items:
        raise ctx.err(where, "needs at least one waypoint")
    ts: list[float] = []
    poses: list[list[float]] = []
    for k, wp in enumerate(items):
        w = f"{where}[{k}]"
        wp = ctx.mapping(wp, w, allowed)
        prev = poses[-1] if poses else [0.0, 0.0, 0.0]
        x = ctx.num(wp["x"], f"{w}.x", "length") if "x" in wp else prev[0]
        y = ctx.num(wp["y"], f"{w}.y", "length") if "y" in wp else prev[1]
        h = math.radians(ctx.num(wp["heading_deg"], f"{w}.heading_deg", "angle")) if "heading_deg" in wp else prev[2]
        if k == 0:
            if "speed" in wp:
                raise ctx.err(f"{w}.speed", "the first waypoint cannot have a speed (give t)")
            t = ctx.num(wp.get("t", 0.0), f"{w}.t", "time")
        else:
            if ("t" in wp) == ("speed" in wp):
                raise ctx.err(w, "each waypoint after the first needs exactly one of 't' (s) or 'speed' (m/s)")
            if "t" in wp:
                t = ctx.num(wp["t"], f"{w}.t", "time")
                if t <= ts[-1]:
                    raise ctx.err(f"{w}.t", f"times must increase: {t:g} s after {ts[-1]:g} s")
            else:
                v = ctx.num(wp["speed"], f"{w}.speed", "speed", positive=True)
                d = math.hypot(x - prev[0], y - prev[1])
                if d == 0:
                    raise ctx.err(f"{w}.speed", "a speed needs a waypoint at a different position (use t to wait)")
                t = ts[-1] + d / v
        ts.append(t)
        poses.append([x, y, h])
    return np.array(ts), np.array(poses)


# --------------------------------------------------------------------------------------------
# Footprint check (exact for piecewise-linear motion)


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points p (...,2) to segments a-b (...,2), broadcasting."""
    ab = b - a
    denom = np.sum(ab * ab, axis=-1)
    safe = np.where(denom > 0, denom, 1.0)
    u = np.clip(np.sum((p - a) * ab, axis=-1) / safe, 0.0, 1.0)
    u = np.where(denom > 0, u, 0.0)
    return np.linalg.norm(p - (a + u[..., None] * ab), axis=-1)


def _segments_intersect(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> np.ndarray:
    def cross(o, p, q):
        return (p[..., 0] - o[..., 0]) * (q[..., 1] - o[..., 1]) - (p[..., 1] - o[..., 1]) * (q[..., 0] - o[..., 0])
    d1, d2 = cross(c, d, a), cross(c, d, b)
    d3, d4 = cross(a, b, c), cross(a, b, d)
    return (d1 * d2 <= 0) & (d3 * d4 <= 0)


def _segment_segment_distance(a, b, c, d) -> np.ndarray:
    dist = np.minimum.reduce([_point_segment_distance(a, c, d), _point_segment_distance(b, c, d),
                              _point_segment_distance(c, a, b), _point_segment_distance(d, a, b)])
    return np.where(_segments_intersect(a, b, c, d), 0.0, dist)


def _check_footprint(scene: Scene, src: str) -> None:
    R = scene.footprint_radius
    tt = scene.trajectory_t
    xy = scene.trajectory_pose[:, :2]
    if tt.size == 1:
        ra, rb = xy[:1], xy[:1]
    else:
        ra, rb = xy[:-1], xy[1:]
    what = f"the robot footprint (ring radius + footprint_margin = {R:.3f} m)"
    for w, name in zip(scene.walls, scene.wall_names):
        d = _segment_segment_distance(ra, rb, w[0][None], w[1][None])
        if d.min() < R:
            raise SceneError(f"{src}: wall {name!r} comes within {d.min():.3f} m of the robot origin, inside {what}")
    for kind, centres, radii, names in (("point", scene.points, np.zeros(len(scene.points)), scene.point_names),
                                        ("cylinder", scene.cylinders, scene.cylinder_radius, scene.cylinder_names)):
        for c, r, name in zip(centres, radii, names):
            d = _point_segment_distance(c[None], ra, rb).min() - r
            if d < R:
                raise SceneError(f"{src}: {kind} {name!r} comes within {d:.3f} m of the robot origin, inside {what}")
    for p in scene.people:
        ts = np.union1d(tt, p.path.t)
        rel = p.path.at(ts) - np.stack(scene.pose(ts)[:2], axis=-1)
        a, b = (rel[:1], rel[:1]) if ts.size == 1 else (rel[:-1], rel[1:])
        d = _point_segment_distance(np.zeros(2), a, b).min() - p.radius
        if d < R:
            raise SceneError(f"{src}: person {p.name!r} comes within {d:.3f} m of the robot origin, inside {what}")
