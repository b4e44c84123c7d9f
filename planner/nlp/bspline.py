"""Uniform cubic B-spline joint trajectories (paper §4.6, Eq. 22): basis, evaluation, boundary maps.

A trajectory of one phase is given by ``N`` vertices (control points) ``B_1..B_N`` per joint, stored as an
``(N, n_joints)`` array [rad].  It has ``n_seg = N - 3`` segments of equal duration
``t_seg = t_f / (N - 3)`` [s].  On segment ``i`` (0-based here, ``i = 0..n_seg-1``; the paper's segment
``i + 1``) with local time ``u = t / t_seg - i`` in ``[0, 1]``::

    (s, ṡ, s̈, s⃛)ᵀ(u) = (1/6) C(u) A (B_{i}, B_{i+1}, B_{i+2}, B_{i+3})ᵀ            (Eq. 22)

where rows of ``C(u)`` are the monomials ``[1, u, u², u³]`` and their ``d``-th derivatives divided by
``t_seg**d`` (so derivatives are w.r.t. time in seconds: rad/s, rad/s², rad/s³).

Because ``C(0) A`` and ``C(1) A`` are invertible, the four boundary values (position, velocity,
acceleration, jerk) at ``t = 0`` fix ``B_1..B_4`` and those at ``t = t_f`` fix ``B_{N-3}..B_N``; the phases'
parameter layouts built on that are in :mod:`planner.nlp.phase_spline`.

Every function here accepts numpy arrays or casadi ``SX``/``MX``/``DM`` (the NLP keeps the evaluation times
fixed numbers and the vertices symbolic, so all maps here are constant matrices).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

# Uniform cubic B-spline basis matrix A of Eq. 22 (with the 1/6 kept separate, as in the paper):
# s(u) = (1/6) [1 u u² u³] A [B_i B_{i+1} B_{i+2} B_{i+3}]ᵀ.
BASIS_MATRIX: NDArray[np.float64] = np.array(
    [
        [1.0, 4.0, 1.0, 0.0],
        [-3.0, 0.0, 3.0, 0.0],
        [3.0, -6.0, 3.0, 0.0],
        [-1.0, 3.0, -3.0, 1.0],
    ]
)

MIN_VERTICES = 8  # 4 vertices fixed by each end's (pos, vel, acc, jerk); fewer would over-determine them.
MAX_DERIVATIVE = 3  # jerk; the 4th derivative is a sum of Dirac impulses at the knots.

# Times may come from float arithmetic such as ``k * t_f / n``; allow this much (relative) overshoot.
_TIME_TOLERANCE = 1e-9
# A time within this many segment durations of a knot is evaluated at the knot (on its right segment), so
# that ``k * t_seg`` rounded either way picks the same segment; matters for the jerk, which jumps at knots.
_KNOT_SNAP = 1e-12

Matrix = Any  # numpy array or casadi SX/MX/DM


def is_casadi(x: object) -> bool:
    """True for a casadi SX, MX or DM."""
    return isinstance(x, (ca.SX, ca.MX, ca.DM))


def _monomial_rows(u: NDArray[np.float64], derivative: int) -> NDArray[np.float64]:
    """``d``-th derivative w.r.t. ``u`` of ``[1, u, u², u³]`` at each ``u``: shape ``(len(u), 4)``."""
    rows = np.zeros((u.size, 4))
    for k in range(derivative, 4):
        # d^d/du^d u^k = k!/(k-d)! u^(k-d)
        factor = float(np.prod(np.arange(k - derivative + 1, k + 1)))
        rows[:, k] = factor * u ** (k - derivative)
    return rows


@dataclass(frozen=True)
class UniformCubicBSpline:
    """Uniform cubic B-spline with ``n_vertices`` vertices over ``[0, duration_s]`` (Eq. 22).

    Attributes:
        n_vertices: number of vertices ``N`` (≥ 8; see module docstring).
        duration_s: phase duration ``t_f`` [s], > 0.
    """

    n_vertices: int
    duration_s: float

    def __post_init__(self) -> None:
        if isinstance(self.n_vertices, bool) or int(self.n_vertices) != self.n_vertices:
            raise ValueError(f"n_vertices: must be an integer, got {self.n_vertices!r}")
        if self.n_vertices < MIN_VERTICES:
            raise ValueError(
                f"n_vertices: must be >= {MIN_VERTICES} (4 vertices fixed by each end's position, "
                f"velocity, acceleration and jerk), got {self.n_vertices}"
            )
        if not (np.isfinite(self.duration_s) and self.duration_s > 0.0):
            raise ValueError(f"duration_s: must be finite and > 0, got {self.duration_s!r}")

    # ------------------------------------------------------------------ sizes
    @property
    def n_segments(self) -> int:
        """Number of polynomial segments ``N - 3``."""
        return self.n_vertices - 3

    @property
    def segment_duration_s(self) -> float:
        """Segment (knot-interval) duration ``t_seg = t_f / (N - 3)`` [s]."""
        return self.duration_s / self.n_segments

    @property
    def n_free_per_joint(self) -> int:
        """Free params per joint, Eq. 23 / 24: ``p_j0``, ``N - 8`` interior vertices, ``p_θtf``, ``p_jtf``."""
        return self.n_vertices - 5

    @property
    def n_interior(self) -> int:
        """Number of interior vertices ``B_5..B_{N-4}``: ``N - 8``."""
        return self.n_vertices - 8

    # ------------------------------------------------------------------ basis
    def segment_weights(self, segment: int, u: ArrayLike, derivative: int = 0) -> NDArray[np.float64]:
        """Weights ``(len(u), N)`` of the ``derivative``-th time derivative on one segment (Eq. 22).

        Args:
            segment: 0-based segment index, ``0 <= segment < N - 3`` (the paper's ``i - 1``).
            u: local times in ``[0, 1]`` (dimensionless; ``u = 1`` is the segment's right end).
            derivative: 0 position [rad], 1 velocity [rad/s], 2 acceleration [rad/s²], 3 jerk [rad/s³].
        """
        if not 0 <= segment < self.n_segments:
            raise ValueError(f"segment: must be in [0, {self.n_segments}), got {segment}")
        u_arr = np.atleast_1d(np.asarray(u, dtype=float))
        segments = np.full(u_arr.shape, segment, dtype=int)
        return self._weights(segments, u_arr, derivative)

    def weights(self, times_s: ArrayLike, derivative: int = 0) -> NDArray[np.float64]:
        """Weight matrix ``W`` (``(n_times, N)``) with ``s^(d)(t) = W @ B`` (Eq. 22).

        Args:
            times_s: times in ``[0, t_f]`` [s]; ``t == t_f`` is evaluated on the last segment at ``u = 1``.
                Knots ``t = k t_seg`` (0 < k < N - 3) are evaluated on the right segment at ``u = 0``.
            derivative: 0..3, see :meth:`segment_weights`; units rad/s^d per rad of vertex.
        """
        t = np.atleast_1d(np.asarray(times_s, dtype=float)).ravel()
        slack = _TIME_TOLERANCE * self.duration_s
        if t.size and (not np.all(np.isfinite(t)) or t.min() < -slack or t.max() > self.duration_s + slack):
            raise ValueError(
                f"times_s: must lie in [0, {self.duration_s}] s, got range [{t.min()}, {t.max()}]"
            )
        t = np.clip(t, 0.0, self.duration_s)
        x = t / self.segment_duration_s
        nearest = np.rint(x)
        x = np.where(np.abs(x - nearest) <= _KNOT_SNAP * np.maximum(1.0, nearest), nearest, x)
        segments = np.minimum(np.floor(x).astype(int), self.n_segments - 1)
        return self._weights(segments, x - segments, derivative)

    def _weights(
        self, segments: NDArray[np.int_], u: NDArray[np.float64], derivative: int
    ) -> NDArray[np.float64]:
        if derivative not in range(MAX_DERIVATIVE + 1):
            raise ValueError(f"derivative: must be in 0..{MAX_DERIVATIVE}, got {derivative}")
        # (1/6) C(u) A for this derivative, with the chain-rule factor 1/t_seg^d (Eq. 22).
        local = _monomial_rows(u, derivative) @ BASIS_MATRIX / (6.0 * self.segment_duration_s**derivative)
        W = np.zeros((u.size, self.n_vertices))
        rows = np.arange(u.size)
        for c in range(4):
            W[rows, segments + c] = local[:, c]
        return W

    def evaluate(self, vertices: Matrix, times_s: ArrayLike, derivative: int = 0) -> Matrix:
        """``derivative``-th time derivative at ``times_s``: ``(n_times, n_joints)``, ``W @ vertices``.

        ``vertices`` is ``(N, n_joints)`` numpy (returns numpy) or casadi SX/MX/DM (returns the same casadi
        type, so an NLP stays symbolic in the vertices while the times are fixed numbers).
        """
        W = self.weights(times_s, derivative)
        if is_casadi(vertices):
            return ca.mtimes(ca.DM(W), vertices)
        return W @ np.asarray(vertices, dtype=float)

    # ------------------------------------------------------------------ boundary maps
    @cached_property
    def start_map(self) -> NDArray[np.float64]:
        """4×4 map ``(B_1..B_4) -> (pos, vel, acc, jerk)`` at ``t = 0``: ``(1/6) C(0) A``."""
        return self._boundary_map(0.0)

    @cached_property
    def end_map(self) -> NDArray[np.float64]:
        """4×4 map ``(B_{N-3}..B_N) -> (pos, vel, acc, jerk)`` at ``t = t_f``: ``(1/6) C(1) A``."""
        return self._boundary_map(1.0)

    @cached_property
    def start_map_inverse(self) -> NDArray[np.float64]:
        """4×4 map ``(pos, vel, acc, jerk)`` at ``t = 0`` -> ``(B_1..B_4)``."""
        return self._boundary_map_inverse(0.0)

    @cached_property
    def end_map_inverse(self) -> NDArray[np.float64]:
        """4×4 map ``(pos, vel, acc, jerk)`` at ``t = t_f`` -> ``(B_{N-3}..B_N)``."""
        return self._boundary_map_inverse(1.0)

    def _boundary_map(self, u: float) -> NDArray[np.float64]:
        u_arr = np.array([u])
        scale = self.segment_duration_s ** np.arange(4)
        return np.vstack([_monomial_rows(u_arr, d) for d in range(4)]) @ BASIS_MATRIX / 6.0 / scale[:, None]

    def _boundary_map_inverse(self, u: float) -> NDArray[np.float64]:
        # Invert the t_seg-free map (small integers/fractions, well conditioned) and put the t_seg^d
        # scaling back on the columns exactly, rather than inverting a matrix with entries up to 1/t_seg³.
        u_arr = np.array([u])
        unit = np.vstack([_monomial_rows(u_arr, d) for d in range(4)]) @ BASIS_MATRIX / 6.0
        return np.linalg.inv(unit) * (self.segment_duration_s ** np.arange(4))[None, :]

    def vertices_from_boundary(self, start: Matrix, end: Matrix, interior: Matrix) -> Matrix:
        """Vertices ``(N, n)`` from boundary values and interior vertices (inverse of Eq. 22 at both ends).

        Args:
            start: ``(4, n)`` rows position [rad], velocity [rad/s], acceleration [rad/s²], jerk [rad/s³]
                at ``t = 0``.
            end: ``(4, n)``, same rows at ``t = t_f``.
            interior: ``(N - 8, n)`` vertices ``B_5..B_{N-4}`` [rad].
        Returns numpy if all inputs are numpy, else casadi (``DM`` inputs mixed with ``SX``/``MX`` are fine).
        """
        if any(is_casadi(x) for x in (start, end, interior)):
            first = ca.mtimes(ca.DM(self.start_map_inverse), as_casadi(start))
            last = ca.mtimes(ca.DM(self.end_map_inverse), as_casadi(end))
            middle = as_casadi(interior)
            if middle.shape[0] != self.n_interior:
                raise ValueError(f"interior: expected {self.n_interior} rows, got {middle.shape[0]}")
            if middle.shape[0] == 0:
                return ca.vertcat(first, last)
            return ca.vertcat(first, middle, last)
        start_a = np.asarray(start, dtype=float)
        end_a = np.asarray(end, dtype=float)
        n = start_a.shape[1]
        interior_a = np.asarray(interior, dtype=float).reshape(self.n_interior, n)
        return np.vstack([self.start_map_inverse @ start_a, interior_a, self.end_map_inverse @ end_a])

    def boundary_from_vertices(
        self, vertices: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Exact inverse of :meth:`vertices_from_boundary` (numpy): ``(start (4,n), end (4,n), interior)``."""
        V = _as_vertices(self, vertices)
        return self.start_map @ V[:4], self.end_map @ V[-4:], V[4 : self.n_vertices - 4].copy()


def as_casadi(x: Matrix) -> Matrix:
    """``x`` as casadi (numpy becomes a DM)."""
    return x if is_casadi(x) else ca.DM(np.asarray(x, dtype=float))


def _as_vertices(spline: UniformCubicBSpline, vertices: ArrayLike) -> NDArray[np.float64]:
    V = np.asarray(vertices, dtype=float)
    if V.ndim == 1:
        V = V[:, None]
    if V.ndim != 2 or V.shape[0] != spline.n_vertices:
        raise ValueError(f"vertices: expected shape ({spline.n_vertices}, n_joints), got {V.shape}")
    return V


def resample(
    spline_from: UniformCubicBSpline,
    vertices: ArrayLike,
    spline_to: UniformCubicBSpline,
    samples_per_segment: int = 8,
) -> NDArray[np.float64]:
    """Vertices of ``spline_to`` approximating a trajectory of ``spline_from`` (warm starts across N).

    Boundary values (position .. jerk) at both ends are kept exactly; if the durations differ the trajectory
    is time-scaled (normalised time ``t / t_f`` kept, derivatives scaled by ``(t_f,from / t_f,to)^d``).  The
    interior vertices are a least-squares fit to positions at ``samples_per_segment`` points per segment of
    the finer of the two splines.
    """
    V = _as_vertices(spline_from, vertices)
    start, end, _ = spline_from.boundary_from_vertices(V)
    scale = (spline_from.duration_s / spline_to.duration_s) ** np.arange(4)[:, None]
    start, end = start * scale, end * scale
    empty = np.zeros((0, V.shape[1]))
    if spline_to.n_interior == 0:
        return spline_to.vertices_from_boundary(start, end, empty)
    n_samples = samples_per_segment * max(spline_from.n_segments, spline_to.n_segments) + 1
    tau = np.linspace(0.0, 1.0, n_samples)
    target = spline_from.evaluate(V, tau * spline_from.duration_s)
    W = spline_to.weights(tau * spline_to.duration_s)
    # Positions are affine in the interior vertices once both ends are fixed.
    fixed = W @ spline_to.vertices_from_boundary(start, end, np.zeros((spline_to.n_interior, V.shape[1])))
    inner = W[:, 4 : spline_to.n_vertices - 4]
    interior, *_ = np.linalg.lstsq(inner, target - fixed, rcond=None)
    return spline_to.vertices_from_boundary(start, end, interior)
