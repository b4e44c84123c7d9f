"""Torque-free attitude motion of a rigid body: Euler's equations, and their solution on ``[0, t_end]`` [s].

The attitude is ``q_world_body`` (``[w, x, y, z]``, see :mod:`planner.model.rotation`): it maps body vectors
into the world. Body rates ``omega_body_rad_s`` are the angular velocity of body w.r.t. world, expressed
in the body frame, so ``q̇ = ½ q ⊗ [0, ω_body]`` and Euler's equations ``I ω̇ = -ω × I ω`` hold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import OdeSolution, solve_ivp

from planner.model.quaternion_rows import quat_exp_pure_rows, quats_to_matrices
from planner.model.rotation import quat_multiply
from planner.model.target_state import TargetState
from planner.model.target_validation import frozen_copy, validate_inertia, validate_times

# ω counts as a pure spin about a principal axis e when ‖ω × e‖ ≤ PURE_SPIN_TOL ‖ω‖; the closed form
# is then exact up to this relative misalignment, which is far below any observation accuracy.
PURE_SPIN_TOL = 1e-12
# Integration tolerances: conservation of energy / momentum to ~1e-11 relative over hundreds of seconds.
ODE_RTOL = 1e-12
ODE_ATOL = 1e-12


def euler_rhs(inertia_body: ArrayLike, omega_body: ArrayLike) -> NDArray[np.float64]:
    """Torque-free Euler equations: ``ω̇ = I⁻¹ (-ω × I ω)`` [rad/s²], body frame.

    ``inertia_body`` is 3×3 (kg·m², body frame, validated: ``ConfigError`` if not SPD); ``omega_body``
    [rad/s] is ``(3,)`` or ``(n, 3)`` and the result has the same shape. A full (non-diagonal) inertia is
    accepted, since the equation holds in any body-fixed frame.
    """
    inertia = validate_inertia(inertia_body)
    return euler_rhs_unchecked(inertia, np.asarray(omega_body, dtype=float))


def euler_rhs_unchecked(
    inertia: NDArray[np.float64], omega_body: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:func:`euler_rhs` for an inertia already validated: ``ω̇`` [rad/s²] of the same shape as ``omega_body``."""
    h_body = omega_body @ inertia.T  # I ω, row-wise
    torque_like = -np.cross(omega_body, h_body)
    # solve, not an explicit inverse: better conditioned for very flat inertia ellipsoids.
    return np.linalg.solve(inertia, torque_like.T).T


def _is_pure_spin(inertia: NDArray[np.float64], omega_body: NDArray[np.float64]) -> bool:
    """True when ω is (numerically) a steady spin, so the constant-ω closed form is exact.

    Either ω is aligned with a principal axis (‖ω × e_i‖ ≤ 1e-12 ‖ω‖), or the gyroscopic term vanishes
    relative to its scale (‖ω × Iω‖ ≤ 1e-12 ‖ω‖‖Iω‖), which also catches any spin in the degenerate
    plane of an axisymmetric body, where eigh returns arbitrary principal axes.
    """
    omega_norm = float(np.linalg.norm(omega_body))
    if omega_norm == 0.0:
        return True
    _, principal_axes_body = np.linalg.eigh(inertia)
    for e_body in principal_axes_body.T:
        if np.linalg.norm(np.cross(omega_body, e_body)) <= PURE_SPIN_TOL * omega_norm:
            return True
    h_body = inertia @ omega_body
    gyro = float(np.linalg.norm(np.cross(omega_body, h_body)))
    return gyro <= PURE_SPIN_TOL * omega_norm * float(np.linalg.norm(h_body))


@dataclass(frozen=True)
class AttitudeTrajectory:
    """Attitude and body rates of the target on ``[0, t_end_s]`` [s], evaluable at any time.

    Built by :func:`propagate`. ``dense_solution`` is scipy's DOP853 dense output of the 7-state
    ``[q_world_body (4), ω_body (3)]``, or ``None`` for a pure spin, evaluated in closed form
    ``q(t) = q0 ⊗ exp(ω t / 2)``. All methods take a scalar or 1-D array of times in ``[0, t_end_s]``
    (``ValueError`` otherwise) and return arrays with a leading axis ``n = len(times_s)``.
    """

    inertia_body_kg_m2: NDArray[np.float64]
    initial_state: TargetState
    t_end_s: float
    dense_solution: OdeSolution | None
    n_rhs_evaluations: int = 0

    @property
    def is_closed_form(self) -> bool:
        """True for a pure spin evaluated analytically (no ODE integration)."""
        return self.dense_solution is None

    def raw_state(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Unnormalised ``q_world_body`` (n, 4) and ``ω_body`` (n, 3) at validated times."""
        times = validate_times(times_s, self.t_end_s)
        q0_world_body = self.initial_state.attitude_wxyz
        omega0_body = self.initial_state.omega_body_rad_s
        if self.dense_solution is None:
            # Constant ω: q(t) = q0 ⊗ exp([0, ω t / 2]) solves q̇ = ½ q ⊗ [0, ω] exactly.
            half_rotation_body = 0.5 * times[:, None] * omega0_body[None, :]
            q_world_body = quat_multiply(q0_world_body[None, :], quat_exp_pure_rows(half_rotation_body))
            omega_body = np.broadcast_to(omega0_body, (times.size, 3)).copy()
            return q_world_body, omega_body
        if times.size == 0:
            return np.empty((0, 4)), np.empty((0, 3))
        y = self.dense_solution(times)  # (7, n)
        return y[:4].T.copy(), y[4:].T.copy()

    def attitude_wxyz(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """``q_world_body`` (n, 4), renormalised to unit length."""
        q_world_body, _ = self.raw_state(times_s)
        return q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)

    def omega_body(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Body rates (n, 3), rad/s, in the body frame."""
        return self.raw_state(times_s)[1]

    def omega_dot_body(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Body angular acceleration (n, 3), rad/s², body frame, from Euler's equations at ``ω(t)``.

        Equal to the time derivative of ``omega_body`` since the body frame is the one ω is expressed in.
        """
        return euler_rhs_unchecked(self.inertia_body_kg_m2, self.omega_body(times_s))

    def R_world_body(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Rotation matrices (n, 3, 3) mapping body vectors into the world."""
        return quats_to_matrices(self.attitude_wxyz(times_s))


def _attitude_ode_rhs(
    inertia: NDArray[np.float64],
) -> Callable[[float, NDArray[np.float64]], NDArray[np.float64]]:
    """Right-hand side of the 7-state ODE ``[q̇, ω̇] = [½ q ⊗ [0, ω], I⁻¹(-ω × Iω)]``."""
    inertia_inv = np.linalg.inv(inertia)  # 3×3 SPD, inverted once; the RHS is called thousands of times

    def rhs(_t: float, y: NDArray[np.float64]) -> NDArray[np.float64]:
        q_world_body = y[:4]
        omega_body = y[4:]
        q_dot = 0.5 * quat_multiply(q_world_body, np.array([0.0, *omega_body]))
        omega_dot_body = inertia_inv @ (-np.cross(omega_body, inertia @ omega_body))
        return np.concatenate([q_dot, omega_dot_body])

    return rhs


def propagate(
    inertia_body: ArrayLike,
    state: TargetState,
    t_end_s: float,
    *,
    force_integration: bool = False,
) -> AttitudeTrajectory:
    """Propagate torque-free attitude motion from ``state`` (at t = 0) to ``t_end_s`` [s].

    ``inertia_body`` (3×3 SPD, kg·m², body frame; ``ConfigError`` otherwise). A pure spin about a principal
    axis is evaluated in closed form; otherwise DOP853 (rtol = atol = 1e-12) with dense output integrates
    ``[q, ω]``. ``force_integration`` skips the closed-form shortcut (for cross-checks).
    """
    inertia = validate_inertia(inertia_body)
    if not isinstance(state, TargetState):
        raise TypeError(f"state must be a TargetState, got {type(state).__name__}")
    t_end = float(t_end_s)
    if not (np.isfinite(t_end) and t_end > 0.0):
        raise ValueError(f"t_end_s must be finite and > 0, got {t_end_s!r}")
    if not force_integration and _is_pure_spin(inertia, state.omega_body_rad_s):
        return AttitudeTrajectory(frozen_copy(inertia), state, t_end, None, 0)

    y0 = np.concatenate([state.attitude_wxyz, state.omega_body_rad_s])
    solution = solve_ivp(
        _attitude_ode_rhs(inertia),
        (0.0, t_end),
        y0,
        method="DOP853",
        rtol=ODE_RTOL,
        atol=ODE_ATOL,
        dense_output=True,
    )
    if not solution.success:  # pragma: no cover - DOP853 on this smooth ODE only fails on a bug
        raise RuntimeError(f"attitude propagation failed: {solution.message}")
    return AttitudeTrajectory(frozen_copy(inertia), state, t_end, solution.sol, int(solution.nfev))
