"""The target file: the non-cooperative target's mass, inertia, convex shapes and grasp frame (TOML, SI)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.config.limits import MAX_SHAPES
from planner.config.toml_table import MISSING, TomlTable, read_toml, short_repr
from planner.model.rotation import rpy_to_matrix
from planner.model.shapes import Box, Capsule, PlacedShape, make_transform
from planner.model.target import TargetBody, TargetMotion, TargetState

Array = NDArray[np.float64]


@dataclass(frozen=True)
class GraspConfig:
    """Grasp frame in the target body frame: z is the approach axis (into the target)."""

    T_body_grasp: Array  # (4, 4) [m]
    free_axis: Array | None  # unit axis of the grasp frame about which any grasp angle is acceptable


@dataclass(frozen=True)
class TargetConfig:
    """The non-cooperative target: rigid body, convex geometry and its grasp frame (SI)."""

    source: str
    name: str
    mass_kg: float
    inertia_body_kg_m2: Array  # (3, 3), about the COM, body frame
    p_world_com: Array  # (3,) [m]
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
    data, _ = read_toml(path)
    t = TomlTable(data, str(path))
    name = t.string("name")
    mass = t.number("mass_kg", positive=True)
    inertia = _inertia_matrix(t, "inertia_kg_m2")
    com = t.vector("com_position_m", 3)
    shapes, handles = [], set()
    for s in t.tables("shapes", maximum=MAX_SHAPES):
        placed, is_handle = _read_shape(s)
        if is_handle:
            handles.add(placed.name)
        s.finish()
        if any(p.name == placed.name for p in shapes):
            raise s.error("name", f"duplicate shape name {placed.name!r}", placed.name)
        shapes.append(placed)
    grasp = _read_grasp(t.table("grasp"))
    t.finish()
    return TargetConfig(str(path), name, mass, inertia, com, tuple(shapes), frozenset(handles), grasp)


def _read_shape(s: TomlTable) -> tuple[PlacedShape, bool]:
    """One ``[[shapes]]`` entry, placed in the body frame, and whether it is part of the grasp handle."""
    sname = s.string("name")
    kind = s.string("kind", choices=("box", "capsule"))
    position = s.vector("position_m", 3, default=[0.0, 0.0, 0.0])
    if kind == "box":
        shape = Box(tuple(s.vector("size_m", 3)))
        if min(shape.size_m) <= 0:
            raise s.error("size_m", "box sides must be > 0", shape.size_m)
        R = rpy_to_matrix(np.radians(s.vector("rpy_deg", 3, default=[0.0, 0.0, 0.0])))
    else:
        shape = Capsule(s.number("radius_m", positive=True), s.number("length_m", nonnegative=True))
        axis = _unit(s, "axis", default=[0.0, 0.0, 1.0])
        hint = np.eye(3)[int(np.argmin(np.abs(axis)))]
        R = _frame_from_axes(axis, hint, s, "axis")
    return PlacedShape(sname, shape, make_transform(R, position)), s.boolean("handle", default=False)


def _read_grasp(g: TomlTable) -> GraspConfig:
    """The ``[grasp]`` table: the grasp frame from its approach and reference axes, and its free axis."""
    approach = _unit(g, "approach_axis")
    reference = _unit(g, "reference_axis")
    R_body_grasp = _frame_from_axes(approach, reference, g, "reference_axis")
    free = g.string("free_axis", default="none", choices=("none", "x", "y", "z"))
    grasp = GraspConfig(
        T_body_grasp=make_transform(R_body_grasp, g.vector("position_m", 3)),
        free_axis=None if free == "none" else np.eye(3)["xyz".index(free)],
    )
    g.finish()
    return grasp


def _inertia_matrix(t: TomlTable, key: str) -> Array:
    """(3, 3) inertia [kg·m²] from 3 principal moments or a 3×3 matrix: symmetric, SPD, physical."""
    value = t.get(key, MISSING)
    if isinstance(value, list) and len(value) == 3 and all(isinstance(v, list) for v in value):
        if not all(len(r) == 3 and all(isinstance(x, int | float) and not isinstance(x, bool) for x in r)
                   for r in value):
            raise t.type_error(key, f"expected 3 principal moments or a 3×3 matrix of numbers, got "
                                    f"{short_repr(value)}", value)
        rows = [np.asarray(r, dtype=float) for r in value]
        matrix = np.vstack(rows)
    elif isinstance(value, list) and len(value) == 3 and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        matrix = np.diag(np.asarray(value, dtype=float))
    else:
        raise t.type_error(key, f"expected 3 principal moments or a 3×3 matrix, got {short_repr(value)}", value)
    if not np.all(np.isfinite(matrix)) or not np.allclose(matrix, matrix.T, rtol=0, atol=1e-9 * np.abs(matrix).max()):
        raise t.error(key, "inertia must be a finite symmetric matrix", value)
    eig = np.linalg.eigvalsh(matrix)
    if eig.min() <= 0:
        raise t.error(key, f"inertia must be positive definite (eigenvalues {np.round(eig, 6).tolist()})", value)
    a, b, c = np.sort(eig)
    if a + b < c * (1 - 1e-9):
        raise t.error(key, "inertia violates the triangle inequality (not a physical rigid body)", value)
    return matrix


def _unit(t: TomlTable, key: str, default: Any = MISSING) -> Array | None:
    """The 3-vector ``key`` normalised (None when absent with a None default)."""
    v = t.vector(key, 3, default)
    if v is None:
        return None
    n = np.linalg.norm(v)
    if n < 1e-12:
        raise t.error(key, "axis must be non-zero", v.tolist())
    return v / n


def _frame_from_axes(z_axis: Array, x_hint: Array, t: TomlTable, key: str) -> Array:
    """Rotation whose z column is ``z_axis`` and x column is ``x_hint`` made orthogonal to it."""
    x = x_hint - np.dot(x_hint, z_axis) * z_axis
    if np.linalg.norm(x) < 1e-6:
        raise t.error(key, "reference axis must not be parallel to the approach axis", x_hint.tolist())
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z_axis, x), z_axis])

