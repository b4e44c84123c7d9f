"""Numerical building blocks of :mod:`planner.verify.verifier`: sample selection, finite differences, pinocchio.

Everything here is independent of the planner's CasADi model: poses and momenta come from pinocchio
(``framesForwardKinematics``, ``computeCentroidalMap``), rates from finite differences (FD) of the
plan's stored samples.

Finite differences
------------------
A plan stores samples at a fixed step h (0.01 s). Rates at sample k use the :data:`STENCIL_POINTS` = 5
stored samples nearest to k *inside one smooth segment* (one phase; the join sample is shared by the
phases it joins): centred inside, one-sided at a segment end. Weights come from Fornberg's algorithm
(any spacing). The error is O(h⁴) where the motion is smooth, and O(h²)·(jump of the third
derivative) at the few instants where the joint jerk jumps (B-spline knots, ends of the tracking
profiles), still an order of magnitude below a 3-point stencil's error there. Rotations are differentiated through the
rotation vectors ``φ_j = log(R_j R_kᵀ)`` (world frame) of the stencil relative to ``R_k``: with
``R(t) = exp([φ(t)]×) R_k``, ``φ'(t_k) = ω_world`` and ``φ''(t_k) = α_world`` exactly (the
Baker–Campbell–Hausdorff correction ``½ φ × φ'`` and its derivative vanish at φ = 0).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from planner.model.quaternion_rows import matrices_to_quats, quats_to_matrices
from planner.model.robot import RobotModel, pin_configuration
from planner.model.rotation import quat_to_matrix, rotation_log

Array = NDArray[np.float64]

TIME_TOL_S = 1e-6  # two sample times closer than this are the same instant (phase joins)
PHASE_NAMES = ("approach", "tracking", "stabilization")
STENCIL_POINTS = 5  # samples per finite-difference stencil


class PoseSamples(NamedTuple):
    """World poses at the verified samples: positions (n×3, m) and ``[w, x, y, z]`` quaternions (n×4)."""

    position_m: Array
    wxyz: Array


def pose_samples(T_world: Array) -> PoseSamples:
    """(n, 4, 4) homogeneous transforms → :class:`PoseSamples`."""
    return PoseSamples(T_world[:, :3, 3].copy(), matrices_to_quats(T_world[:, :3, :3]))


# ----------------------------------------------------------------------------------------------------
# Samples and segments


def select_samples(t_s: Array, boundaries_s: list[float], step_s: float) -> Array:
    """Indices of the stored samples to verify: gaps ≤ ``step_s`` (where the stored grid allows), and
    always the first and last sample and every sample at a phase boundary (``boundaries_s``)."""
    n = len(t_s)
    must = {0, n - 1}
    for b in boundaries_s:
        must.update(np.flatnonzero(np.abs(t_s - b) <= TIME_TOL_S).tolist())
    must_sorted = np.array(sorted(must))
    chosen = [0]
    i = 0
    while i < n - 1:
        next_must = int(must_sorted[np.searchsorted(must_sorted, i, side="right")])
        j = int(np.searchsorted(t_s, t_s[i] + step_s + 1e-9, side="right")) - 1
        i = max(min(j, next_must), i + 1)
        chosen.append(i)
    return np.array(chosen, dtype=int)


def phase_segments(t_s: Array, phase_index: Array, phases: dict[str, tuple[float, float]]) -> list[tuple[int, int]]:
    """Inclusive index range ``(lo, hi)`` of each phase's smooth segment, in :data:`PHASE_NAMES` order.

    A phase owns the samples labelled with its index; when its start instant is stored only once, as the
    previous phase's last sample (the planner's layout), that sample is shared and prepended.
    """
    segments = []
    for p, name in enumerate(PHASE_NAMES):
        idx = np.flatnonzero(phase_index == p)
        if idx.size == 0:
            raise ValueError(f"plan has no samples of the {name} phase")
        lo, hi = int(idx[0]), int(idx[-1])
        if hi - lo + 1 != idx.size:
            raise ValueError(f"the {name} samples are not contiguous")
        t0 = phases[name][0]
        if lo > 0 and t_s[lo] > t0 + TIME_TOL_S and abs(t_s[lo - 1] - t0) <= TIME_TOL_S:
            lo -= 1
        segments.append((lo, hi))
    return segments


# ----------------------------------------------------------------------------------------------------
# Finite differences


def fd_weights(nodes: ArrayLike, x0: ArrayLike, order: int) -> Array:
    """Weights ``w`` with ``f^(order)(x0) ≈ Σ w_j f(nodes_j)`` (Fornberg 1988, any spacing).

    ``nodes`` (..., n) and ``x0`` (scalar or (...)) may carry leading dimensions: one stencil per row,
    all rows at once (the verifier differentiates thousands of samples).
    """
    nodes = np.asarray(nodes, dtype=float)
    x = nodes - np.asarray(x0, dtype=float)[..., None]
    n = nodes.shape[-1]
    c = np.zeros((*nodes.shape[:-1], n, order + 1))
    c[..., 0, 0] = 1.0
    c1, c4 = 1.0, x[..., 0]
    for i in range(1, n):
        mn = min(i, order)
        c2, c5, c4 = 1.0, c4, x[..., i]
        for j in range(i):
            c3 = nodes[..., i] - nodes[..., j]
            c2 = c2 * c3
            if j == i - 1:
                for k in range(mn, 0, -1):
                    c[..., i, k] = c1 * (k * c[..., i - 1, k - 1] - c5 * c[..., i - 1, k]) / c2
                c[..., i, 0] = -c1 * c5 * c[..., i - 1, 0] / c2
            for k in range(mn, 0, -1):
                c[..., j, k] = (c4 * c[..., j, k] - k * c[..., j, k - 1]) / c3
            c[..., j, 0] = c4 * c[..., j, 0] / c3
        c1 = c2
    return c[..., order]


def stencils(k: ArrayLike, segment: tuple[int, int], order: int) -> Array:
    """Indices (m, P) of the :data:`STENCIL_POINTS` samples of ``segment`` nearest to each sample in k
    (centred inside, one-sided at an end): fourth order where the motion is smooth (module docstring)."""
    k = np.atleast_1d(np.asarray(k, dtype=int))
    lo, hi = segment
    if np.any((k < lo) | (k > hi)):
        raise ValueError(f"samples {k[(k < lo) | (k > hi)][:3].tolist()} outside their segment [{lo}, {hi}]")
    points = min(STENCIL_POINTS, hi - lo + 1)
    if points < order + 1:
        raise ValueError(f"segment [{lo}, {hi}] too short for a derivative of order {order}")
    start = np.clip(k - points // 2, lo, hi - points + 1)
    return start[:, None] + np.arange(points)


def derivatives(t_s: Array, values: Array, k: ArrayLike, segment: tuple[int, int], order: int) -> Array:
    """``order``-th time derivative (1 or 2) of ``values`` (n×d) at the samples k (m,) by FD inside
    ``segment``: (m, d)."""
    k = np.atleast_1d(np.asarray(k, dtype=int))
    idx = stencils(k, segment, order)
    w = fd_weights(t_s[idx], t_s[k], order)
    return np.einsum("mp,mpd->md", w, values[idx])


def rotation_rates(t_s: Array, R: Array, k: ArrayLike, segment: tuple[int, int]) -> tuple[Array, Array]:
    """World angular velocities [rad/s] and accelerations [rad/s²], (m, 3) each, of the rotations ``R``
    (n×3×3) at the samples k, by FD of the stencil's rotation vectors ``log(R_j R_kᵀ)``."""
    k = np.atleast_1d(np.asarray(k, dtype=int))
    idx = stencils(k, segment, 2)
    phi = rotation_log(np.einsum("mpij,mkj->mpik", R[idx], R[k]))
    offsets = t_s[idx] - t_s[k][:, None]
    return (np.einsum("mp,mpd->md", fd_weights(offsets, 0.0, 1), phi),
            np.einsum("mp,mpd->md", fd_weights(offsets, 0.0, 2), phi))


def base_twist_world(t_s: Array, x_base: Array, k: ArrayLike, segment: tuple[int, int]) -> tuple[Array, Array]:
    """Velocities of the base origin and base angular velocities (world, m/s and rad/s), (m, 3) each,
    at the samples k by FD."""
    k = np.atleast_1d(np.asarray(k, dtype=int))
    v = derivatives(t_s, x_base[:, :3], k, segment, 1)
    idx = stencils(k, segment, 1)
    R = quat_to_matrix(x_base[:, 3:])
    phi = rotation_log(np.einsum("mpij,mkj->mpik", R[idx], R[k]))
    return v, np.einsum("mp,mpd->md", fd_weights(t_s[idx] - t_s[k][:, None], 0.0, 1), phi)


def extrapolate(t_s: Array, values: Array, idx: Array, t0: float) -> Array:
    """Polynomial through ``values[idx]`` evaluated at ``t0`` (joint rates at a phase join)."""
    return fd_weights(t_s[idx] - t0, 0.0, 0) @ values[idx]


# ----------------------------------------------------------------------------------------------------
# Pinocchio


class PinKinematics:
    """Pinocchio forward kinematics and centroidal momentum of one free-floating robot model."""

    def __init__(self, robot: RobotModel) -> None:
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.body_names = robot.body_names
        self.body_ids = [self.model.getFrameId(name, pin.BODY) for name in robot.body_names]
        self.ee_id = self.model.getFrameId(robot.ee_frame)

    def _q(self, x_base: Array, q: Array) -> Array:
        return pin_configuration(x_base[:3], x_base[3:], q)

    def forward(self, x_base: Array, q: Array) -> None:
        """Place every frame for base pose ``x_base = [p, quat wxyz]`` and joint angles ``q``."""
        pin.framesForwardKinematics(self.model, self.data, self._q(x_base, q))

    def ee_pose(self) -> Array:
        """World pose (4×4) of the end-effector frame after :meth:`forward`."""
        return np.array(self.data.oMf[self.ee_id].homogeneous)

    def body_poses(self) -> dict[str, Array]:
        """World poses (4×4) of the bodies (base, links) after :meth:`forward`."""
        return {name: np.array(self.data.oMf[fid].homogeneous) for name, fid in zip(self.body_names, self.body_ids,
                                                                                    strict=True)}

    def sampled_poses(self, x_base: Array, q: Array, bodies_at: Array) -> tuple[Array, dict[str, Array]]:
        """Gripper poses (n, 4, 4) at every row of ``x_base`` (n, 7) and ``q`` (n, n_joints), and each body's poses
        (len(bodies_at), 4, 4) at the rows ``bodies_at`` (ascending), world frame."""
        configs = pin_configurations(x_base, q)
        T_ee = np.empty((len(configs), 4, 4))
        T_bodies = np.empty((len(self.body_ids), len(bodies_at), 4, 4))
        row_of = np.full(len(configs), -1)
        row_of[bodies_at] = np.arange(len(bodies_at))
        for k, config in enumerate(configs):
            pin.framesForwardKinematics(self.model, self.data, config)
            T_ee[k] = self.data.oMf[self.ee_id].homogeneous
            if row_of[k] >= 0:
                for b, fid in enumerate(self.body_ids):
                    T_bodies[b, row_of[k]] = self.data.oMf[fid].homogeneous
        return T_ee, dict(zip(self.body_names, T_bodies, strict=True))

    def momentum(self, x_base: Array, q: Array, v_world_base: Array, omega_world_base: Array,
                 qd: Array) -> tuple[Array, Array]:
        """Centroidal momentum ``[P; L_G]`` (world, N·s and N·m·s) and the part due to the joint rates alone."""
        h, h_arm = self.momenta(*(np.asarray(a, dtype=float)[None] for a in (x_base, q, v_world_base,
                                                                             omega_world_base, qd)))
        return h[0], h_arm[0]

    def momenta(self, x_base: Array, q: Array, v_world_base: Array, omega_world_base: Array,
                qd: Array) -> tuple[Array, Array]:
        """:meth:`momentum` at every row: (n, 6) ``[P; L_G]`` and (n, 6) joint-rate part, from (n, ·) rows."""
        configs = pin_configurations(x_base, q)
        quat = x_base[:, 3:] / np.linalg.norm(x_base[:, 3:], axis=-1, keepdims=True)
        R = quats_to_matrices(quat)
        nu = np.concatenate([np.einsum("nji,nj->ni", R, v_world_base), np.einsum("nji,nj->ni", R, omega_world_base),
                             qd], axis=1)  # pinocchio's free-flyer velocity: the base twist in the base frame
        h, h_arm = np.empty((len(configs), 6)), np.empty((len(configs), 6))
        for k, config in enumerate(configs):
            A_g = pin.computeCentroidalMap(self.model, self.data, config)
            h[k], h_arm[k] = A_g @ nu[k], A_g[:, 6:] @ qd[k]
        return h, h_arm


def pin_configurations(x_base: Array, q: Array) -> Array:
    """Pinocchio configurations ``[p, quat(x, y, z, w), q]`` (n, 7 + n_joints) of base poses ``[p, quat wxyz]`` (n, 7)
    and joints (n, n_joints), row by row."""
    return np.concatenate([x_base[:, :3], x_base[:, 4:7], x_base[:, 3:4], q], axis=1)
