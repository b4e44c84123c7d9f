"""Exact signed distances of boxes and capsules in closed form, vectorised over poses (the NLPs' engine).

The NLPs' collision constraints (:mod:`planner.collision.scene_distances`) come from here;
:func:`planner.verify.verifier.verify` checks every plan with an engine of its own
(:mod:`planner.verify.distance`), written apart with other algorithms, so that one engine's error is caught by the
other. Every shape is a *core* swept by a ball: a box is its own core (radius 0), a capsule is its segment with its
radius. The signed distance
of two sphere-swept convex sets is that of their cores minus the radii, with the same normal, so only core
distances are computed here:

* separated cores: the exact minimum over the features that can realise it (segment–segment by
  Ericson's clamped closed form; segment–box: the segment's end points against the box and the segment
  against the box's 12 edges; box–box: each box's 8 vertices against the other box and the 12 × 12 edge
  pairs). For two disjoint convex polytopes one closest pair always has a vertex of one of them, or lies
  on an edge of each, so the minimum over these features is the distance, in every pose.
* intersecting cores: the penetration depth is the smallest translation that separates them, attained
  along a facet normal of their Minkowski difference; for a box and a segment those are the box's 3 axes
  and the 3 cross products of the segment with them, for two boxes the 15 axes of the separating-axis
  test. The minimum of the projection overlaps over these candidates is the depth, exactly.

Conventions as in :mod:`planner.collision.scene_distances`: ``p_world_b - p_world_a = distance_m * normal_world`` and
translating B by ``+ε n`` increases the distance by ``ε``. Shapes are placed by ``T_world_shape`` stacks
``(n, 4, 4)`` (metres). Degenerate normals (crossing or collinear segments, touching cores) get a valid
one-sided normal; the distance itself never depends on that choice.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.model.shapes import Box, Capsule, Shape

Array = NDArray[np.float64]

# Below this core separation [m] the direction between the witness points carries no information.
DEGENERATE_M = 1e-9
# Cross products shorter than this (relative) are not candidate axes: the segment is parallel to that edge.
_PARALLEL_REL = 1e-12
# Sign patterns of a box's 8 vertices and, per axis, of its 4 edges' offsets on the other two axes.
_VERTEX_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
_EDGE_SIGNS = np.array([[1, 1], [1, -1], [-1, 1], [-1, -1]], dtype=float)


def _edge_pattern() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per edge of a unit box: the signs of its start point's coordinates and its axis (12, 3) each."""
    starts, dirs = np.zeros((12, 3)), np.zeros((12, 3))
    for axis in range(3):
        j, k = [i for i in range(3) if i != axis]
        for e, (sj, sk) in enumerate(_EDGE_SIGNS):
            row = 4 * axis + e
            starts[row, axis], starts[row, j], starts[row, k] = -1.0, sj, sk
            dirs[row, axis] = 1.0
    return starts, dirs


_EDGE_START_SIGNS, _EDGE_DIRECTIONS = _edge_pattern()


@dataclass(frozen=True)
class SignedDistances:
    """Per pose: signed distance (m; < 0 minus the penetration depth), witness points and unit normal (world).

    Arrays: ``distance_m`` (n,), ``p_world_a``, ``p_world_b``, ``normal_world`` (n, 3).
    """

    distance_m: Array
    p_world_a: Array
    p_world_b: Array
    normal_world: Array


def signed_distance(shape_a: Shape, T_world_a: Array, shape_b: Shape, T_world_b: Array) -> SignedDistances:
    """Signed distance of ``shape_a`` posed by ``T_world_a`` and ``shape_b`` by ``T_world_b`` ((n, 4, 4) or 4×4)."""
    Ta = np.asarray(T_world_a, dtype=float).reshape(-1, 4, 4)
    Tb = np.asarray(T_world_b, dtype=float).reshape(-1, 4, 4)
    Ta, Tb = np.broadcast_arrays(Ta, Tb)
    return signed_distances(ShapeRows.of([shape_a] * len(Ta)), Ta, ShapeRows.of([shape_b] * len(Tb)), Tb)


@dataclass(frozen=True)
class ShapeRows:
    """Shapes of one kind, one per row: boxes by half sides ``half_m`` (n, 3), capsules by ``radius_m`` and
    ``length_m`` (n,). Rows of different sizes go through the engine in one call."""

    is_box: bool
    half_m: Array
    radius_m: Array
    length_m: Array

    @staticmethod
    def of(shapes: list[Shape]) -> ShapeRows:
        """Rows of one kind of shape (all boxes or all capsules), in the given order."""
        if all(isinstance(sh, Box) for sh in shapes):
            half = np.array([sh.size_m for sh in shapes], dtype=float).reshape(-1, 3) * 0.5
            return ShapeRows(True, half, np.zeros(len(shapes)), np.zeros(len(shapes)))
        if all(isinstance(sh, Capsule) for sh in shapes):
            r = np.array([sh.radius_m for sh in shapes], dtype=float)
            return ShapeRows(False, np.zeros((len(shapes), 3)), r, np.array([sh.length_m for sh in shapes], float))
        raise TypeError(f"unsupported or mixed shapes {sorted({type(sh).__name__ for sh in shapes})}")


def signed_distances(a: ShapeRows, T_world_a: Array, b: ShapeRows, T_world_b: Array) -> SignedDistances:
    """Row by row, the signed distance of shape ``a[i]`` posed by ``T_world_a[i]`` and ``b[i]`` by ``T_world_b[i]``."""
    Ta, Tb = T_world_a, T_world_b
    if not a.is_box and not b.is_box:
        d, ca, cb, n = segment_segment(*_segment(a.length_m, Ta), *_segment(b.length_m, Tb))
    elif a.is_box and not b.is_box:
        d, ca, cb, n = box_segment(a.half_m, Ta, *_segment(b.length_m, Tb))
    elif b.is_box and not a.is_box:
        d, cb, ca, n = box_segment(b.half_m, Tb, *_segment(a.length_m, Ta))
        n = -n
    else:
        d, ca, cb, n = box_box(a.half_m, Ta, b.half_m, Tb)
    ra, rb = a.radius_m, b.radius_m
    d = d - ra - rb
    p_a = ca + ra[:, None] * n
    # B's witness from the identity: cb - rb n up to rounding, but exact to it where the normal comes from core
    # points a few nm apart (nearly touching cores), whose direction carries that rounding
    return SignedDistances(d, p_a, p_a + d[:, None] * n, n)


def _segment(length_m: Array, T: Array) -> tuple[Array, Array]:
    """Start points and direction vectors (world, m) of capsule cores: from −L/2 to +L/2 along the shapes' z."""
    axis = T[:, :3, 2]
    return T[:, :3, 3] - 0.5 * length_m[:, None] * axis, length_m[:, None] * axis


def _dot(a: Array, b: Array) -> Array:
    return np.einsum("...i,...i->...", a, b)


def _unit(v: Array) -> Array:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def closest_segment_params(p: Array, u: Array, q: Array, v: Array) -> tuple[Array, Array]:
    """Parameters ``s, t ∈ [0, 1]`` of a closest pair of segments ``p + s u`` and ``q + t v`` (Ericson §5.1.9).

    Broadcasts over leading axes. Parallel segments take ``s = 0`` before clamping, which still yields a
    closest pair (parallel segments are closest at an end point of one of them); point segments work too.
    """
    r = p - q
    a, e, b, c, f = _dot(u, u), _dot(v, v), _dot(u, v), _dot(u, r), _dot(v, r)
    tiny = 1e-300
    a_safe, e_safe = np.maximum(a, tiny), np.maximum(e, tiny)
    denom = _dot(np.cross(u, v), np.cross(u, v))  # ‖u × v‖², not a·e − b²: that cancels for nearly parallel u, v
    s = np.where(denom > 1e-14 * a * e, np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0, 1), 0.0)
    t = (b * s + f) / e_safe
    s = np.where(t < 0.0, np.clip(-c / a_safe, 0, 1), np.where(t > 1.0, np.clip((b - c) / a_safe, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    # point segments: the other segment's closest point to it
    s = np.where(e <= tiny, np.clip(-c / a_safe, 0, 1), s)
    t = np.where(e <= tiny, 0.0, t)
    s = np.where(a <= tiny, 0.0, s)
    t = np.where(a <= tiny, np.where(e <= tiny, 0.0, np.clip(f / e_safe, 0, 1)), t)
    return s, t


def segment_segment(p: Array, u: Array, q: Array, v: Array) -> tuple[Array, Array, Array, Array]:
    """Core distance (m, ≥ 0), closest points and unit normal (from A to B) of segments ``p + s u``, ``q + t v``.

    When the segments meet, the normal is ``u × v`` (or, for parallel ones, a perpendicular), oriented
    from A's centre towards B's: either side is a valid one-sided gradient of ``|n·δ| − r_a − r_b``.
    """
    s, t = closest_segment_params(p, u, q, v)
    ca, cb = p + s[..., None] * u, q + t[..., None] * v
    diff = cb - ca
    d = np.linalg.norm(diff, axis=-1)
    n = diff / np.where(d > DEGENERATE_M, d, 1.0)[..., None]
    touching = d <= DEGENERATE_M
    if np.any(touching):
        n[touching] = _crossing_normal(u[touching], v[touching], (q + 0.5 * v - p - 0.5 * u)[touching])
    return d, ca, cb, n


def _crossing_normal(u: Array, v: Array, centres: Array) -> Array:
    """Unit normal of meeting segments: ``u × v``, else ⟂ ``u``; pointing along the centre difference."""
    n = np.cross(u, v)
    parallel = np.linalg.norm(n, axis=-1) <= _PARALLEL_REL * np.linalg.norm(u, axis=-1) * np.linalg.norm(v, axis=-1)
    if np.any(parallel):
        perp = centres[parallel] - _dot(centres[parallel], _unit_or_z(u[parallel]))[:, None] * _unit_or_z(u[parallel])
        fallback = np.cross(_unit_or_z(u[parallel]), _least_aligned_axis(_unit_or_z(u[parallel])))
        small = np.linalg.norm(perp, axis=-1) <= DEGENERATE_M
        n[parallel] = np.where(small[:, None], fallback, perp)
    n = _unit(n)
    return np.where((_dot(n, centres) < 0.0)[:, None], -n, n)


def _unit_or_z(u: Array) -> Array:
    norm = np.linalg.norm(u, axis=-1, keepdims=True)
    return np.where(norm > 0.0, u / np.where(norm > 0.0, norm, 1.0), np.array([0.0, 0.0, 1.0]))


def _least_aligned_axis(u: Array) -> Array:
    return np.eye(3)[np.argmin(np.abs(u), axis=-1)]


def point_box(x: Array, half: Array) -> Array:
    """Closest points of the boxes ``|y_i| ≤ half_i`` (half (n, 3)) to the points ``x`` (n, ..., 3), box frames."""
    h = half.reshape(len(half), *(1,) * (x.ndim - 2), 3)
    return np.clip(x, -h, h)


def _box_edges(half: Array) -> tuple[Array, Array]:
    """The 12 edges of boxes centred at 0 (their frames), half sides (n, 3): start points and direction vectors
    (n, 12, 3)."""
    return _EDGE_START_SIGNS[None] * half[:, None, :], _EDGE_DIRECTIONS[None] * (2.0 * half[:, None, :])


def _to_frame(T: Array, x: Array) -> Array:
    """Points (n, ..., 3) from the world into the frame of ``T`` (n, 4, 4)."""
    extra = (1,) * (x.ndim - 2)
    R = T[:, :3, :3].reshape(T.shape[0], *extra, 3, 3)
    o = T[:, :3, 3].reshape(T.shape[0], *extra, 3)
    return np.einsum("...ji,...j->...i", R, x - o)


def _to_world(T: Array, x: Array, direction: bool = False) -> Array:
    out = np.einsum("nij,nj->ni", T[:, :3, :3], x)
    return out if direction else out + T[:, :3, 3]


def box_segment(half: Array, T_box: Array, p: Array, u: Array) -> tuple[Array, Array, Array, Array]:
    """Signed core distance [m] of a box (half sides ``half``, pose ``T_box``) and segments ``p + s u`` (world).

    Returns ``(d, c_box, c_seg, n)``: ``c_seg − c_box = d n``, ``n`` moves the segment away (world).
    """
    a, du = _to_frame(T_box, p), np.einsum("nji,nj->ni", T_box[:, :3, :3], u)
    d_sep, c_box, c_seg = _box_segment_separated(half, a, du)
    n_sep = (c_seg - c_box) / np.maximum(d_sep, DEGENERATE_M)[:, None]
    inside = _segment_meets_box(half, a, du) | (d_sep <= DEGENERATE_M)
    d = d_sep.copy()
    n = n_sep
    if np.any(inside):
        depth, cb_in, cs_in, n_in = _box_segment_penetration(half[inside], a[inside], du[inside])
        d[inside], c_box[inside], c_seg[inside], n[inside] = -depth, cb_in, cs_in, n_in
    return d, _to_world(T_box, c_box), _to_world(T_box, c_seg), _to_world(T_box, n, direction=True)


def _box_segment_separated(half: Array, a: Array, du: Array) -> tuple[Array, Array, Array]:
    """Distance and closest points (box frame) of a box and disjoint segments: end points and 12 edges."""
    ends = np.stack([a, a + du], axis=1)  # (n, 2, 3)
    on_box_ends = point_box(ends, half)
    e0, ed = _box_edges(half)
    s, t = closest_segment_params(a[:, None, :], du[:, None, :], e0, ed)
    on_seg = a[:, None, :] + s[..., None] * du[:, None, :]
    on_edge = e0 + t[..., None] * ed
    box_pts = np.concatenate([on_box_ends, on_edge], axis=1)  # (n, 14, 3)
    seg_pts = np.concatenate([ends, on_seg], axis=1)
    dist = np.linalg.norm(seg_pts - box_pts, axis=-1)
    k = np.argmin(dist, axis=1)
    rows = np.arange(len(a))
    return dist[rows, k], box_pts[rows, k], seg_pts[rows, k]


def _segment_meets_box(half: Array, a: Array, du: Array) -> Array:
    """Whether segments ``a + s du`` (box frame) meet the closed box (slab clipping)."""
    lo, hi = np.zeros(len(a)), np.ones(len(a))
    for i in range(3):
        moving = np.abs(du[:, i]) > 0.0
        step = np.where(moving, du[:, i], 1.0)
        t1, t2 = (-half[:, i] - a[:, i]) / step, (half[:, i] - a[:, i]) / step
        lo = np.where(moving, np.maximum(lo, np.minimum(t1, t2)), lo)
        hi = np.where(moving, np.minimum(hi, np.maximum(t1, t2)), hi)
        outside = ~moving & (np.abs(a[:, i]) > half[:, i])
        hi = np.where(outside, -1.0, hi)
    return lo <= hi


def _box_segment_penetration(half: Array, a: Array, du: Array) -> tuple[Array, Array, Array, Array]:
    """Penetration depth of a box and segments that meet it (box frame): SAT over the 6 candidate axes."""
    m = len(a)
    axes = np.concatenate([np.broadcast_to(np.eye(3), (m, 3, 3)), np.cross(du[:, None, :], np.eye(3)[None])], axis=1)
    norms = np.linalg.norm(axes, axis=-1)
    valid = norms > _PARALLEL_REL * np.maximum(np.linalg.norm(du, axis=-1, keepdims=True), 1.0)
    axes = axes / np.where(valid, norms, 1.0)[..., None]
    radius = _dot(np.abs(axes), half[:, None, :])
    proj0, proj1 = _dot(axes, a[:, None, :]), _dot(axes, (a + du)[:, None, :])
    push_plus = radius - np.minimum(proj0, proj1)  # move the segment along +axis until it clears the box
    push_minus = np.maximum(proj0, proj1) + radius
    depth_axes = np.where(valid, np.minimum(push_plus, push_minus), np.inf)
    k = np.argmin(depth_axes, axis=1)
    rows = np.arange(m)
    depth = depth_axes[rows, k]
    n = axes[rows, k] * np.where(push_plus[rows, k] <= push_minus[rows, k], 1.0, -1.0)[:, None]
    # witnesses: a contact point of the pose separated by the depth (touching there), moved back
    _, c_box, c_seg = _box_segment_separated(half, a + depth[:, None] * n, du)
    return depth, c_box, c_seg - depth[:, None] * n, n


def box_box(half_a: Array, T_a: Array, half_b: Array, T_b: Array) -> tuple[Array, Array, Array, Array]:
    """Signed core distance [m] of two boxes; ``(d, c_a, c_b, n)`` with ``c_b − c_a = d n`` (world)."""
    R = np.einsum("nji,njk->nik", T_a[:, :3, :3], T_b[:, :3, :3])  # B's axes in A's frame (columns)
    c = _to_frame(T_a, T_b[:, :3, 3])
    depth, n = _box_box_sat(half_a, half_b, R, c)
    inside = depth >= 0.0
    d, ca, cb = _box_box_separated(half_a, half_b, R, c)
    nn = (cb - ca) / np.maximum(d, DEGENERATE_M)[:, None]
    touching = ~inside & (d <= DEGENERATE_M)
    nn[touching] = n[touching]
    if np.any(inside):
        d[inside] = -depth[inside]
        # witnesses: a contact point of the pose separated by the depth (touching there), B's moved back
        shift = depth[inside, None] * n[inside]
        _, ca[inside], cb_touch = _box_box_separated(half_a[inside], half_b[inside], R[inside], c[inside] + shift)
        cb[inside] = cb_touch - shift
        nn[inside] = n[inside]
    return d, _to_world(T_a, ca), _to_world(T_a, cb), _to_world(T_a, nn, direction=True)


def _box_box_axes(R: Array) -> tuple[Array, Array]:
    """The 15 SAT candidate axes (A's frame), unit where valid, and their validity."""
    m = len(R)
    ea = np.broadcast_to(np.eye(3), (m, 3, 3))
    eb = np.swapaxes(R, 1, 2)  # rows: B's axes
    cross = np.cross(ea[:, :, None, :], eb[:, None, :, :]).reshape(m, 9, 3)
    axes = np.concatenate([ea, eb, cross], axis=1)
    norms = np.linalg.norm(axes, axis=-1)
    valid = norms > _PARALLEL_REL
    return axes / np.where(valid, norms, 1.0)[..., None], valid


def _box_box_sat(half_a: Array, half_b: Array, R: Array, c: Array) -> tuple[Array, Array, Array]:
    """Smallest overlap over the 15 axes: ≥ 0 when the boxes meet (then it is the penetration depth), < 0 when
    some axis separates them; and that axis, oriented so that moving B along it separates them."""
    axes, valid = _box_box_axes(R)
    r_a = _dot(np.abs(axes), half_a[:, None, :])
    r_b = np.einsum("nkj,nj->nk", np.abs(np.einsum("nki,nij->nkj", axes, R)), half_b)
    centre = _dot(axes, c[:, None, :])
    push_plus = r_a + r_b - centre
    push_minus = r_a + r_b + centre
    depth_axes = np.where(valid, np.minimum(push_plus, push_minus), np.inf)
    k = np.argmin(depth_axes, axis=1)
    rows = np.arange(len(R))
    n = axes[rows, k] * np.where(push_plus[rows, k] <= push_minus[rows, k], 1.0, -1.0)[:, None]
    return depth_axes[rows, k], n


def _box_box_separated(half_a: Array, half_b: Array, R: Array, c: Array) -> tuple[Array, Array, Array]:
    """Distance and closest points (A's frame) of disjoint boxes: vertices against boxes, edges against edges."""
    vb = c[:, None, :] + np.einsum("nij,nkj->nki", R, _VERTEX_SIGNS[None] * half_b[:, None, :])  # in A's frame
    on_a = point_box(vb, half_a)
    va = _VERTEX_SIGNS[None] * half_a[:, None, :]
    va_in_b = np.einsum("nji,nkj->nki", R, va - c[:, None, :])
    on_b = c[:, None, :] + np.einsum("nij,nkj->nki", R, point_box(va_in_b, half_b))
    ea0, ead = _box_edges(half_a)
    eb0, ebd = _box_edges(half_b)
    b0 = c[:, None, :] + np.einsum("nij,nkj->nki", R, eb0)
    bd = np.einsum("nij,nkj->nki", R, ebd)
    s, t = closest_segment_params(ea0[:, :, None, :], ead[:, :, None, :], b0[:, None, :, :], bd[:, None, :, :])
    pa_edge = (ea0[:, :, None, :] + s[..., None] * ead[:, :, None, :]).reshape(len(R), 144, 3)
    pb_edge = (b0[:, None, :, :] + t[..., None] * bd[:, None, :, :]).reshape(len(R), 144, 3)
    pa = np.concatenate([on_a, va, pa_edge], axis=1)
    pb = np.concatenate([vb, on_b, pb_edge], axis=1)
    dist = np.linalg.norm(pb - pa, axis=-1)
    k = np.argmin(dist, axis=1)
    rows = np.arange(len(R))
    return dist[rows, k], pa[rows, k], pb[rows, k]


