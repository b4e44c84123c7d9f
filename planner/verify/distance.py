"""verify's own exact signed distances of boxes and capsules, vectorised over poses (shares no code with the NLPs').

:func:`planner.verify.verifier.verify` is a second opinion: its distances must not come from the engine the NLPs use, so
this module is written from the maths with different algorithms, and reads only the shape dataclasses of
:mod:`planner.model.shapes`. Every shape is a convex *core* swept by a ball (a box is its own core with radius 0, a
capsule is its segment with its radius); the signed distance of two sphere-swept convex sets is the signed
distance of their cores minus both radii, with the same normal, so only cores are handled below. Why each
routine is exact:

* segment–segment: ``|p(s) - q(t)|²`` is a convex quadratic on the rectangle of parameters, so its minimum is
  either the interior stationary point (when it lies inside) or the minimum on one of the 4 edges, each a
  1-D convex quadratic minimised by the clamped projection. All 5 candidates are evaluated and the smallest
  kept. Two segments never penetrate (their Minkowski difference is flat): the core depth is 0.
* segment–box, separated: in the box frame ``f(t) = Σ_i max(|p_i(t)| - h_i, 0)²`` is the squared distance of
  the segment point ``p(t)`` to the box, convex and piecewise quadratic in ``t``; between consecutive
  breakpoints (where ``|p_i(t)| = h_i``) the set of active coordinates and their signs is fixed, so ``f`` is one
  quadratic there, minimised in closed form and clamped to the piece. The smallest piece minimum is the minimum.
* box–box, separated: a closest pair of two disjoint polytopes can always be chosen with a vertex of one against
  the other or on an edge of each; every vertex is an end of an edge, so the minimum of the segment–box distance
  over the 12 edges of each box against the other box is the distance.
* meeting and penetration depth: the separating-axis theorem over the exact candidate axes, the facet normals
  of the Minkowski difference (for a box and a segment the 3 box axes and the segment's cross products with
  them; for two boxes their 6 face normals and 9 edge cross products). The cores meet iff every axis overlaps,
  and the penetration depth (smallest separating translation) is the smallest overlap. Cross products of
  nearly parallel directions (sine below :data:`AXIS_MIN_SIN`) are dropped: such a facet is a strip under
  2e-8 m wide, which moves the depth by less than that, while its rounded direction would cost more.
* penetration witnesses: B translated by the depth along the normal touches A; the separated routine gives a
  contact pair there, moved back by the depth, so ``p_b - p_a = d n`` holds and both points lie on the surfaces.

Degenerate normals: where the closest core points are within :data:`TOUCH_M` (their direction is rounding),
the normal is structural: the best separating axis for boxes (moving B along it raises the distance at rate 1
since it separates the touching cores), and for segments their common normal (or any direction across
parallel segments), along which every pair's gap grows at rate 1. Conventions of
:mod:`planner.collision.closed_form`: ``p_world_b - p_world_a = distance_m * normal_world``, translating B by
``+ε n`` increases the distance by ``ε``; poses are ``T_world_shape`` (n, 4, 4) or one 4×4, metres.

Internally every vector is stored coordinate-first, ``(3, ..., n)`` with the poses on the last (contiguous)
axis, so each step is one numpy operation over all poses and candidates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.model.shapes import Box, Capsule

Array = NDArray[np.float64]
Shape = Box | Capsule

# Closest core points nearer than this [m] are touching: their direction is rounding, use a structural normal.
TOUCH_M = 1e-10
# Separating-axis cross products of unit directions with a norm (sine) at or below this are not candidates.
AXIS_MIN_SIN = 1e-8
# Segments whose direction sine is at or below this are parallel for the contact normal.
PARALLEL_SIN = 1e-12


@dataclass(frozen=True)
class PairDistances:
    """Per pose: signed distance (m; > 0 separated, < 0 minus the penetration depth), witness points on A's and
    B's surfaces and the unit normal from A to B (world frame).

    Arrays: ``distance_m`` (n,), ``p_world_a``, ``p_world_b``, ``normal_world`` (n, 3).
    """

    distance_m: Array
    p_world_a: Array
    p_world_b: Array
    normal_world: Array


@dataclass(frozen=True)
class _Core:
    """Core signed distance [m] (n,), a core witness on A and the unit normal A → B (3, n), world frame."""

    d: Array
    c_a: Array
    n: Array


def shape_distance(shape_a: Shape, T_world_a: Array, shape_b: Shape, T_world_b: Array) -> PairDistances:
    """Signed distance of ``shape_a`` posed by ``T_world_a`` and ``shape_b`` by ``T_world_b`` ((n, 4, 4) or 4×4, m)."""
    Ta = np.asarray(T_world_a, dtype=float).reshape(-1, 4, 4)
    Tb = np.asarray(T_world_b, dtype=float).reshape(-1, 4, 4)
    Ta, Tb = np.broadcast_arrays(Ta, Tb)
    if len(Ta) == 0:
        return PairDistances(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
    Ta, Tb = np.ascontiguousarray(Ta.transpose(1, 2, 0)), np.ascontiguousarray(Tb.transpose(1, 2, 0))  # (4, 4, n)
    if isinstance(shape_a, Capsule) and isinstance(shape_b, Capsule):
        la, lb = _half_length(shape_a), _half_length(shape_b)
        core = _segment_segment(Ta[:3, 3], Ta[:3, 2], la, Tb[:3, 3], Tb[:3, 2], lb)
    elif isinstance(shape_a, Box) and isinstance(shape_b, Capsule):
        d, on_box, on_seg, n = _box_segment(_half_size(shape_a), Ta, Tb[:3, 3], Tb[:3, 2], _half_length(shape_b))
        core = _Core(d, on_box, n)
    elif isinstance(shape_a, Capsule) and isinstance(shape_b, Box):
        d, on_box, on_seg, n = _box_segment(_half_size(shape_b), Tb, Ta[:3, 3], Ta[:3, 2], _half_length(shape_a))
        core = _Core(d, on_seg, -n)
    elif isinstance(shape_a, Box) and isinstance(shape_b, Box):
        core = _box_box(_half_size(shape_a), Ta, _half_size(shape_b), Tb)
    else:
        raise TypeError(f"unsupported shapes {type(shape_a).__name__}, {type(shape_b).__name__}")
    ra, rb = _radius(shape_a), _radius(shape_b)
    d = core.d - ra - rb
    p_a = core.c_a + ra * core.n
    return PairDistances(d, p_a.T.copy(), (p_a + d * core.n).T.copy(), core.n.T.copy())


def _radius(shape: Shape) -> float:
    return float(shape.radius_m) if isinstance(shape, Capsule) else 0.0


def _half_length(capsule: Capsule) -> float:
    return 0.5 * float(capsule.length_m)


def _half_size(box: Box) -> Array:
    return 0.5 * np.asarray(box.size_m, dtype=float)


# ------------------------------------------------------------------------------- coordinate-first vectors
def _dot(a: Array, b: Array) -> Array:
    """Dot products of (3, ...) vectors over the leading axis."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Array, b: Array) -> Array:
    """Cross products of (3, ...) vectors."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _unit(v: Array) -> Array:
    """(3, ...) vectors scaled to unit length (zero vectors stay zero)."""
    norm = np.sqrt(_dot(v, v))
    return np.divide(v, norm, out=np.zeros_like(v), where=norm > 0.0)


def _rot(R: Array, v: Array) -> Array:
    """``R v`` for rotations (3, 3, n) and vectors (3, ..., n) (or (3, ..., 1) constants)."""
    R = R.reshape(R.shape[:2] + (1,) * (v.ndim - 2) + R.shape[2:])
    return R[:, 0] * v[0] + R[:, 1] * v[1] + R[:, 2] * v[2]


def _rot_t(R: Array, v: Array) -> Array:
    """``Rᵀ v`` for rotations (3, 3, n) and vectors (3, ..., n) (or (3, ..., 1) constants)."""
    R = R.reshape(R.shape[:2] + (1,) * (v.ndim - 2) + R.shape[2:])
    return R[0] * v[0] + R[1] * v[1] + R[2] * v[2]


def _pick(x: Array, k: Array) -> Array:
    """Entry ``k[j]`` of candidate axis 1 for each pose j: (3, m, n) → (3, n), or (m, n) → (n,)."""
    j = np.arange(k.shape[-1])
    return x[:, k, j] if x.ndim == 3 else x[k, j]


def _across(u: Array) -> Array:
    """(3, n) unit vectors orthogonal to the unit vectors ``u``: the cross product with the world axis least
    aligned with each (its sine is at least sqrt(2/3), so the result is well conditioned)."""
    e = np.zeros_like(u)
    e[np.argmin(np.abs(u), axis=0), np.arange(u.shape[1])] = 1.0
    return _unit(_cross(u, e))


# --------------------------------------------------------------------------------------- segment-segment
def _segment_candidates(ca: Array, ua: Array, la: float, cb: Array, ub: Array, lb: float) -> tuple[Array, Array]:
    """Parameters (s, t) (m along each unit direction, |s| <= la, |t| <= lb), each (5, n), of the candidate
    minimisers of ``|ca + s ua - cb - t ub|``: the interior stationary point (NaN when outside or the lines are
    parallel) and the minimum on each edge s = ±la, t = ±lb (clamped projections of the other parameter)."""
    r = cb - ca
    c = _cross(ua, ub)
    den = _dot(c, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        # Stationary point of the lines in cross-product form (Lagrange's identity: no a e - b² cancellation).
        s0 = _dot(_cross(r, ub), c) / den
        t0 = _dot(_cross(r, ua), c) / den
    inside = (den > 0.0) & (np.abs(s0) <= la) & (np.abs(t0) <= lb)
    ones = np.ones_like(den)
    s_fixed = np.stack([np.where(inside, s0, np.nan), -la * ones, la * ones])  # t: clamped projection
    t_fixed = np.stack([-lb * ones, lb * ones])  # s: clamped projection
    # The stationary point's t is refined the same way (exact for the 1-D quadratic in t at that s).
    t_of_s = np.clip(_dot(ca[:, None] + s_fixed * ua[:, None] - cb[:, None], ub[:, None]), -lb, lb)
    s_of_t = np.clip(_dot(cb[:, None] + t_fixed * ub[:, None] - ca[:, None], ua[:, None]), -la, la)
    return np.concatenate([s_fixed, s_of_t]), np.concatenate([t_of_s, t_fixed])


def _segment_segment(ca: Array, ua: Array, la: float, cb: Array, ub: Array, lb: float) -> _Core:
    """Distance [m] of segments ``c ± l u`` (centres and unit directions (3, n), half-lengths l >= 0)."""
    s, t = _segment_candidates(ca, ua, la, cb, ub, lb)
    pa = ca[:, None] + s * ua[:, None]  # (3, 5, n); NaN for a stationary point outside
    pb = cb[:, None] + t * ub[:, None]
    gap = _dot(pb - pa, pb - pa)
    k = np.argmin(np.where(np.isnan(gap), np.inf, gap), axis=0)
    pa, diff = _pick(pa, k), _pick(pb - pa, k)
    d = np.sqrt(_dot(diff, diff))
    # Meeting or touching cores: the common normal of non-parallel segments (every pair's gap along it grows at
    # rate 1), else any direction across both; oriented along the rounding residue when it has a sign.
    c = _cross(ua, ub)
    flat = np.where(_dot(c, c) > PARALLEL_SIN**2, _unit(c), _across(ua))
    flat *= np.where(_dot(flat, diff) < 0.0, -1.0, 1.0)
    return _Core(d, pa, np.where(d >= TOUCH_M, diff / np.maximum(d, TOUCH_M), flat))


# ------------------------------------------------------------------------------------------- segment-box
def _segment_box_local(m: Array, u: Array, ell: Array, h: Array) -> tuple[Array, Array]:
    """Closest parameter ``t`` (|t| <= ell, m) of segments ``m + t u`` to boxes ``|x_i| <= h_i`` in the boxes'
    frames, and the distance [m]. Shapes: m, u (3, *S), ell broadcastable to S, h (3,). Minimises the convex
    piecewise quadratic ``f(t) = Σ_i max(|m_i + t u_i| - h_i, 0)²`` exactly on each piece between breakpoints."""
    ell = np.broadcast_to(ell, m.shape[1:])
    with np.errstate(divide="ignore", invalid="ignore"):
        breaks = [(side * h[i] - m[i]) / u[i] for i in range(3) for side in (1.0, -1.0)]  # |m_i + t u_i| = h_i
    knots = np.stack([-ell, *breaks, ell])
    knots = np.minimum(np.maximum(np.where(np.isfinite(knots), knots, -ell), -ell), ell)
    knots.sort(axis=0)
    lo, hi = knots[:-1], knots[1:]  # (7, *S) pieces
    mid = 0.5 * (lo + hi)
    # On a piece each coordinate is inside its slab or outside on one side σ_i: f = Σ_out (m_i - σ_i h_i + t u_i)².
    num, den = np.zeros_like(lo), np.zeros_like(lo)
    for i in range(3):
        x = m[i] + mid * u[i]
        sigma = (x > h[i]).astype(float) - (x < -h[i])
        out_u = np.abs(sigma) * u[i]
        num -= out_u * (m[i] - sigma * h[i])
        den += out_u * u[i]
    t = np.minimum(np.maximum(np.divide(num, den, out=np.array(mid), where=den > 0.0), lo), hi)  # flat: any t
    f = np.zeros_like(t)
    for i in range(3):
        f += np.maximum(np.abs(m[i] + t * u[i]) - h[i], 0.0) ** 2
    k = np.argmin(f, axis=0)[None]
    return np.take_along_axis(t, k, axis=0)[0], np.sqrt(np.take_along_axis(f, k, axis=0)[0])


def _box_segment_sat(h: Array, m: Array, u: Array, ell: float) -> tuple[Array, Array]:
    """Separating-axis test of the box ``|x_i| <= h_i`` and segments ``m ± ell u`` (box frame, (3, n)): the
    smallest overlap (m; > 0 penetration depth, <= 0 minus a separating gap) and its unit axis (3, n), oriented
    so that translating the segment along it separates."""
    zero = np.zeros_like(u[0])
    cross = np.stack([np.stack([zero, u[2], -u[1]]),  # u × e_x, u × e_y, u × e_z: (3, 3, n)
                      np.stack([-u[2], zero, u[0]]),
                      np.stack([u[1], -u[0], zero])], axis=1)
    sin = np.sqrt(_dot(cross, cross))
    axes = np.concatenate([np.broadcast_to(np.eye(3)[:, :, None], (3, 3, len(zero))), _unit(cross)], axis=1)
    valid = np.concatenate([np.ones((3, len(zero)), bool), sin > AXIS_MIN_SIN])  # (6, n)
    r_box = h[0] * np.abs(axes[0]) + h[1] * np.abs(axes[1]) + h[2] * np.abs(axes[2])
    centre, half = _dot(axes, m[:, None]), ell * np.abs(_dot(axes, u[:, None]))
    return _best_axis(r_box - (centre - half), r_box + (centre + half), axes, valid)


def _best_axis(push_plus: Array, push_minus: Array, axes: Array, valid: Array) -> tuple[Array, Array]:
    """Smallest push (n,) over valid axes (3, m, n) and both senses, and its signed unit axis (3, n)."""
    push = np.where(valid, np.concatenate([push_plus, push_minus]).reshape(2, *valid.shape), np.inf)
    push = push.reshape(-1, push.shape[-1])
    k = np.argmin(push, axis=0)
    m = axes.shape[1]
    return _pick(push, k), _pick(axes, k % m) * np.where(k < m, 1.0, -1.0)


def _box_segment(h: Array, T_box: Array, cs: Array, us: Array, ell: float) -> tuple[Array, Array, Array, Array]:
    """Signed core distance [m] of boxes (half sizes ``h``, poses ``T_box`` (4, 4, n)) and segments ``cs ± ell us``
    ((3, n) each): (distance, witness on the box, witness on the segment, unit normal box → segment), world
    frame, the witnesses in the given poses (penetrating: a contact pair, moved back by the depth)."""
    R, cb = T_box[:3, :3], T_box[:3, 3]
    m, u = _rot_t(R, cs - cb), _rot_t(R, us)
    depth, axis = _box_segment_sat(h, m, u, ell)
    d, on_box, on_seg, n = _box_segment_apart(h, R, cb, m, u, ell, axis)
    pen = depth > 0.0
    if pen.any():  # the segment moved out along the best axis by the depth touches the box: a contact pair
        depth_p, axis_p, R_p = depth[pen], axis[:, pen], R[..., pen]
        _, box_p, seg_p, _ = _box_segment_apart(h, R_p, cb[:, pen], m[:, pen] + depth_p * axis_p, u[:, pen], ell,
                                                axis_p)
        n[:, pen] = _rot(R_p, axis_p)
        d[pen], on_box[:, pen], on_seg[:, pen] = -depth_p, box_p, seg_p - depth_p * n[:, pen]
    return d, on_box, on_seg, n


def _box_segment_apart(h: Array, R: Array, cb: Array, m: Array, u: Array, ell: float,
                       axis: Array) -> tuple[Array, Array, Array, Array]:
    """Closest points of boxes (rotations ``R`` (3, 3, n), centres ``cb``) and segments ``m ± ell u`` given in
    the box frames, the cores taken as apart or touching: (distance [m], box point, segment point, unit normal
    box → segment), world frame. Touching cores take the separating ``axis`` (box frame) as their normal."""
    t, d = _segment_box_local(m, u, np.asarray(ell, dtype=float), h)
    q = m + t * u
    q_box = np.clip(q, -h[:, None], h[:, None])
    n_local = np.where(d >= TOUCH_M, (q - q_box) / np.maximum(d, TOUCH_M), axis)
    return d, cb + _rot(R, q_box), cb + _rot(R, q), _rot(R, n_local)


# ----------------------------------------------------------------------------------------------- box-box
def _edges(h: Array) -> tuple[Array, Array, Array]:
    """A box's 12 edges in its frame: centres and unit directions (3, 12, 1), half-lengths (12, 1) [m]."""
    axis = np.repeat(np.arange(3), 4)
    signs = np.tile(np.array([[-1.0, -1.0], [-1.0, 1.0], [1.0, -1.0], [1.0, 1.0]]), (3, 1))
    centres = np.zeros((12, 3))
    for j, k in enumerate(axis):
        others = [i for i in range(3) if i != k]
        centres[j, others] = signs[j] * h[others]
    return centres.T[..., None], np.eye(3)[axis].T[..., None], h[axis][:, None]


def _box_box_sat(ha: Array, hb: Array, R: Array, t: Array) -> tuple[Array, Array]:
    """Separating-axis test of boxes A (half sizes ``ha``, at the origin of its frame) and B (``hb``, rotation
    ``R`` (3, 3, n) and centre ``t`` (3, n) in A's frame): smallest overlap (m; > 0 depth) and its unit axis in
    A's frame, oriented so that translating B along it separates. Axes: 3 + 3 face normals, 9 edge crosses."""
    b = R  # b[:, j]: B's axis j in A's frame, (3, 3, n)
    zero = np.zeros_like(b[0])
    cross = np.concatenate([np.stack([zero, -b[2], b[1]]),  # e_x × b_j, e_y × b_j, e_z × b_j: (3, 9, n)
                            np.stack([b[2], zero, -b[0]]),
                            np.stack([-b[1], b[0], zero])], axis=1)
    sin = np.sqrt(_dot(cross, cross))
    axes = np.concatenate([np.broadcast_to(np.eye(3)[:, :, None], b.shape), b, _unit(cross)], axis=1)
    valid = np.concatenate([np.ones((6, b.shape[2]), bool), sin > AXIS_MIN_SIN])  # (15, n)
    reach = sum(ha[i] * np.abs(axes[i]) for i in range(3))  # radius of A along each axis, plus B's:
    reach = reach + sum(hb[j] * np.abs(_dot(axes, b[:, j][:, None])) for j in range(3))
    centre = _dot(axes, t[:, None])
    return _best_axis(reach - centre, reach + centre, axes, valid)


def _box_box_apart(ha: Array, hb: Array, R: Array, t: Array, axis: Array) -> tuple[Array, Array, Array]:
    """Closest points of boxes taken as apart or touching, in A's frame (B: rotation ``R``, centre ``t``): the
    minimum of the segment-box distance over A's 12 edges against B and B's 12 edges against A. Returns
    (distance [m], witness on A, unit normal A → B (``axis`` where touching)), A's frame, (n,) and (3, n)."""
    centre_a, dir_a, half_a = _edges(ha)
    centre_b, dir_b, half_b = _edges(hb)
    m_a, u_a = _rot_t(R, centre_a - t[:, None]), _rot_t(R, dir_a)  # A's edges in B's frame: Rᵀ (x - t)
    m_b, u_b = _rot(R, centre_b) + t[:, None], _rot(R, dir_b)  # B's edges in A's frame: R x + t
    s_a, d_a = _segment_box_local(m_a, u_a, half_a, hb)
    s_b, d_b = _segment_box_local(m_b, u_b, half_b, ha)
    q_a = m_a + s_a * u_a  # A's edge point, B's frame
    q_b = m_b + s_b * u_b  # B's edge point, A's frame
    hha, hhb = ha[:, None, None], hb[:, None, None]
    on_a = np.concatenate([centre_a + s_a * dir_a, np.clip(q_b, -hha, hha)], axis=1)  # (3, 24, n)
    gap = np.concatenate([-_rot(R, q_a - np.clip(q_a, -hhb, hhb)), q_b - np.clip(q_b, -hha, hha)], axis=1)
    k = np.argmin(np.concatenate([d_a, d_b]), axis=0)
    d, g = _pick(np.concatenate([d_a, d_b]), k), _pick(gap, k)
    return d, _pick(on_a, k), np.where(d >= TOUCH_M, g / np.maximum(d, TOUCH_M), axis)


def _box_box(ha: Array, Ta: Array, hb: Array, Tb: Array) -> _Core:
    """Signed core distance [m] of boxes with half sizes ``ha``, ``hb`` at poses (4, 4, n)."""
    Ra, ca = Ta[:3, :3], Ta[:3, 3]
    R = np.einsum("kin,kjn->ijn", Ra, Tb[:3, :3])  # Raᵀ Rb: B's axes in A's frame
    t = _rot_t(Ra, Tb[:3, 3] - ca)
    depth, axis = _box_box_sat(ha, hb, R, t)
    d, on_a, n = _box_box_apart(ha, hb, R, t, axis)
    pen = depth > 0.0
    if pen.any():  # B moved out along the best axis by the depth touches A: a contact pair (A's point unmoved)
        _, on_a[:, pen], _ = _box_box_apart(ha, hb, R[..., pen], t[:, pen] + depth[pen] * axis[:, pen],
                                            axis[:, pen])
        d[pen], n[:, pen] = -depth[pen], axis[:, pen]
    return _Core(d, ca + _rot(Ra, on_a), _rot(Ra, n))
