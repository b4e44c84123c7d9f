"""Signed distances between rigid bodies made of boxes and capsules (paper §4.4, Eq. 19).

A :class:`CollisionScene` holds bodies (each a tuple of :class:`~planner.model.shapes.PlacedShape`) and a list
of body pairs. :meth:`CollisionScene.distances` returns, per pair, the signed distance (m; > 0 separated,
< 0 minus the penetration depth), one witness point on each body (world frame, m) and a unit normal
``n`` (world frame) with ``p_world_b - p_world_a = distance_m * n`` in every case, so that translating
body B by ``+ε n`` (or body A by ``-ε n``) increases the distance by ``ε`` to first order.
:func:`distance_gradient` turns that into ``∂d/∂x`` for any coordinates ``x`` (TrajOpt style).

Engine
------
Distances come from :mod:`planner.collision.closed_form`: exact signed distances of boxes and capsules in
closed form, vectorised over many poses, so one call sweeps every pair at every via point of an NLP; the
general-purpose engines (python-fcl, coal) are not exact in every pose the NLPs meet (aligned and
near-parallel shapes, touching faces). ``verify`` checks every plan with
an engine of its own (:mod:`planner.verify.distance`), so an error in this one is caught by the other.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.collision.closed_form import ShapeRows, signed_distances
from planner.collision.layout import CollisionBody
from planner.model.shapes import Box, Capsule, PlacedShape

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PairDistance:
    """Signed distance between two bodies and where it is realised (all vectors in the world frame).

    ``p_world_b - p_world_a == distance_m * normal_world`` (up to rounding), separated or not.
    """

    pair: tuple[str, str]  # (body A, body B)
    distance_m: float  # signed: > 0 separated, < 0 minus the penetration depth [m]
    p_world_a: Array  # witness point on A's surface (world, m)
    p_world_b: Array  # witness point on B's surface (world, m)
    normal_world: Array  # unit; moving B by +ε n (or A by -ε n) increases distance_m by ε
    shape_pair: tuple[str, str]  # names of the shape of A and the shape of B that realise the minimum


@dataclass(frozen=True)
class PairSweep:
    """Every pair at n poses: ``distance_m`` (n, m), witnesses ``p_world_a``, ``p_world_b`` and unit
    ``normal_world`` (n, m, 3), and ``combo`` (n, m), the index of the shape pair realising each minimum."""

    distance_m: Array
    p_world_a: Array
    p_world_b: Array
    normal_world: Array
    combo: NDArray[np.int64]


@dataclass(frozen=True)
class _ShapePair:
    """One shape of body A against one shape of body B, scaled, with the frames they move with."""

    frame_a: str
    placed_a: PlacedShape
    frame_b: str
    placed_b: PlacedShape


def distance_gradient(pd: PairDistance, J_point_a: ArrayLike, J_point_b: ArrayLike) -> Array:
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
    """Bodies of boxes and capsules and the body pairs whose signed distance is queried."""

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
        placed = {b.name: _scaled_shapes(b, self._scale_of(scale, b.name)) for b in bodies}
        self._pairs = self._checked_pairs(pairs)
        self._shape_pairs = [[_ShapePair(self.frame_of(a), sa, self.frame_of(b), sb)
                              for sa in placed[a] for sb in placed[b]] for a, b in self._pairs]
        # (pair index, shape-pair index, shape pair) grouped by the kinds of the two shapes, in pair order
        kinds: dict[tuple[bool, bool], list[tuple[int, int, _ShapePair]]] = {}
        for k, shape_pairs in enumerate(self._shape_pairs):
            for c, sp in enumerate(shape_pairs):
                key = (isinstance(sp.placed_a.shape, Box), isinstance(sp.placed_b.shape, Box))
                kinds.setdefault(key, []).append((k, c, sp))
        self._by_kind = list(kinds.values())
        self._rows: dict[int, list[tuple[ShapeRows, ShapeRows]]] = {}

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
        sweep = self.sweep({f: np.asarray(T, dtype=float)[None] for f, T in T_world_frame.items()})
        out = []
        for k, pair in enumerate(self._pairs):
            sp = self._shape_pairs[k][sweep.combo[0, k]]
            out.append(PairDistance(pair, float(sweep.distance_m[0, k]), sweep.p_world_a[0, k],
                                    sweep.p_world_b[0, k], sweep.normal_world[0, k],
                                    (sp.placed_a.name, sp.placed_b.name)))
        return out

    def distance_arrays(self, T_world_frame: Mapping[str, ArrayLike]) -> tuple[Array, ...]:
        """:meth:`distances` as arrays, one row per pair: distances [m], witness points on A and on B, unit
        normals (world)."""
        sweep = self.sweep({f: np.asarray(T, dtype=float)[None] for f, T in T_world_frame.items()})
        return sweep.distance_m[0], sweep.p_world_a[0], sweep.p_world_b[0], sweep.normal_world[0]

    def sweep(self, T_world_frame: Mapping[str, Array]) -> PairSweep:
        """Every pair at n pose sets at once: ``T_world_frame`` maps frame names to (n, 4, 4) stacks.

        The shape pairs of one kind (capsule–capsule, box–capsule, …) go through the engine in one call: its
        cost is mostly per call, not per row.
        """
        n = len(next(iter(T_world_frame.values())))
        m = len(self._pairs)
        d = np.full((n, m), np.inf)
        pa, pb, nn = np.zeros((n, m, 3)), np.zeros((n, m, 3)), np.zeros((n, m, 3))
        combo = np.zeros((n, m), dtype=np.int64)
        for members, (shapes_a, shapes_b) in zip(self._by_kind, self._rows_for(n), strict=True):
            Ta = np.concatenate([_pose(T_world_frame, sp.frame_a, sp.placed_a) for _, _, sp in members])
            Tb = np.concatenate([_pose(T_world_frame, sp.frame_b, sp.placed_b) for _, _, sp in members])
            r = signed_distances(shapes_a, Ta, shapes_b, Tb)
            for g, (k, c, _) in enumerate(members):
                rows = slice(g * n, (g + 1) * n)
                better = r.distance_m[rows] < d[:, k]
                d[better, k] = r.distance_m[rows][better]
                pa[better, k], pb[better, k] = r.p_world_a[rows][better], r.p_world_b[rows][better]
                nn[better, k] = r.normal_world[rows][better]
                combo[better, k] = c
        return PairSweep(d, pa, pb, nn, combo)

    def _rows_for(self, n: int) -> list[tuple[ShapeRows, ShapeRows]]:
        """Per kind group, its shapes repeated for n poses (kept: the NLPs sweep the same n every call)."""
        if n not in self._rows:
            self._rows[n] = [(ShapeRows.of([sp.placed_a.shape for _, _, sp in members for _ in range(n)]),
                              ShapeRows.of([sp.placed_b.shape for _, _, sp in members for _ in range(n)]))
                             for members in self._by_kind]
        return self._rows[n]


def _scaled_shapes(body: CollisionBody, scale: float) -> list[PlacedShape]:
    names = [s.name for s in body.shapes]
    if not names:
        raise ValueError(f"body {body.name!r} has no shapes")
    if len(set(names)) != len(names):
        raise ValueError(f"body {body.name!r}: duplicate shape names {names}")
    out = []
    for placed in body.shapes:
        if not isinstance(placed.shape, Box | Capsule):
            raise ValueError(f"body {body.name!r} shape {placed.name!r}: unsupported shape type "
                             f"{type(placed.shape).__name__}")
        T = np.array(placed.T_body_shape, dtype=float)
        if T.shape != (4, 4):
            raise ValueError(f"body {body.name!r} shape {placed.name!r}: T_body_shape must be 4×4, got {T.shape}")
        out.append(PlacedShape(placed.name, placed.shape.scaled(scale), T))
    return out


def _pose(T_world_frame: Mapping[str, Array], frame: str, placed: PlacedShape) -> Array:
    try:
        T = T_world_frame[frame]
    except KeyError:
        raise KeyError(f"no pose given for collision frame {frame!r}") from None
    return T if np.array_equal(placed.T_body_shape, np.eye(4)) else T @ placed.T_body_shape
