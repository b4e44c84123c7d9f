"""Signed distances between rigid bodies made of boxes and capsules (paper §4.4, Eq. 19).

A :class:`CollisionScene` holds bodies (each a tuple of :class:`~planner.geometry.PlacedShape`) and a list
of body pairs. :meth:`CollisionScene.distances` returns, per pair, the signed distance (m; > 0 separated,
< 0 minus the penetration depth), one witness point on each body (world frame, m) and a unit normal
``n`` (world frame) with ``p_world_b - p_world_a = distance_m * n`` in every case, so that translating
body B by ``+ε n`` (or body A by ``-ε n``) increases the distance by ``ε`` to first order.
:func:`distance_gradient` turns that into ``∂d/∂x`` for any coordinates ``x`` (TrajOpt style).

Implementation: sphere-swept cores
----------------------------------
Every shape is handled as a *core* swept by a sphere: a box is its own core with radius 0, a capsule is
its segment (a python-fcl ``Capsule(0, length)``) with radius ``radius_m``. For convex sets the signed
distance of ``A ⊕ ball(r_a)`` and ``B ⊕ ball(r_b)`` is exactly ``sd(A, B) - r_a - r_b``, with the same
normal, and the witness points move by ``+r_a n`` / ``-r_b n``. We ask fcl only for the core distance
(``fcl.distance`` with ``enable_signed_distance=True``) and add the radii analytically. Why: fcl's signed
path runs GJK/EPA (libccd) on the real shapes, which converges slowly on curved surfaces. Measured on
2000 random seeded capsule pairs (python-fcl 0.7.0.11), full capsules in the signed path were off by up
to 1e-3 m when *separated* (99th percentile 3e-5 m) and up to 1e-6 m (median 3e-7 m) when penetrating
(EPA); box–capsule up to 2e-4 m separated and 1e-6 m penetrating. The cores are polytopes (boxes,
segments), on which GJK terminates exactly and EPA finds the exact face: on the same samples the core
formulation agrees with the analytic references to ~5e-16 m, separated or penetrating, and the gradient
test can use one tight tolerance for both. (fcl's *unsigned* path has an exact capsule–capsule routine,
but it reports -1 for any penetrating pair involving a box, so one signed request for everything is
simpler.)

Degenerate normal
-----------------
When the two core witness points coincide (``‖c_a - c_b‖ < 1e-9 m``: touching cores, or two segments that
cross, where the distance of the cores is 0 and the capsules penetrate by ``r_a + r_b``), the direction
cannot be read from the points. We then translate B's core by a small probe ``h = 1e-5 m`` along a
candidate direction (first the shape-centre difference ``centre_b - centre_a``, then the world axes) and
take the normal from fcl's witness points at the probed pose, as soon as they are ``> 1e-9 m`` apart.
Cores are polytopes, so in the generic degenerate case (face or edge contact, crossing segments) the
normal at the probed pose is the exact one-sided normal on the side the probe moved B to; the distance
and witness points reported are still those of the true pose. For touching cores the centre difference
always has a non-negative component along the outward normal, so the probe separates them and the normal
points the way that pushes the bodies apart. For crossing segments both centres lie in the plane of the
segments, the centre-difference probe slides along the contact, and the first world axis not in that
plane decides the side: ``d = |n·δ| - r_a - r_b`` under a translation ``δ`` of B is not differentiable
there, and either ``±n`` is a valid one-sided gradient.

fcl conventions relied upon (python-fcl 0.7, checked by the tests): ``Capsule(radius, lz)`` is centred
with its axis on z, ``Box(x, y, z)`` takes full side lengths, ``DistanceResult.nearest_points`` are in the
world frame, and the result is only overwritten by a smaller distance (so it is reset before reuse).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import fcl
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.geometry import Box, Capsule, PlacedShape

# Below this core witness-point separation (m) the normal is taken from a probe (see module docstring).
_DEGENERATE_TOL_M = 1e-9
# Probe translation (m) of B's core in the degenerate case: large enough that the probed witness points are
# far above _DEGENERATE_TOL_M for any probe direction not nearly tangent (|u·n| > 1e-4), small against shapes.
_PROBE_STEP_M = 1e-5


@dataclass(frozen=True)
class CollisionBody:
    """A rigid body of the collision model: shapes placed in the body frame (``T_body_shape``, m)."""

    name: str
    shapes: tuple[PlacedShape, ...]


@dataclass(frozen=True)
class PairDistance:
    """Signed distance between two bodies and where it is realised (all vectors in the world frame).

    ``p_world_b - p_world_a == distance_m * normal_world`` (up to rounding), separated or not.
    """

    pair: tuple[str, str]  # (body A, body B)
    distance_m: float  # signed: > 0 separated, < 0 minus the penetration depth (m)
    p_world_a: NDArray[np.float64]  # witness point on A's surface (world, m)
    p_world_b: NDArray[np.float64]  # witness point on B's surface (world, m)
    normal_world: NDArray[np.float64]  # unit; moving B by +ε n (or A by -ε n) increases distance_m by ε
    shape_pair: tuple[str, str]  # names of the shape of A and the shape of B that realise the minimum


@dataclass(frozen=True)
class _Core:
    """One shape as fcl sees it: a polytope core (box or segment) plus a sweep radius (m)."""

    body: str
    name: str
    obj: fcl.CollisionObject  # the core; its transform is rewritten on every distances() call
    radius_m: float
    T_body_shape: NDArray[np.float64]
    at_body_origin: bool  # T_body_shape is the identity: skip the product per call


def distance_gradient(pd: PairDistance, J_point_a: ArrayLike, J_point_b: ArrayLike) -> NDArray[np.float64]:
    """Gradient ``∂d/∂x = nᵀ (J_point_b - J_point_a)`` of a pair's signed distance (m per unit of ``x``).

    ``J_point_a`` / ``J_point_b`` (3×n_x) are the Jacobians, w.r.t. any coordinates ``x``, of the world
    positions of ``pd.p_world_a`` / ``pd.p_world_b`` *held fixed in their bodies*; e.g. for world-frame
    twists of a body with origin ``o`` (linear velocity at ``o``, angular velocity) it is
    ``[I, -[p - o]×]``.

    Why this is exact to first order where the witness pair is unique (convex shapes): for separated
    bodies ``d(x) = min ‖q - p‖`` over body-fixed points ``p̄ ∈ A``, ``q̄ ∈ B`` mapped to the world by the
    poses at ``x``. By Danskin's (envelope) theorem, when the minimiser is unique the derivative of the
    minimum equals the partial derivative of the objective at the minimiser held fixed, which is
    ``((q - p)/‖q - p‖)ᵀ (∂q/∂x - ∂p/∂x) = nᵀ (J_b - J_a)``: sliding the witness points along the
    surfaces changes ``d`` only to second order. In penetration ``-d`` is the depth
    ``min_{‖u‖=1} [h_A(u) + h_B(-u)]`` (support functions), a min of a max; with a unique optimal ``u``
    (``= n`` up to sign) and unique support points the same theorem applied twice gives the same formula.
    Where the witness pair is not unique (parallel faces or segments, crossing segments) ``d`` is only
    directionally differentiable and this is one element of its generalised gradient, as in TrajOpt.
    """
    Ja = np.asarray(J_point_a, dtype=float)
    Jb = np.asarray(J_point_b, dtype=float)
    if Ja.ndim != 2 or Ja.shape[0] != 3 or Ja.shape != Jb.shape:
        raise ValueError(f"point Jacobians must both be 3×n, got {Ja.shape} and {Jb.shape}")
    return pd.normal_world @ (Jb - Ja)


class CollisionScene:
    """Bodies of boxes and capsules and the body pairs whose signed distance is queried.

    The fcl objects are built once here; :meth:`distances` only sets transforms and calls ``fcl.distance``.
    """

    distance_gradient = staticmethod(distance_gradient)

    def __init__(
        self,
        bodies: Sequence[CollisionBody],
        pairs: Sequence[tuple[str, str]],
        scale: float | Mapping[str, float] = 1.0,
        excluded_shapes: Mapping[tuple[str, str], Collection[str]] | None = None,
    ) -> None:
        """Build the scene.

        Args:
            bodies: rigid bodies; names unique, shape names unique within a body.
            pairs: ordered body pairs ``(A, B)``; each is queried by :meth:`distances`, in this order.
            scale: overscaling factor of shape *dimensions* (paper §5: the robot geometric model was
                scaled), one for all bodies or per body name (bodies not named keep 1.0). Box sides and
                capsule radius and length are multiplied; shape positions in their body are not.
            excluded_shapes: per pair ``(A, B)``, names of B's shapes ignored for that pair only (e.g. the
                target's grasp handle, which only the gripper is allowed to touch).

        Raises:
            ValueError: unknown body or shape names, duplicate names or pairs, a pair of a body with
                itself, a non-positive scale, or a pair whose shapes are all excluded.
        """
        self._body_names: tuple[str, ...] = tuple(b.name for b in bodies)
        if len(set(self._body_names)) != len(self._body_names):
            raise ValueError(f"duplicate body names in {self._body_names}")
        body_by_name = {b.name: b for b in bodies}

        scales = {name: self._scale_of(scale, name) for name in self._body_names}
        if isinstance(scale, Mapping):
            unknown = set(scale) - set(self._body_names)
            if unknown:
                raise ValueError(f"scale given for unknown bodies {sorted(unknown)}")

        self._request = fcl.DistanceRequest(enable_nearest_points=True, enable_signed_distance=True)
        self._result = fcl.DistanceResult()
        self._cores: list[_Core] = []
        self._core_ids: dict[str, list[int]] = {}
        for body in bodies:
            names = [s.name for s in body.shapes]
            if not names:
                raise ValueError(f"body {body.name!r} has no shapes")
            if len(set(names)) != len(names):
                raise ValueError(f"body {body.name!r}: duplicate shape names {names}")
            ids = []
            for placed in body.shapes:
                ids.append(len(self._cores))
                self._cores.append(self._make_core(body.name, placed, scales[body.name]))
            self._core_ids[body.name] = ids

        excluded = dict(excluded_shapes or {})
        self._pairs: tuple[tuple[str, str], ...] = tuple((str(a), str(b)) for a, b in pairs)
        seen: set[frozenset[str]] = set()
        for a, b in self._pairs:
            for name in (a, b):
                if name not in body_by_name:
                    raise ValueError(f"pair ({a!r}, {b!r}): unknown body {name!r}")
            if a == b:
                raise ValueError(f"pair ({a!r}, {b!r}) pairs a body with itself")
            key = frozenset((a, b))
            if key in seen:
                raise ValueError(f"pair ({a!r}, {b!r}) is listed twice")
            seen.add(key)
        unknown_pairs = set(excluded) - set(self._pairs)
        if unknown_pairs:
            raise ValueError(f"excluded_shapes given for pairs not in the scene: {sorted(unknown_pairs)}")

        # Per pair: the (core of A, core of B, r_a + r_b) combinations to evaluate, fixed once here.
        self._pair_cores: list[list[tuple[int, int]]] = []
        for a, b in self._pairs:
            skip = set(excluded.get((a, b), ()))
            b_names = {self._cores[j].name for j in self._core_ids[b]}
            if skip - b_names:
                missing = sorted(skip - b_names)
                raise ValueError(f"pair ({a!r}, {b!r}): excluded shapes {missing} are not shapes of {b!r}")
            combos = [(i, j) for i in self._core_ids[a] for j in self._core_ids[b]
                      if self._cores[j].name not in skip]
            if not combos:
                raise ValueError(f"pair ({a!r}, {b!r}): every shape of {b!r} is excluded")
            self._pair_cores.append(combos)
        self._pair_combos = [
            [(i, j, self._cores[i].obj, self._cores[j].obj, self._cores[i].radius_m + self._cores[j].radius_m)
             for i, j in combos]
            for combos in self._pair_cores
        ]

        # Only bodies that appear in some pair need a pose per call.
        in_pairs = {name for pair in self._pairs for name in pair}
        self._used_bodies: tuple[str, ...] = tuple(n for n in self._body_names if n in in_pairs)
        self._T_world_core: list[NDArray[np.float64] | None] = [None] * len(self._cores)
        self._radii = np.array([c.radius_m for c in self._cores])

    @staticmethod
    def _scale_of(scale: float | Mapping[str, float], body: str) -> float:
        s = float(scale.get(body, 1.0)) if isinstance(scale, Mapping) else float(scale)
        if not (math.isfinite(s) and s > 0.0):
            raise ValueError(f"scale of body {body!r} must be finite and > 0, got {s}")
        return s

    @staticmethod
    def _make_core(body: str, placed: PlacedShape, scale: float) -> _Core:
        shape = placed.shape.scaled(scale)
        if isinstance(shape, Box):
            geom, radius = fcl.Box(*shape.size_m), 0.0
        elif isinstance(shape, Capsule):
            # Radius-0 capsule = the segment along z from -length/2 to +length/2 (fcl's centred convention).
            geom, radius = fcl.Capsule(0.0, shape.length_m), float(shape.radius_m)
        else:
            kind = type(shape).__name__
            raise ValueError(f"body {body!r} shape {placed.name!r}: unsupported shape type {kind}")
        T = np.array(placed.T_body_shape, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"body {body!r} shape {placed.name!r}: T_body_shape must be 4×4, got {T.shape}")
        obj = fcl.CollisionObject(geom, fcl.Transform())
        return _Core(body, placed.name, obj, radius, T, bool(np.array_equal(T, np.eye(4))))

    @property
    def pairs(self) -> tuple[tuple[str, str], ...]:
        """The queried body pairs ``(A, B)``, in the order of :meth:`distances`' output."""
        return self._pairs

    @property
    def body_names(self) -> tuple[str, ...]:
        """Names of all bodies, in construction order."""
        return self._body_names

    def distances(self, T_world_body: Mapping[str, ArrayLike]) -> list[PairDistance]:
        """Signed distance of every pair at the given body poses (4×4, world frame, m).

        A body with several shapes contributes the minimum over its shape pairs. Only the bodies of some
        pair need a pose; extra entries are ignored.

        Raises:
            KeyError: a body of some pair has no pose.
        """
        d, PA, PB, N, best_ids = self._sweep(T_world_body)
        cores = self._cores
        return [
            PairDistance(
                pair=pair,
                distance_m=float(d[k]),
                p_world_a=PA[k],
                p_world_b=PB[k],
                normal_world=N[k],
                shape_pair=(cores[i].name, cores[j].name),
            )
            for k, (pair, (i, j)) in enumerate(zip(self._pairs, best_ids, strict=True))
        ]

    def distance_arrays(self, T_world_body: Mapping[str, ArrayLike]) -> tuple[NDArray[np.float64], ...]:
        """:meth:`distances` as arrays, one row per pair: distances (m), witness points on A and on B, unit
        normals (world). For the NLPs' callbacks, which need no per-pair objects."""
        return self._sweep(T_world_body)[:4]

    def _sweep(self, T_world_body: Mapping[str, ArrayLike]) -> tuple:
        """``(d, PA, PB, N, best_ids)``: what :meth:`distances` reports, and the core pair realising each."""
        cores = self._cores
        for name in self._used_bodies:
            try:
                T_wb = np.asarray(T_world_body[name], dtype=float)
            except KeyError:
                raise KeyError(f"no pose given for collision body {name!r}") from None
            for i in self._core_ids[name]:
                core = cores[i]
                T = T_wb if core.at_body_origin else T_wb @ core.T_body_shape
                self._T_world_core[i] = T
                # Two setters: ~2× cheaper than building an fcl.Transform for setTransform.
                core.obj.setRotation(T[:3, :3])
                core.obj.setTranslation(T[:3, 3])

        # Hot loop (≈ 600 sweeps per NLP evaluation): locals, no per-combo allocation beyond fcl's own; the
        # normals and witness offsets are then computed for all pairs at once (a small numpy op costs ~1 µs).
        res, req, fcl_distance, inf = self._result, self._request, fcl.distance, math.inf
        m = len(self._pairs)
        d_best = np.empty(m)
        d_cores = np.empty(m)
        best_ids: list[tuple[int, int]] = []
        c_a: list[NDArray[np.float64]] = []
        c_b: list[NDArray[np.float64]] = []
        for k, combos in enumerate(self._pair_combos):
            best_d = inf
            best: tuple[float, int, int, list[NDArray[np.float64]]] | None = None
            for i, j, obj_a, obj_b, radius_sum in combos:
                # python-fcl only overwrites the result if the new distance is smaller: reset it to reuse it.
                res.min_distance = inf
                d_core = fcl_distance(obj_a, obj_b, req, res)
                if d_core - radius_sum < best_d:
                    best_d = d_core - radius_sum
                    # nearest_points is a fresh list of fresh arrays on every call: safe to keep.
                    best = (d_core, i, j, res.nearest_points)
            assert best is not None  # combos is never empty (checked in __init__)
            d_best[k] = best_d
            d_cores[k] = best[0]
            best_ids.append((best[1], best[2]))
            c_a.append(best[3][0])
            c_b.append(best[3][1])

        CA = np.array(c_a)
        CB = np.array(c_b)
        diff = CB - CA
        dist = np.sqrt(np.einsum("ij,ij->i", diff, diff))
        degenerate = dist < _DEGENERATE_TOL_M
        # Separated cores: n = (c_b - c_a)/‖·‖; penetrating cores (fcl's EPA): n = (c_a - c_b)/‖·‖.
        N = diff * (np.where(d_cores >= 0.0, 1.0, -1.0) / np.where(degenerate, 1.0, dist))[:, None]
        for k in np.flatnonzero(degenerate):
            i, j = best_ids[k]
            N[k] = self._probe_normal(i, j)
        ids = np.array(best_ids)
        PA = CA + self._radii[ids[:, 0], None] * N
        PB = CB - self._radii[ids[:, 1], None] * N
        return d_best, PA, PB, N, best_ids

    def _core_query(self, i: int, j: int) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
        """Signed distance (m) of cores i and j at their current transforms, and their witness points."""
        res = self._result
        # python-fcl only overwrites the result if the new distance is smaller: reset it to reuse it.
        res.min_distance = math.inf
        d = fcl.distance(self._cores[i].obj, self._cores[j].obj, self._request, res)
        return float(d), res.nearest_points[0], res.nearest_points[1]

    def _probe_normal(self, i: int, j: int) -> NDArray[np.float64]:
        """Unit normal (world) of cores i (A) and j (B) whose witness points coincide (module docstring)."""
        T_b = self._T_world_core[j]
        T_a = self._T_world_core[i]
        assert T_a is not None and T_b is not None
        obj_b = self._cores[j].obj
        candidates = [T_b[:3, 3] - T_a[:3, 3], *np.eye(3)]
        try:
            for u in candidates:
                norm_u = float(np.linalg.norm(u))
                if norm_u < _DEGENERATE_TOL_M:
                    continue
                p = T_b[:3, 3] + (_PROBE_STEP_M / norm_u) * u
                obj_b.setTransform(fcl.Transform(T_b[:3, :3], p))
                n = _normal_from_witnesses(*self._core_query(i, j))
                if n is not None:
                    return n
        finally:
            obj_b.setTransform(fcl.Transform(T_b[:3, :3], T_b[:3, 3]))
        # Unreachable for real geometry (a probe along one of the world axes always leaves the contact);
        # fall back to the centre difference rather than returning NaN into an optimiser.
        c = candidates[0]
        nc = float(np.linalg.norm(c))
        return c / nc if nc > 0.0 else np.array([0.0, 0.0, 1.0])



def _normal_from_witnesses(
    d_core: float, ca: NDArray[np.float64], cb: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """Unit normal from fcl's core witness points, or ``None`` if they (nearly) coincide.

    ``(cb - ca)/‖·‖`` when the cores are separated (``d_core > 0``), ``(ca - cb)/‖·‖`` when they penetrate:
    fcl's EPA then returns A's point deepest inside B and B's point deepest inside A (checked in the tests).
    The points alone cannot tell the two cases apart, hence the sign of ``d_core``.
    """
    diff = cb - ca
    dist = math.sqrt(diff.dot(diff))  # np.linalg.norm costs ~4× more here
    if dist < _DEGENERATE_TOL_M:
        return None
    return diff * (1.0 / dist if d_core >= 0.0 else -1.0 / dist)


def default_pairs(
    chaser_bodies: Sequence[str], adjacent: Collection[tuple[str, str]], target_bodies: Sequence[str]
) -> list[tuple[str, str]]:
    """Collision pairs: all non-adjacent chaser body pairs, then every chaser body against every target body.

    Adjacency is unordered. Chaser pairs are ``(chaser_bodies[i], chaser_bodies[j])`` with ``i < j``; target
    pairs are ``(chaser, target)`` so the target is body B (whose shapes ``excluded_shapes`` may name).
    With 8 chained chaser bodies (7 adjacent pairs) and 1 target body: 28 - 7 + 8 = 29 pairs (paper's m).

    Raises:
        ValueError: duplicate names, a body both chaser and target, an adjacent pair naming an unknown body.
    """
    chaser = list(chaser_bodies)
    target = list(target_bodies)
    if len(set(chaser)) != len(chaser) or len(set(target)) != len(target):
        raise ValueError("duplicate body names in default_pairs")
    if set(chaser) & set(target):
        raise ValueError(f"bodies both chaser and target: {sorted(set(chaser) & set(target))}")
    adj = set()
    for a, b in adjacent:
        if a not in chaser or b not in chaser:
            raise ValueError(f"adjacent pair ({a!r}, {b!r}) names a body not in chaser_bodies")
        adj.add(frozenset((a, b)))
    pairs = [
        (chaser[i], chaser[j])
        for i in range(len(chaser))
        for j in range(i + 1, len(chaser))
        if frozenset((chaser[i], chaser[j])) not in adj
    ]
    pairs += [(c, t) for c in chaser for t in target]
    return pairs


def closest_points_segment_segment(
    p0a: ArrayLike, p1a: ArrayLike, p0b: ArrayLike, p1b: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Closest points (m) of segments ``[p0a, p1a]`` and ``[p0b, p1b]`` (Ericson, RTCD §5.1.9, clamped).

    Parallel segments (``‖da × db‖² ≤ 1e-14 ‖da‖² ‖db‖²``) take ``s = 0`` and then clamp, which still gives
    a closest pair (the closest distance of parallel segments is attained at an end point of one of them).
    Degenerate (point) segments are handled.
    """
    P0a = np.asarray(p0a, dtype=float)
    P0b = np.asarray(p0b, dtype=float)
    da = np.asarray(p1a, dtype=float) - P0a
    db = np.asarray(p1b, dtype=float) - P0b
    r = P0a - P0b
    a = float(da @ da)
    e = float(db @ db)
    f = float(db @ r)
    tiny = 1e-300
    if a <= tiny and e <= tiny:
        return P0a, P0b
    if a <= tiny:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = float(da @ r)
        if e <= tiny:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            b = float(da @ db)
            denom = a * e - b * b  # = ‖da × db‖² ≥ 0
            # Relative test: for (near-)parallel segments the line solution is ill-conditioned; any s works
            # before the clamping below, which then finds the right end point.
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 1e-14 * a * e else 0.0
            t = (b * s + f) / e
            # t outside [0, 1]: clamp it and recompute the best s for that end point of segment b.
            if t < 0.0:
                t, s = 0.0, min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    return P0a + s * da, P0b + t * db


def capsule_capsule_distance(
    p0a: ArrayLike, p1a: ArrayLike, ra: float, p0b: ArrayLike, p1b: ArrayLike, rb: float
) -> float:
    """Signed distance (m) of two capsules given by segment end points (m) and radii (m), analytically.

    ``segment distance - ra - rb``: exact also in penetration, because a capsule is its segment swept by a
    ball and the signed distance of sphere-swept convex sets is that of their cores minus the radii (for
    crossing segments the depth is ``ra + rb``: the segments' Minkowski difference is flat).
    """
    ca, cb = closest_points_segment_segment(p0a, p1a, p0b, p1b)
    return float(np.linalg.norm(cb - ca)) - float(ra) - float(rb)
