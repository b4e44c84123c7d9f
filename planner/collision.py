"""Signed distances between rigid bodies made of boxes and capsules (paper §4.4, Eq. 19).

A :class:`CollisionScene` holds bodies (each a tuple of :class:`~planner.geometry.PlacedShape`) and a list
of body pairs. :meth:`CollisionScene.distances` returns, per pair, the signed distance (m; > 0 separated,
< 0 minus the penetration depth), one witness point on each body (world frame, m) and a unit normal
``n`` (world frame) with ``p_world_b - p_world_a = distance_m * n`` in every case, so that translating
body B by ``+ε n`` (or body A by ``-ε n``) increases the distance by ``ε`` to first order.
:func:`distance_gradient` turns that into ``∂d/∂x`` for any coordinates ``x`` (TrajOpt style).

Engine: coal
------------
Distances come from ``coal`` (the maintained successor of FCL, shipped with ``pin``) on the true shapes:
its capsule–capsule routine is closed form, and its GJK/EPA treats a capsule as a swept segment, so
box–capsule and box–box run on polytopes, where GJK terminates exactly and EPA finds the exact face.
python-fcl's signed path is not used: it overstates distances in aligned poses (by up to 1.9 m on
box–capsule). How the engine is held to the truth: ``tests/test_distance_truth.py`` compares it with an
exact oracle and with :mod:`planner.distance_closed_form` (verify's engine, which shares no code with this
one) on seeded adversarial pairs, aligned and touching poses included.

Degenerate normal
-----------------
When coal cannot give a direction (crossing capsule segments, where the depth is ``r_a + r_b`` and any
normal of the two segments' plane is a valid one-sided gradient), B is probed by a small translation
``h = 1e-5 m`` along the centre difference, then the world axes, and the normal is read at the probed pose;
the distance and witness points reported are still those of the true pose.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass

import coal
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.geometry import Box, Capsule, PlacedShape

# Below this witness-point separation (m) with no normal from coal, the normal is taken from a probe.
_DEGENERATE_TOL_M = 1e-9
# Probe translation (m) of B in the degenerate case: far above _DEGENERATE_TOL_M, small against shapes.
_PROBE_STEP_M = 1e-5
# GJK/EPA stop tolerance (m): well below the 1e-6 m the distances are held to.
_GJK_TOLERANCE_M = 1e-10


@dataclass(frozen=True)
class CollisionBody:
    """A rigid body of the collision model: shapes placed in the body frame (``T_body_shape``, m).

    ``frame`` names the pose the body moves with (default: its own name); e.g. the target's grasp handle is
    a body of its own, so that pairs can treat it apart, that moves with the target's frame.
    """

    name: str
    shapes: tuple[PlacedShape, ...]
    frame: str | None = None

    @property
    def frame_name(self) -> str:
        return self.frame or self.name


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
class _Placed:
    """One shape as coal sees it; its transform is rewritten on every sweep."""

    body: str
    name: str
    obj: coal.CollisionObject
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

    The coal objects are built once here; :meth:`distances` only sets transforms and calls ``coal.distance``.
    """

    distance_gradient = staticmethod(distance_gradient)

    def __init__(self, bodies: Sequence[CollisionBody], pairs: Sequence[tuple[str, str]],
                 scale: float | Mapping[str, float] = 1.0) -> None:
        """Build the scene.

        Args:
            bodies: rigid bodies; names unique, shape names unique within a body.
            pairs: ordered body pairs ``(A, B)``; each is queried by :meth:`distances`, in this order.
            scale: overscaling factor of shape *dimensions* (paper §5: the robot geometric model was
                scaled), one for all bodies or per body name (bodies not named keep 1.0). Box sides and
                capsule radius and length are multiplied; shape positions in their body are not.

        Raises:
            ValueError: unknown body or shape names, duplicate names or pairs, a pair of a body with
                itself, a non-positive scale, a body without shapes.
        """
        self._bodies = {b.name: b for b in bodies}
        self._body_names: tuple[str, ...] = tuple(b.name for b in bodies)
        if len(self._bodies) != len(self._body_names):
            raise ValueError(f"duplicate body names in {self._body_names}")
        if isinstance(scale, Mapping) and set(scale) - set(self._body_names):
            raise ValueError(f"scale given for unknown bodies {sorted(set(scale) - set(self._body_names))}")
        self._request = coal.DistanceRequest()
        self._request.enable_signed_distance = True
        self._request.gjk_tolerance = self._request.epa_tolerance = _GJK_TOLERANCE_M
        self._result = coal.DistanceResult()
        self._placed: dict[str, list[_Placed]] = {
            b.name: self._place_body(b, self._scale_of(scale, b.name)) for b in bodies}
        self._pairs = self._checked_pairs(pairs)
        self._pair_shapes = [[(sa, sb) for sa in self._placed[a] for sb in self._placed[b]] for a, b in self._pairs]
        in_pairs = {name for pair in self._pairs for name in pair}
        self._used_bodies: tuple[str, ...] = tuple(n for n in self._body_names if n in in_pairs)

    def _checked_pairs(self, pairs: Sequence[tuple[str, str]]) -> tuple[tuple[str, str], ...]:
        out = tuple((str(a), str(b)) for a, b in pairs)
        seen: set[frozenset[str]] = set()
        for a, b in out:
            for name in (a, b):
                if name not in self._bodies:
                    raise ValueError(f"pair ({a!r}, {b!r}): unknown body {name!r}")
            if a == b:
                raise ValueError(f"pair ({a!r}, {b!r}) pairs a body with itself")
            if frozenset((a, b)) in seen:
                raise ValueError(f"pair ({a!r}, {b!r}) is listed twice")
            seen.add(frozenset((a, b)))
        return out

    @staticmethod
    def _scale_of(scale: float | Mapping[str, float], body: str) -> float:
        s = float(scale.get(body, 1.0)) if isinstance(scale, Mapping) else float(scale)
        if not (math.isfinite(s) and s > 0.0):
            raise ValueError(f"scale of body {body!r} must be finite and > 0, got {s}")
        return s

    @staticmethod
    def _place_body(body: CollisionBody, scale: float) -> list[_Placed]:
        names = [s.name for s in body.shapes]
        if not names:
            raise ValueError(f"body {body.name!r} has no shapes")
        if len(set(names)) != len(names):
            raise ValueError(f"body {body.name!r}: duplicate shape names {names}")
        return [CollisionScene._place(body.name, placed, scale) for placed in body.shapes]

    @staticmethod
    def _place(body: str, placed: PlacedShape, scale: float) -> _Placed:
        shape = placed.shape.scaled(scale)
        if isinstance(shape, Box):
            geom = coal.Box(*shape.size_m)
        elif isinstance(shape, Capsule):
            geom = coal.Capsule(shape.radius_m, shape.length_m)  # centred, axis z: the convention of geometry
        else:
            raise ValueError(f"body {body!r} shape {placed.name!r}: unsupported shape type {type(shape).__name__}")
        T = np.array(placed.T_body_shape, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"body {body!r} shape {placed.name!r}: T_body_shape must be 4×4, got {T.shape}")
        return _Placed(body, placed.name, coal.CollisionObject(geom), T, bool(np.array_equal(T, np.eye(4))))

    @property
    def pairs(self) -> tuple[tuple[str, str], ...]:
        """The queried body pairs ``(A, B)``, in the order of :meth:`distances`' output."""
        return self._pairs

    @property
    def body_names(self) -> tuple[str, ...]:
        """Names of all bodies, in construction order."""
        return self._body_names

    def frame_of(self, body: str) -> str:
        """The pose a body moves with (see :class:`CollisionBody`)."""
        return self._bodies[body].frame_name

    def distances(self, T_world_frame: Mapping[str, ArrayLike]) -> list[PairDistance]:
        """Signed distance of every pair at the given poses (4×4, world frame, m), keyed by frame name.

        A body with several shapes contributes the minimum over its shape pairs. Only the frames of the
        bodies of some pair are needed; extra entries are ignored.

        Raises:
            KeyError: a body of some pair has no pose.
        """
        d, PA, PB, N, best = self._sweep(T_world_frame)
        return [PairDistance(pair, float(d[k]), PA[k], PB[k], N[k], (sa.name, sb.name))
                for k, (pair, (sa, sb)) in enumerate(zip(self._pairs, best, strict=True))]

    def distance_arrays(self, T_world_frame: Mapping[str, ArrayLike]) -> tuple[NDArray[np.float64], ...]:
        """:meth:`distances` as arrays, one row per pair: distances (m), witness points on A and on B, unit
        normals (world). For the NLPs' callbacks, which need no per-pair objects."""
        return self._sweep(T_world_frame)[:4]

    def _set_poses(self, T_world_frame: Mapping[str, ArrayLike]) -> None:
        for name in self._used_bodies:
            frame = self.frame_of(name)
            try:
                T_wb = np.asarray(T_world_frame[frame], dtype=float)
            except KeyError:
                raise KeyError(f"no pose given for collision body {name!r} (frame {frame!r})") from None
            for placed in self._placed[name]:
                T = T_wb if placed.at_body_origin else T_wb @ placed.T_body_shape
                placed.obj.setRotation(T[:3, :3])  # two setters: ~3× cheaper than a Transform3s
                placed.obj.setTranslation(T[:3, 3])

    def _sweep(self, T_world_frame: Mapping[str, ArrayLike]) -> tuple:
        """``(d, PA, PB, N, best)``: what :meth:`distances` reports, and the shape pair realising each."""
        self._set_poses(T_world_frame)
        res, req, coal_distance = self._result, self._request, coal.distance
        m = len(self._pairs)
        d, PA, PB, N = np.empty(m), np.empty((m, 3)), np.empty((m, 3)), np.empty((m, 3))
        best: list[tuple[_Placed, _Placed]] = []
        for k, combos in enumerate(self._pair_shapes):
            d[k] = math.inf
            pair_best = combos[0]
            for sa, sb in combos:
                res.clear()
                dist = coal_distance(sa.obj, sb.obj, req, res)
                if dist < d[k]:
                    d[k] = dist
                    PA[k], PB[k], N[k] = res.getNearestPoint1(), res.getNearestPoint2(), res.normal
                    pair_best = (sa, sb)
            best.append(pair_best)
            if not _consistent(d[k], PA[k], PB[k], N[k]) or (d[k] < 0.0 and not self._pushes_apart(*pair_best,
                                                                                                      d[k], N[k])):
                N[k], PA[k] = self._probe(*pair_best)
                PB[k] = PA[k] + d[k] * N[k]
        return d, PA, PB, N, best

    def _pushes_apart(self, sa: _Placed, sb: _Placed, d: float, n: NDArray[np.float64]) -> bool:
        """Whether moving B by ``h n`` increases the distance by ``h`` (coal's normal of crossing capsule cores
        is unit and consistent with its points but not a direction of the depth)."""
        p_b = np.array(sb.obj.getTransform().getTranslation())
        sb.obj.setTranslation(p_b + _PROBE_STEP_M * n)
        self._result.clear()
        moved = coal.distance(sa.obj, sb.obj, self._request, self._result)
        sb.obj.setTranslation(p_b)
        return abs(moved - d - _PROBE_STEP_M) < 0.1 * _PROBE_STEP_M

    def _probe(self, sa: _Placed, sb: _Placed) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Unit normal (world) and A's witness point of a pair coal gave no direction for (module docstring)."""
        res, req = self._result, self._request
        p_b = np.array(sb.obj.getTransform().getTranslation())
        candidates = [p_b - np.array(sa.obj.getTransform().getTranslation()), *np.eye(3)]
        try:
            for u in candidates:
                norm_u = float(np.linalg.norm(u))
                if norm_u < _DEGENERATE_TOL_M:
                    continue
                sb.obj.setTranslation(p_b + (_PROBE_STEP_M / norm_u) * u)
                res.clear()
                dist = coal.distance(sa.obj, sb.obj, req, res)
                pa, pb, n = res.getNearestPoint1(), res.getNearestPoint2(), np.array(res.normal)
                if _consistent(dist, pa, pb, n) and self._pushes_apart(sa, sb, dist, n):
                    return n, pa
        finally:
            sb.obj.setTranslation(p_b)
        raise RuntimeError(f"no contact normal found for shapes {sa.name!r}, {sb.name!r}")  # a world axis always works


def _consistent(d: float, pa: NDArray[np.float64], pb: NDArray[np.float64], n: NDArray[np.float64]) -> bool:
    """Whether coal's output is usable as is: a unit normal with ``p_b − p_a = d n``."""
    return abs(float(n @ n) - 1.0) < 1e-9 and float(np.linalg.norm(pb - pa - d * n)) < 1e-7


def default_pairs(chaser_bodies: Sequence[str], adjacent: Collection[tuple[str, str]],
                  target_bodies: Sequence[str]) -> list[tuple[str, str]]:
    """Collision pairs: all non-adjacent chaser body pairs, then every chaser body against every target body.

    Adjacency is unordered. Chaser pairs are ``(chaser_bodies[i], chaser_bodies[j])`` with ``i < j``; target
    pairs are ``(chaser, target)``, the target bodies in the given order, chaser-major.
    With 8 chained chaser bodies (7 adjacent pairs) and 2 target bodies (the target and its handle):
    28 - 7 + 16 = 37 pairs.

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
    pairs = [(chaser[i], chaser[j]) for i in range(len(chaser)) for j in range(i + 1, len(chaser))
             if frozenset((chaser[i], chaser[j])) not in adj]
    return pairs + [(c, t) for c in chaser for t in target]
