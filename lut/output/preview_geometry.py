"""Triangle meshes of the preview's bodies, and their poses over a plan (for :mod:`lut.output.preview`).

Every body is a rigid set of triangles in its own frame; the browser moves it with one 3×4 pose per
frame, so the page carries each mesh once and 12 numbers per body and frame (small HTML).

* Chaser: the URDF's collision shapes (a ``<cylinder>`` is a capsule, see :mod:`planner.model.robot`), body
  poses by pinocchio forward kinematics from the exported base pose and joint angles.
* Target: ``doc["target"]["shapes"]`` in the target body frame (the frame of ``samples.target_*``). A plan
  without that field gets the box with the target's mass and principal inertia (its sides from
  ``I_x = m (b² + c²) / 12`` …), flagged as a stand-in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.model.robot import RobotModel
from planner.model.rotation import quat_to_matrix
from planner.model.shapes import Box, Capsule, PlacedShape, make_transform

Array = NDArray[np.float64]
CAPSULE_SEGMENTS = 12  # around the axis: a smooth enough silhouette at a few hundred vertices per link
CAPSULE_RINGS = 3  # latitude rings per hemispherical cap


@dataclass(frozen=True)
class Mesh:
    """Triangles in a body frame: ``vertices`` (v×3, m) and ``faces`` (f×3 vertex indices)."""

    vertices: Array
    faces: NDArray[np.int64]


def box_mesh(size_m: tuple[float, float, float]) -> Mesh:
    """Closed box centred at the origin, full side lengths ``size_m`` (m)."""
    half = np.asarray(size_m, dtype=float) / 2
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float) * half
    # two triangles per face, corners indexed by the bits (x, y, z) = (4, 2, 1)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    faces = [tri for a, b, c, d in quads for tri in ((a, b, c), (a, c, d))]
    return Mesh(corners, np.array(faces, dtype=np.int64))


def capsule_mesh(radius_m: float, length_m: float) -> Mesh:
    """Capsule along z, centred: the segment ``[-length/2, length/2]`` swept by a sphere of ``radius_m`` (m)."""
    n = CAPSULE_SEGMENTS
    phi = 2 * np.pi * np.arange(n) / n
    rings = []  # (z, ring radius), bottom pole to top pole
    for k in range(1, CAPSULE_RINGS + 1):  # bottom cap, from the pole up to the equator
        a = -np.pi / 2 + (np.pi / 2) * k / CAPSULE_RINGS
        rings.append((-length_m / 2 + radius_m * np.sin(a), radius_m * np.cos(a)))
    for k in range(CAPSULE_RINGS):  # top cap, from the equator up
        a = (np.pi / 2) * k / CAPSULE_RINGS
        rings.append((length_m / 2 + radius_m * np.sin(a), radius_m * np.cos(a)))
    vertices = [[0.0, 0.0, -length_m / 2 - radius_m]]
    for z, r in rings:
        vertices += [[r * np.cos(p), r * np.sin(p), z] for p in phi]
    vertices.append([0.0, 0.0, length_m / 2 + radius_m])
    top = len(vertices) - 1
    faces = [(0, 1 + (i + 1) % n, 1 + i) for i in range(n)]
    for ring in range(len(rings) - 1):
        lo, hi = 1 + ring * n, 1 + (ring + 1) * n
        for i in range(n):
            j = (i + 1) % n
            faces += [(lo + i, lo + j, hi + j), (lo + i, hi + j, hi + i)]
    last = 1 + (len(rings) - 1) * n
    faces += [(last + i, last + (i + 1) % n, top) for i in range(n)]
    return Mesh(np.array(vertices), np.array(faces, dtype=np.int64))


def placed_mesh(placed: PlacedShape) -> Mesh:
    """The mesh of a shape placed in its body frame (``T_body_shape``)."""
    shape = placed.shape
    mesh = box_mesh(shape.size_m) if isinstance(shape, Box) else capsule_mesh(shape.radius_m, shape.length_m)
    T = placed.T_body_shape
    return Mesh(mesh.vertices @ T[:3, :3].T + T[:3, 3], mesh.faces)


def merge(meshes: list[Mesh]) -> Mesh:
    """One mesh of several (faces re-indexed)."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return Mesh(np.vstack([m.vertices for m in meshes]),
                np.vstack([m.faces + off for m, off in zip(meshes, offsets, strict=True)]))


# ---- target -------------------------------------------------------------------------------------


def target_shapes(doc: dict[str, Any]) -> tuple[list[tuple[PlacedShape, bool]], str]:
    """Shapes of the target in its body frame with their ``handle`` flag, and a note when they are a stand-in.

    Reads ``doc["target"]["shapes"]``: ``{name, kind: "box" | "capsule", size_m | radius_m + length_m,
    position_m, wxyz, handle}``. Without it: the inertia-equivalent box (module docstring).
    """
    target = doc.get("target", {})
    shapes = target.get("shapes")
    if isinstance(shapes, list) and shapes:
        out = []
        for s in shapes:
            T = make_transform(quat_to_matrix(s.get("wxyz", [1.0, 0.0, 0.0, 0.0])),
                               np.asarray(s.get("position_m", [0.0, 0.0, 0.0]), dtype=float))
            shape = Box(tuple(s["size_m"])) if s["kind"] == "box" else Capsule(s["radius_m"], s["length_m"])
            out.append((PlacedShape(str(s.get("name", s["kind"])), shape, T), bool(s.get("handle", False))))
        return out, ""
    inertia = np.asarray(target.get("inertia_kg_m2", [1.0, 1.0, 1.0]), dtype=float)
    mass = float(target.get("mass_kg", 1.0))
    # moments about the body axes: the plan file has the 3×3 tensor (body frame), older ones the 3 moments; the
    # stand-in box is drawn along the body axes
    Ix, Iy, Iz = np.diag(inertia) if inertia.shape == (3, 3) else inertia
    sides = [np.sqrt(max(6.0 * v / mass, 1e-4)) for v in (Iy + Iz - Ix, Ix + Iz - Iy, Ix + Iy - Iz)]
    return [(PlacedShape("inertia-equivalent box", Box(tuple(sides))), False)], \
        "target drawn as its inertia-equivalent box: the plan has no target.shapes"


# ---- poses --------------------------------------------------------------------------------------


def chaser_body_poses(robot: RobotModel, base_position: Array, base_wxyz: Array, q: Array) -> Array:
    """World poses (frames × bodies × 3 × 4) of the chaser bodies (``robot.body_names`` order), pinocchio FK."""
    from planner.verify.kinematics import PinKinematics

    kin = PinKinematics(robot)
    out = np.empty((len(q), len(robot.body_names), 3, 4))
    for k in range(len(q)):
        kin.forward(np.concatenate([base_position[k], base_wxyz[k]]), q[k])
        poses = kin.body_poses()
        out[k] = [poses[name][:3, :] for name in robot.body_names]
    return out


def pose_matrices(position: Array, wxyz: Array) -> Array:
    """(n × 3 × 4) poses from positions (n×3, m) and ``[w, x, y, z]`` quaternions (n×4)."""
    out = np.empty((len(position), 3, 4))
    for k, (p, quat) in enumerate(zip(position, wxyz, strict=True)):
        out[k, :, :3] = quat_to_matrix(quat)
        out[k, :, 3] = p
    return out
