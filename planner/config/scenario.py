"""Typed, validated configuration: target files and scenario files (TOML).

Every user mistake — unknown or missing field, wrong type, negative mass, inertia that is not
symmetric positive definite, a range with min > max — raises :class:`ConfigError` naming the file
and the dotted field (``scenario_I.toml: phases.approach_s: must be > 0, got -1``).

Degrees appear only here, in field names ending in ``_deg``/``_deg_s``; the loaded objects are SI.
Relative paths inside a file are relative to that file's folder.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.config.limits import MAX_CONFIG_BYTES, MAX_SHAPES, violation
from planner.errors import ConfigError
from planner.model.robot import RobotModel, load_robot
from planner.model.rotation import matrix_to_quat, rpy_to_matrix
from planner.model.shapes import Box, Capsule, PlacedShape, make_transform
from planner.model.target import TargetBody, TargetMotion, TargetState

Array = NDArray[np.float64]

_MISSING = object()


class _Table:
    """One TOML table being read: typed getters that name the field on error, and an unknown-key check."""

    def __init__(self, data: dict[str, Any], source: str, prefix: str = "") -> None:
        if not isinstance(data, dict):
            raise ConfigError(source, prefix or "(root)", "expected a table")
        self.data = data
        self.source = source
        self.prefix = prefix
        self.used: set[str] = set()

    def field(self, key: str) -> str:
        return f"{self.prefix}.{key}" if self.prefix else key

    def error(self, key: str, problem: str) -> ConfigError:
        return ConfigError(self.source, self.field(key), problem)

    def _get(self, key: str, default: Any) -> Any:
        self.used.add(key)
        if key in self.data:
            return self.data[key]
        if default is _MISSING:
            raise self.error(key, "missing required field")
        return default

    def number(self, key: str, default: Any = _MISSING, *, positive: bool = False,
               nonnegative: bool = False, integer: bool = False) -> float:
        value = self._get(key, default)
        if value is default and default is not _MISSING:
            return value
        kinds = (int,) if integer else (int, float)
        if isinstance(value, bool) or not isinstance(value, kinds):
            raise self.error(key, f"expected {'an integer' if integer else 'a number'}, got {short_repr(value)}")
        if not math.isfinite(value):
            raise self.error(key, f"must be finite, got {value!r}")
        if positive and not value > 0:
            raise self.error(key, f"must be > 0, got {value!r}")
        if nonnegative and value < 0:
            raise self.error(key, f"must be >= 0, got {value!r}")
        problem = violation(self.field(key), value)
        if problem:
            raise self.error(key, problem)
        return int(value) if integer else float(value)

    def string(self, key: str, default: Any = _MISSING, choices: tuple[str, ...] | None = None) -> str:
        value = self._get(key, default)
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {short_repr(value)}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(choices)}, got {short_repr(value)}")
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {short_repr(value)}")
        return value

    def vector(self, key: str, length: int, default: Any = _MISSING) -> Array:
        value = self._get(key, default)
        if value is default and default is not _MISSING:
            return None if default is None else np.asarray(default, dtype=float)
        if (not isinstance(value, list) or len(value) != length
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)):
            raise self.error(key, f"expected a list of {length} numbers, got {short_repr(value)}")
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise self.error(key, f"must be finite, got {value!r}")
        problem = violation(self.field(key), float(np.abs(arr).max()))
        if problem:
            raise self.error(key, f"every element {problem}")
        return arr

    def range_(self, key: str, default: Any = _MISSING) -> tuple[float, float]:
        lo, hi = self.vector(key, 2, default)
        if lo > hi:
            raise self.error(key, f"min > max ({lo} > {hi})")
        return float(lo), float(hi)

    def table(self, key: str, default: Any = _MISSING) -> _Table:
        value = self._get(key, {} if default is not _MISSING else _MISSING)
        return _Table(value, self.source, self.field(key))

    def tables(self, key: str, maximum: int | None = None) -> list[_Table]:
        value = self._get(key, _MISSING)
        if not isinstance(value, list) or not value:
            raise self.error(key, "expected a non-empty array of tables ([[...]])")
        if maximum is not None and len(value) > maximum:
            raise self.error(key, f"{len(value)} entries, at most {maximum} (sanity limit)")
        return [_Table(v, self.source, f"{self.field(key)}[{i}]") for i, v in enumerate(value)]

    def finish(self) -> None:
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            raise self.error(unknown[0], "unknown field")


def short_repr(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters (a 2-million-element list stays one short line)."""
    text = repr(value) if not isinstance(value, list) or len(value) <= limit else f"[{len(value)} items]"
    return text if len(text) <= limit else text[: limit - 1] + "…"


def parse_toml(text: str, source: str) -> dict[str, Any]:
    """``text`` parsed as TOML; anything that is not a sane config is a :class:`ConfigError` naming ``source``."""
    if len(text) > MAX_CONFIG_BYTES:
        raise ConfigError(source, "", f"{len(text)} characters: too large for a config (at most {MAX_CONFIG_BYTES})")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, "", f"not valid TOML ({exc})") from None
    except RecursionError:  # tomllib recurses once per nesting level of an array or inline table
        raise ConfigError(source, "", "not a config: arrays or tables nested too deeply") from None


def _read_toml(path: Path) -> tuple[dict[str, Any], str]:
    src = str(path)
    if not path.is_file():
        raise ConfigError(src, "", "file not found")
    if path.stat().st_size > MAX_CONFIG_BYTES:
        raise ConfigError(src, "", f"{path.stat().st_size} bytes: too large for a config (at most {MAX_CONFIG_BYTES})")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigError(src, "", "not valid TOML (not UTF-8 text)") from None
    return parse_toml(text, src), text


def _inertia_matrix(t: _Table, key: str) -> Array:
    value = t._get(key, _MISSING)
    if isinstance(value, list) and len(value) == 3 and all(isinstance(v, list) for v in value):
        if not all(len(r) == 3 and all(isinstance(x, int | float) and not isinstance(x, bool) for x in r)
                   for r in value):
            raise t.error(key, f"expected 3 principal moments or a 3×3 matrix of numbers, got {short_repr(value)}")
        rows = [np.asarray(r, dtype=float) for r in value]
        matrix = np.vstack(rows)
    elif isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        matrix = np.diag(np.asarray(value, dtype=float))
    else:
        raise t.error(key, f"expected 3 principal moments or a 3×3 matrix, got {short_repr(value)}")
    if not np.all(np.isfinite(matrix)) or not np.allclose(matrix, matrix.T, rtol=0, atol=1e-9 * np.abs(matrix).max()):
        raise t.error(key, "inertia must be a finite symmetric matrix")
    eig = np.linalg.eigvalsh(matrix)
    if eig.min() <= 0:
        raise t.error(key, f"inertia must be positive definite (eigenvalues {np.round(eig, 6).tolist()})")
    a, b, c = np.sort(eig)
    if a + b < c * (1 - 1e-9):
        raise t.error(key, "inertia violates the triangle inequality (not a physical rigid body)")
    return matrix


def _unit(t: _Table, key: str, default: Any = _MISSING) -> Array | None:
    v = t.vector(key, 3, default)
    if v is None:
        return None
    n = np.linalg.norm(v)
    if n < 1e-12:
        raise t.error(key, "axis must be non-zero")
    return v / n


def _frame_from_axes(z_axis: Array, x_hint: Array, t: _Table, key: str) -> Array:
    """Rotation whose z column is ``z_axis`` and x column is ``x_hint`` made orthogonal to it."""
    x = x_hint - np.dot(x_hint, z_axis) * z_axis
    if np.linalg.norm(x) < 1e-6:
        raise t.error(key, "reference axis must not be parallel to the approach axis")
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z_axis, x), z_axis])


# ----------------------------------------------------------------------------------------------------
# Target


@dataclass(frozen=True)
class GraspConfig:
    """Grasp frame in the target body frame: z is the approach axis (into the target)."""

    T_body_grasp: Array
    free_axis: Array | None  # unit axis of the grasp frame about which any grasp angle is acceptable


@dataclass(frozen=True)
class TargetConfig:
    """The non-cooperative target: rigid body, convex geometry and its grasp frame (SI)."""

    source: str
    name: str
    mass_kg: float
    inertia_body_kg_m2: Array
    p_world_com: Array
    shapes: tuple[PlacedShape, ...]
    handle_shapes: frozenset[str]  # shapes only the gripper may touch
    grasp: GraspConfig

    def body(self) -> TargetBody:
        """The target's mass properties and grasp frame, as the torque-free model takes them."""
        return TargetBody(self.mass_kg, self.inertia_body_kg_m2, self.p_world_com, self.grasp.T_body_grasp)

    def motion(self, state: TargetState, t_end_s: float) -> TargetMotion:
        """Accurate torque-free motion of this target from the observed ``state`` (at t = 0) to ``t_end_s`` [s]."""
        return TargetMotion(self.body(), state, t_end_s)


def load_target(path: str | Path) -> TargetConfig:
    """Read and validate a target TOML file (see ``configs/targets/*.toml`` for the fields)."""
    path = Path(path)
    data, _ = _read_toml(path)
    t = _Table(data, str(path))
    name = t.string("name")
    mass = t.number("mass_kg", positive=True)
    inertia = _inertia_matrix(t, "inertia_kg_m2")
    com = t.vector("com_position_m", 3)
    shapes, handles = [], set()
    for s in t.tables("shapes", maximum=MAX_SHAPES):
        sname = s.string("name")
        kind = s.string("kind", choices=("box", "capsule"))
        position = s.vector("position_m", 3, default=[0.0, 0.0, 0.0])
        if kind == "box":
            shape = Box(tuple(s.vector("size_m", 3)))
            if min(shape.size_m) <= 0:
                raise s.error("size_m", "box sides must be > 0")
            R = rpy_to_matrix(np.radians(s.vector("rpy_deg", 3, default=[0.0, 0.0, 0.0])))
        else:
            shape = Capsule(s.number("radius_m", positive=True), s.number("length_m", nonnegative=True))
            axis = _unit(s, "axis", default=[0.0, 0.0, 1.0])
            hint = np.eye(3)[int(np.argmin(np.abs(axis)))]
            R = _frame_from_axes(axis, hint, s, "axis")
        if s.boolean("handle", default=False):
            handles.add(sname)
        s.finish()
        if any(p.name == sname for p in shapes):
            raise s.error("name", f"duplicate shape name {sname!r}")
        shapes.append(PlacedShape(sname, shape, make_transform(R, position)))
    g = t.table("grasp")
    approach = _unit(g, "approach_axis")
    reference = _unit(g, "reference_axis")
    R_body_grasp = _frame_from_axes(approach, reference, g, "reference_axis")
    free = g.string("free_axis", default="none", choices=("none", "x", "y", "z"))
    grasp = GraspConfig(
        T_body_grasp=make_transform(R_body_grasp, g.vector("position_m", 3)),
        free_axis=None if free == "none" else np.eye(3)["xyz".index(free)],
    )
    g.finish()
    t.finish()
    return TargetConfig(str(path), name, mass, inertia, com, tuple(shapes), frozenset(handles), grasp)


# ----------------------------------------------------------------------------------------------------
# Scenario


@dataclass(frozen=True)
class TargetStateConfig:
    """Default observed target state at t = 0 (the CLI may override it)."""

    attitude_wxyz: Array
    omega_body_rad_s: Array

    def as_state(self) -> TargetState:
        """This default as the planner's :class:`~planner.model.target.TargetState`."""
        return TargetState(np.asarray(self.attitude_wxyz, dtype=float), np.asarray(self.omega_body_rad_s, dtype=float))


@dataclass(frozen=True)
class PhaseTimes:
    """Phase durations (s) and the admissible start delay along the target trajectory (s)."""

    approach_s: float
    tracking_s: float
    stabilization_s: float
    max_start_delay_s: float


@dataclass(frozen=True)
class ApproachSettings:
    n_vertices: int
    via_points: int
    rk4_steps: int
    pregrasp_backoff_m: float


@dataclass(frozen=True)
class TrackingSettings:
    step_s: float
    pose_gain_per_s: float
    nullspace_gain: float


@dataclass(frozen=True)
class StabilizationSettings:
    n_vertices: int
    via_points: int
    rk4_steps: int
    # joint acceleration the Eq. 24 spline starts with: "continuous" = the tracking IK's at the grasp (C²
    # join: the gripper keeps accelerating with the free target, so the grasp wrench starts from zero);
    # "zero" = the paper's Eq. 24 (s̈(0) = 0; the wrench steps at the grasp by what the IK's acceleration
    # carried)
    start_acceleration: str = "continuous"
    # a cold solve first solves the same NLP with this many uniform via points (and RK4 steps), then starts
    # the full NLP from that answer; 0 solves the full NLP directly (planner.phases.stabilization)
    coarse_via_points: int = 20


@dataclass(frozen=True)
class Limits:
    collision_margin_m: float
    grasp_force_max_n: float  # inf = unconstrained
    grasp_torque_max_nm: float  # inf = unconstrained


@dataclass(frozen=True)
class CostWeights:
    """Weights of the scenario's weighted-sum cost (all 0: a pure feasibility solve)."""

    manipulability: float
    min_distance: float
    approach_energy: float
    attitude_disturbance: float
    peak_wrench: float
    overscale: float  # robot geometry scale for the distance cost (paper §5)

    @property
    def is_feasibility(self) -> bool:
        return not any((self.manipulability, self.min_distance, self.approach_energy,
                        self.attitude_disturbance, self.peak_wrench))


@dataclass(frozen=True)
class SolverSettings:
    max_iter: int
    max_wall_s: float
    tol: float


@dataclass(frozen=True)
class Scenario:
    """Everything one plan needs, loaded and validated (SI units)."""

    source: str
    text: str  # the scenario file's text (stored in tables for provenance)
    name: str
    robot: RobotModel
    target: TargetConfig
    target_state: TargetStateConfig
    q_initial: Array
    base_offset_bounds_m: tuple[tuple[float, float], tuple[float, float]]  # orbital-plane x, z
    base_offset_guess_m: Array
    phases: PhaseTimes
    approach: ApproachSettings
    tracking: TrackingSettings
    stabilization: StabilizationSettings
    limits: Limits
    costs: CostWeights
    solver: SolverSettings


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario TOML file, its robot URDF and its target file, and validate all of them."""
    path = Path(path)
    data, text = _read_toml(path)
    src = str(path)
    t = _Table(data, src)
    name = t.string("name")
    base_dir = path.parent
    urdf = t.string("robot_urdf")
    ee_frame = t.string("ee_frame", default="grasp_frame")
    if not (base_dir / urdf).is_file():
        raise t.error("robot_urdf", f"file not found: {base_dir / urdf}")
    try:
        robot = load_robot(base_dir / urdf, ee_frame=ee_frame)
    except ConfigError as exc:
        if exc.field != "ee_frame":
            raise
        raise t.error("ee_frame", f"{exc.problem} ({exc.source})") from None
    target_file = t.string("target")
    if not (base_dir / target_file).is_file():
        raise t.error("target", f"file not found: {base_dir / target_file}")
    target = load_target(base_dir / target_file)

    s = t.table("target_state")
    quat = s.vector("attitude_wxyz", 4)
    if abs(np.linalg.norm(quat) - 1.0) > 1e-6:
        raise s.error("attitude_wxyz", f"quaternion must have unit norm, got norm {np.linalg.norm(quat):.6g}")
    state = TargetStateConfig(quat, np.radians(s.vector("omega_body_deg_s", 3)))
    s.finish()

    r = t.table("robot")
    q0 = np.radians(r.vector("initial_joints_deg", robot.n_joints))
    bad = np.flatnonzero((q0 < robot.q_min) | (q0 > robot.q_max))
    if bad.size:
        raise r.error("initial_joints_deg", f"joint {bad[0] + 1} outside its URDF limits")
    bx = r.range_("base_offset_x_m")
    bz = r.range_("base_offset_z_m")
    guess = r.vector("base_offset_guess_m", 2, default=[0.0, 0.0])
    if not (bx[0] <= guess[0] <= bx[1] and bz[0] <= guess[1] <= bz[1]):
        raise r.error("base_offset_guess_m", "guess must lie inside base_offset_x_m / base_offset_z_m")
    r.finish()

    p = t.table("phases")
    phases = PhaseTimes(p.number("approach_s", positive=True), p.number("tracking_s", positive=True),
                        p.number("stabilization_s", positive=True),
                        p.number("max_start_delay_s", nonnegative=True))
    p.finish()

    a = t.table("approach", default={})
    approach = ApproachSettings(
        n_vertices=a.number("n_vertices", 10, integer=True), via_points=a.number("via_points", 20, integer=True),
        rk4_steps=a.number("rk4_steps", 50, integer=True),
        pregrasp_backoff_m=a.number("pregrasp_backoff_m", 0.1, nonnegative=True))
    for key in ("n_vertices", "via_points", "rk4_steps"):
        minimum = 8 if key == "n_vertices" else 2
        if getattr(approach, key) < minimum:
            raise a.error(key, f"must be >= {minimum}, got {getattr(approach, key)}")
    a.finish()

    k = t.table("tracking", default={})
    tracking = TrackingSettings(k.number("step_s", 0.01, positive=True),
                                k.number("pose_gain_per_s", 2.0, positive=True),
                                k.number("nullspace_gain", 0.5, nonnegative=True))
    k.finish()

    b = t.table("stabilization", default={})
    stab = StabilizationSettings(b.number("n_vertices", 10, integer=True), b.number("via_points", 20, integer=True),
                                 b.number("rk4_steps", 90, integer=True),
                                 b.string("start_acceleration", "continuous", choices=("continuous", "zero")),
                                 b.number("coarse_via_points", 20, integer=True, nonnegative=True))
    if 0 < stab.coarse_via_points < 2:
        raise b.error("coarse_via_points", f"must be 0 (off) or >= 2, got {stab.coarse_via_points}")
    for key in ("n_vertices", "via_points", "rk4_steps"):
        minimum = 8 if key == "n_vertices" else 2
        if getattr(stab, key) < minimum:
            raise b.error(key, f"must be >= {minimum}, got {getattr(stab, key)}")
    b.finish()

    lim = t.table("limits", default={})
    limits = Limits(lim.number("collision_margin_m", 0.02, nonnegative=True),
                    lim.number("grasp_force_max_n", math.inf, positive=True),
                    lim.number("grasp_torque_max_nm", math.inf, positive=True))
    lim.finish()

    c = t.table("costs", default={})
    costs = CostWeights(*(c.number(key, 0.0, nonnegative=True) for key in (
        "manipulability", "min_distance", "approach_energy", "attitude_disturbance", "peak_wrench")),
        overscale=c.number("overscale", 1.0, positive=True))
    c.finish()

    so = t.table("solver", default={})
    solver = SolverSettings(so.number("max_iter", 300, integer=True, positive=True),
                            so.number("max_wall_s", 60.0, positive=True), so.number("tol", 1e-6, positive=True))
    so.finish()
    t.finish()
    return Scenario(src, text, name, robot, target, state, q0, (bx, bz), guess, phases, approach, tracking,
                    stab, limits, costs, solver)


def grasp_quaternion(target: TargetConfig) -> Array:
    """``[w, x, y, z]`` of the grasp frame in the target body frame (export convenience)."""
    return matrix_to_quat(target.grasp.T_body_grasp[:3, :3])
