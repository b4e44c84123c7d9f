"""Exact reference signed distances of boxes and capsules, independent of both distance engines (issue 19).

Every shape is a polytope *core* swept by a ball: a box is its own core (radius 0), a capsule is its segment
(from ``-L/2`` to ``+L/2`` along its frame's z axis) swept by its radius. For convex sets the signed distance
of the swept shapes is the core signed distance minus both radii, exactly, separated or penetrating.

* Separated cores: the closest pair minimises ``‖(c_a + M_a u) - (c_b + M_b v)‖`` over ``|u_i|, |v_j| ≤ 1``
  (``M`` = half-extent vectors), a bounded-variable least-squares problem that BVLS solves by a finite
  active-set method; every answer is then *certified* by duality: the found pair's distance (an upper bound)
  and the largest vertex-projection gap over the found direction and the SAT axes (a lower bound: no pair is
  closer than the gap along any unit axis) must meet to 1e-8 m (to 1e-7 m within 1e-7 m of contact, where
  rounding blurs the witness direction).
* Penetrating box-box / box-segment cores: the depth is the minimum over the separating-axis candidates
  (face normals of each core and cross products of edge directions) of the projection overlap. That set
  holds every facet normal of the Minkowski difference (a zonotope), so the minimum is exact.
* Segment-segment cores never penetrate (their Minkowski difference is flat): the depth is 0 when they
  meet, and their distance is also given in closed form (Ericson, RTCD §5.1.9) as a cross-check.

No code is shared with ``planner.collision.scene_distances`` or ``planner.collision.closed_form``: only the shape
dataclasses of ``planner.model.shapes`` are read.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import lsq_linear

from planner.model.shapes import Box, Capsule

Array = NDArray[np.float64]
Shape = Box | Capsule

# A BVLS answer is accepted only if primal and dual bounds meet to this (m): 100× below the tests' 1e-6 m. Not
# 1e-9: a nearly parallel contact leaves BVLS's witness direction ~1e-8 rad loose (ill-conditioned sliding),
# which weakens the dual bound by up to ~7e-9 m (measured over 25,000 seeded certifications).
CERTIFICATE_TOL_M = 1e-8
# Within this distance (m) of contact the certificate degrades to [0, distance] (see _certify).
NEAR_CONTACT_M = 1e-7
# Cross products of edge directions shorter than this are parallel edges: they add no new axis.
PARALLEL_SIN_TOL = 1e-9
# Translation margin (m) within which the oracle reports the distance as smooth (see OracleDistance.smooth).
SMOOTH_MARGIN_M = 1e-4


# Sign patterns of the corners of a k-dimensional box, k = 0 … 3.
_SIGNS = [np.array(list(itertools.product((-1.0, 1.0), repeat=k)), dtype=float).reshape(2**k, k) for k in range(4)]


@dataclass(frozen=True)
class Core:
    """A shape's polytope core in the world frame: the points ``centre + axes @ u`` with ``|u_i| <= 1``."""

    centre: Array  # (3,) world, m
    axes: Array  # (3, k) half-extent vectors: k = 3 for a box, 1 for a segment, 0 for a point
    radius_m: float  # sweep radius: 0 for a box
    is_box: bool

    @cached_property
    def vertices(self) -> Array:
        """(2^k, 3) corner points: every sign pattern of the half extents (exact extreme points)."""
        return self.centre + _SIGNS[self.axes.shape[1]] @ self.axes.T

    @cached_property
    def edge_directions(self) -> Array:
        """(k, 3) unit edge directions (box axes, segment direction); none for a point."""
        norms = np.linalg.norm(self.axes, axis=0)
        return (self.axes[:, norms > 0] / norms[norms > 0]).T

    @cached_property
    def face_normals(self) -> Array:
        """(3, 3) unit face normals of a box (its axes, orthogonal); a segment or point has no faces."""
        return self.edge_directions if self.is_box else np.zeros((0, 3))


@dataclass(frozen=True)
class OracleDistance:
    """Exact signed distance of two shapes and a unit normal from A to B (world frame)."""

    distance_m: float  # > 0 separated, < 0 minus the penetration depth (m)
    normal_world: Array  # unit: translating B by +ε n increases the distance by ε (one-sided, exact)
    core_distance_m: float  # signed distance of the cores (the radii not subtracted)
    axis_margin_m: float  # penetrating cores: next-best axis overlap minus the best one (inf otherwise)

    @property
    def smooth(self) -> bool:
        """The distance is differentiable in B's translation within ``SMOOTH_MARGIN_M``: the cores are
        separated by more than it (distance to a convex set is C¹ outside it), or penetrate deeper than it
        with a unique best axis by that margin (then ``-depth`` is linear in the translation)."""
        if self.core_distance_m > SMOOTH_MARGIN_M:
            return True
        return self.core_distance_m < -SMOOTH_MARGIN_M and self.axis_margin_m > 2 * SMOOTH_MARGIN_M


def make_core(shape: Shape, T_world_shape: Array) -> Core:
    """World-frame core of a box or capsule placed at ``T_world_shape`` (4×4): a box is its own core, a capsule's
    is its segment (a point if its length is 0)."""
    R, c = T_world_shape[:3, :3], T_world_shape[:3, 3]
    if isinstance(shape, Box):
        return Core(c.copy(), R * (0.5 * np.asarray(shape.size_m, dtype=float)), 0.0, True)
    half = 0.5 * float(shape.length_m)
    axes = R[:, 2:3] * half if half > 0.0 else np.zeros((3, 0))  # a zero-length capsule is a ball on a point
    return Core(c.copy(), axes, float(shape.radius_m), False)


def segment_closest_points(p0: Array, p1: Array, q0: Array, q1: Array) -> tuple[Array, Array]:
    """Closest points of segments [p0, p1] and [q0, q1] (Ericson RTCD §5.1.9): exact minimiser of a convex
    quadratic on [0, 1]², clamping one parameter then the other; parallel segments take s = 0 first (any s
    on the common projection is a minimiser, and the clamped re-solve finds one)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = float(d1 @ d1), float(d2 @ d2), float(d2 @ r)
    if a == 0.0 and e == 0.0:
        return p0.copy(), q0.copy()
    if a == 0.0:
        return p0.copy(), q0 + float(np.clip(f / e, 0.0, 1.0)) * d2
    c = float(d1 @ r)
    if e == 0.0:
        return p0 + float(np.clip(-c / a, 0.0, 1.0)) * d1, q0.copy()
    b = float(d1 @ d2)
    # Line solution s = (b f - c e) / (a e - b²) written with cross products (Lagrange's identity): the dot
    # form cancels catastrophically below ~1.5e-8 rad between the segments and can pick the wrong end.
    n = np.cross(d1, d2)
    denom = float(n @ n)
    s = float(np.clip(float(n @ np.cross(d2, r)) / denom, 0.0, 1.0)) if denom > 0.0 else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, float(np.clip(-c / a, 0.0, 1.0))
    elif t > 1.0:
        t, s = 1.0, float(np.clip((b - c) / a, 0.0, 1.0))
    return p0 + s * d1, q0 + t * d2


def closest_core_points(core_a: Core, core_b: Core) -> tuple[Array, Array]:
    """Closest points of two cores. Exact: BVLS is a finite active-set method for this convex QP, and each
    answer is certified by duality to 1e-8 m, 1e-7 m near contact (:func:`_certify`)."""
    M = np.hstack([core_a.axes, -core_b.axes])
    rhs = core_b.centre - core_a.centre
    if M.shape[1] == 0:  # two points
        return core_a.centre.copy(), core_b.centre.copy()
    sol = lsq_linear(M, rhs, bounds=(-1.0, 1.0), method="bvls", tol=1e-15, max_iter=200)
    u = np.clip(sol.x, -1.0, 1.0)  # BVLS keeps bounds; the clip only guards rounding of active bounds
    k = core_a.axes.shape[1]
    pa = core_a.centre + core_a.axes @ u[:k]
    pb = core_b.centre + core_b.axes @ u[k:]
    _certify(core_a, core_b, pa, pb)
    return pa, pb


def _certify(core_a: Core, core_b: Core, pa: Array, pb: Array) -> None:
    """Raise unless the true distance is pinned to within CERTIFICATE_TOL_M: it lies between the best
    projection gap (weak duality: no pair is closer than the gap along any unit axis; also >= 0) and
    ``‖pb - pa‖`` (a feasible pair). Axes tried: the witness direction and the SAT candidates."""
    dist = float(np.linalg.norm(pb - pa))
    axes = candidate_axes(core_a, core_b)
    if dist > 0.0:
        axes = np.vstack([axes, (pb - pa) / dist])
    gaps = (core_b.vertices @ axes.T).min(axis=0) - (core_a.vertices @ axes.T).max(axis=0)
    lower = max(0.0, float(gaps.max(initial=0.0)))
    # The witness direction of points ``dist`` apart is only known to ~eps·scale/dist rad, which moves the
    # projection gap by ~eps·scale²/dist: within NEAR_CONTACT_M of contact the certificate is only that the
    # distance is in [0, dist], i.e. exact to NEAR_CONTACT_M (still 10× below the tests' 1e-6 m).
    scale = 1.0 + float(np.abs(np.r_[core_a.vertices.ravel(), core_b.vertices.ravel()]).max())
    rounding = 8.0 * np.finfo(float).eps * scale**2 / max(dist, np.finfo(float).tiny)
    if dist - lower > CERTIFICATE_TOL_M + min(rounding, NEAR_CONTACT_M):
        raise AssertionError(f"BVLS closest points not certified: distance {dist!r}, dual bound {lower!r}")


def candidate_axes(core_a: Core, core_b: Core) -> Array:
    """(m, 3) unit separating-axis candidates: face normals of both cores and cross products of edges."""
    ea, eb = core_a.edge_directions[:, None, :], core_b.edge_directions[None, :, :]
    crosses = np.stack([ea[..., 1] * eb[..., 2] - ea[..., 2] * eb[..., 1],  # np.cross is 10× slower here
                        ea[..., 2] * eb[..., 0] - ea[..., 0] * eb[..., 2],
                        ea[..., 0] * eb[..., 1] - ea[..., 1] * eb[..., 0]], axis=-1).reshape(-1, 3)
    norms = np.linalg.norm(crosses, axis=1)
    keep = norms > PARALLEL_SIN_TOL
    return np.vstack([core_a.face_normals, core_b.face_normals, crosses[keep] / norms[keep, None]])


def axis_overlaps(core_a: Core, core_b: Core, axes: Array) -> Array:
    """Per unit axis u, the translations of B along +u and along -u that separate it from A (m; < 0 = already
    apart by that much): columns (push along +u, push along -u)."""
    pa, pb = core_a.vertices @ axes.T, core_b.vertices @ axes.T  # (vertices, axes) projections
    return np.stack([pa.max(axis=0) - pb.min(axis=0), pb.max(axis=0) - pa.min(axis=0)], axis=1)


def penetration(core_a: Core, core_b: Core) -> tuple[float, Array, float]:
    """SAT on box-box / box-segment cores: (min overlap (m, < 0 = separated), its unit normal A→B, margin to
    the next-best direction (m): another axis, or the same axis the other way). Exact: the candidates are all
    the zonotope's facet normals, each taken both ways."""
    axes = candidate_axes(core_a, core_b)
    pushes = axis_overlaps(core_a, core_b, axes)  # (m, 2)
    best, side = np.unravel_index(int(np.argmin(pushes)), pushes.shape)
    normal = axes[best] if side == 0 else -axes[best]
    # Every direction except the best one (duplicates of the best axis, e.g. an edge cross product equal to a
    # face normal, are the same facet): a tie means two facets equally near, i.e. a kink in the distance.
    same = (axes @ normal)[:, None] * np.array([1.0, -1.0]) > 1.0 - 1e-12
    others = pushes[~same]
    margin = float(others.min() - pushes[best, side]) if others.size else np.inf
    return float(pushes[best, side]), normal, margin


def core_signed_distance(core_a: Core, core_b: Core) -> tuple[float, Array, float]:
    """Signed distance of two cores, unit normal A→B and the axis margin (see :class:`OracleDistance`). Exact:
    SAT decides and measures penetration of polytope cores; BVLS (certified) measures separation."""
    sat = penetration(core_a, core_b) if (core_a.is_box or core_b.is_box) else None
    if sat is not None and sat[0] >= 0.0:
        return -sat[0], sat[1], sat[2]
    pa, pb = closest_core_points(core_a, core_b)
    dist = float(np.linalg.norm(pb - pa))
    if dist > CERTIFICATE_TOL_M:
        return dist, (pb - pa) / dist, np.inf
    # Touching: a box's best SAT axis separates; meeting segments have a flat contact (a kink either way).
    return dist, (sat[1] if sat is not None else _flat_contact_normal(core_a, core_b)), 0.0


def _flat_contact_normal(core_a: Core, core_b: Core) -> Array:
    """Normal of two meeting segments (or points): their common plane's normal if they cross, else any
    direction orthogonal to both; either side is a valid one-sided gradient of the flat contact."""
    dirs = np.vstack([core_a.edge_directions, core_b.edge_directions, np.eye(3)])
    for i, j in itertools.combinations(range(len(dirs)), 2):
        c = np.cross(dirs[i], dirs[j])
        if np.linalg.norm(c) > 1e-6:
            return c / np.linalg.norm(c)
    raise AssertionError("unreachable: the world axes always span a plane")


def signed_distance(shape_a: Shape, T_world_a: Array, shape_b: Shape, T_world_b: Array) -> OracleDistance:
    """Exact signed distance (m) of two placed shapes: the core signed distance minus both sweep radii, which
    is exact for sphere-swept convex sets, separated or penetrating."""
    core_a, core_b = make_core(shape_a, T_world_a), make_core(shape_b, T_world_b)
    d_core, n, margin = core_signed_distance(core_a, core_b)
    return OracleDistance(d_core - core_a.radius_m - core_b.radius_m, n, d_core, margin)


def translated(T: Array, delta: Array) -> Array:
    """``T`` moved by the world translation ``delta`` (m)."""
    out = np.array(T, dtype=float)
    out[:3, 3] += delta
    return out


def distance_after_translation(shape_a: Shape, T_a: Array, shape_b: Shape, T_b: Array, delta: Array) -> float:
    """Exact signed distance after translating B by ``delta`` (world, m): the finite-difference probe."""
    return signed_distance(shape_a, T_a, shape_b, translated(T_b, delta)).distance_m


def surface_offset(shape: Shape, T_world_shape: Array, points: Array) -> Array:
    """Signed distance (m) of world points (n, 3) to a shape's surface at poses (n, 4, 4); 0 = on it.

    Exact: a box's is the textbook box SDF in its frame, a capsule's is the point-segment distance minus r.
    """
    T = np.broadcast_to(T_world_shape, (len(points), 4, 4))
    local = np.einsum("nji,nj->ni", T[:, :3, :3], points - T[:, :3, 3])  # Rᵀ (p - c)
    if isinstance(shape, Box):
        q = np.abs(local) - 0.5 * np.asarray(shape.size_m, dtype=float)
        outside = np.linalg.norm(np.maximum(q, 0.0), axis=1)
        return outside + np.minimum(q.max(axis=1), 0.0)
    half = 0.5 * float(shape.length_m)
    on_axis = np.clip(local[:, 2], -half, half)
    radial = local - on_axis[:, None] * np.array([0.0, 0.0, 1.0])
    return np.linalg.norm(radial, axis=1) - float(shape.radius_m)
