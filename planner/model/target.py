"""Torque-free rigid-body motion of the target satellite and of its grasp frame (SI units).

Frames:

* world ``O``: the inertial orbital frame. The target's centre of mass (COM) is fixed in it at
  ``p_world_com`` (same orbit as the chaser, no relative orbital dynamics over a grasp).
* body: the target's principal-axis frame at the COM; ``inertia_body_kg_m2`` is expressed in it.
* grasp: rigidly attached to the body, at ``T_body_grasp``.

The attitude is ``q_world_body`` (``[w, x, y, z]``, see ``planner.model.rotation``): it maps body vectors
into the world. Body rates ``omega_body_rad_s`` are the angular velocity of body w.r.t. world, expressed
in the body frame, so ``q̇ = ½ q ⊗ [0, ω_body]`` and Euler's equations ``I ω̇ = -ω × I ω`` hold.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import OdeSolution, solve_ivp

from planner.errors import ConfigError, TargetStateError
from planner.model.rotation import quat_multiply

# ‖q‖ may deviate from 1 by this much in an observed state (estimator output is rounded); it is then
# renormalised. Larger deviations mean a wrong field (e.g. Euler angles or [x, y, z, w] garbage).
UNIT_QUATERNION_TOL = 1e-6
# ω counts as a pure spin about a principal axis e when ‖ω × e‖ ≤ PURE_SPIN_TOL ‖ω‖; the closed form
# is then exact up to this relative misalignment, which is far below any observation accuracy.
PURE_SPIN_TOL = 1e-12
# Integration tolerances: conservation of energy / momentum to ~1e-11 relative over hundreds of seconds.
ODE_RTOL = 1e-12
ODE_ATOL = 1e-12
# Relative asymmetry of an inertia matrix that is still rounding noise (e.g. from a CAD export).
_INERTIA_SYMMETRY_TOL = 1e-9
# Tolerance on ‖RᵀR − I‖ and det R of the rotation part of T_body_grasp (config files print ~15 digits).
_ROTATION_TOL = 1e-9

_CONFIG_SOURCE = "target"


# ---------------------------------------------------------------------------------------------------
# Validation helpers
# ---------------------------------------------------------------------------------------------------


def _frozen_copy(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Private read-only float copy, so a frozen dataclass really is immutable."""
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def _validate_inertia(inertia_body: ArrayLike, field: str = "inertia_body_kg_m2") -> NDArray[np.float64]:
    """Check a 3×3 inertia (kg·m²) is finite, symmetric and positive definite; return it symmetrised."""
    try:
        inertia = np.asarray(inertia_body, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(_CONFIG_SOURCE, field, f"must be a 3x3 numeric matrix ({exc})") from None
    if inertia.shape != (3, 3):
        raise ConfigError(_CONFIG_SOURCE, field, f"must have shape (3, 3), got {inertia.shape}")
    if not np.all(np.isfinite(inertia)):
        raise ConfigError(_CONFIG_SOURCE, field, "must be finite (got NaN or inf)")
    scale = float(np.max(np.abs(inertia)))
    if np.max(np.abs(inertia - inertia.T)) > _INERTIA_SYMMETRY_TOL * max(scale, np.finfo(float).tiny):
        raise ConfigError(_CONFIG_SOURCE, field, "must be symmetric")
    inertia = 0.5 * (inertia + inertia.T)
    eigvals = np.linalg.eigvalsh(inertia)
    if eigvals[0] <= 0.0:
        raise ConfigError(
            _CONFIG_SOURCE, field, f"must be positive definite, got eigenvalues {np.array2string(eigvals)}"
        )
    return inertia


def _validate_vector(value: ArrayLike, size: int, field: str, error: type[Exception]) -> NDArray[np.float64]:
    """Finite float vector of the given size, else ``error`` naming ``field``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise _make_error(error, field, f"must be a numeric vector of length {size} ({exc})") from None
    if v.shape != (size,):
        raise _make_error(error, field, f"must have shape ({size},), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise _make_error(error, field, f"must be finite, got {np.array2string(v)}")
    return v


def _make_error(error: type[Exception], field: str, problem: str) -> Exception:
    if error is ConfigError:
        return ConfigError(_CONFIG_SOURCE, field, problem)
    return error(f"{field}: {problem}")


def _validate_times(times_s: ArrayLike, t_end_s: float) -> NDArray[np.float64]:
    """Times (s) as a 1-D array inside ``[0, t_end_s]``; scalars become length-1 arrays."""
    times = np.atleast_1d(np.asarray(times_s, dtype=float))
    if times.ndim != 1:
        raise ValueError(f"times_s must be a scalar or a 1-D array, got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        raise ValueError("times_s must be finite")
    if times.size and times.min() < 0.0:
        raise ValueError(f"times_s must be >= 0, got {times.min()!r}")
    if times.size and times.max() > t_end_s:
        raise ValueError(f"times_s must be <= t_end_s = {t_end_s!r}, got {times.max()!r}")
    return times


# ---------------------------------------------------------------------------------------------------
# Batched rotation helpers (planner.model.rotation works on single quaternions; these work on (n, 4))
# ---------------------------------------------------------------------------------------------------


def _quat_multiply_rows(q1: NDArray[np.float64], q2: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row-wise Hamilton product of broadcastable (..., 4) ``[w, x, y, z]`` arrays."""
    w1, x1, y1, z1 = np.moveaxis(q1, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(q2, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def _quats_to_matrices(q_wxyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 4) unit quaternions → (n, 3, 3) rotation matrices (same formula as ``quat_to_matrix``)."""
    w, x, y, z = q_wxyz.T
    R = np.empty((q_wxyz.shape[0], 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def _quat_exp_pure(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """``exp([0, v])`` for (n, 3) ``v`` (rad): ``[cos‖v‖, sin‖v‖ v/‖v‖]``, smooth at ``v = 0``."""
    angle = np.linalg.norm(v, axis=-1)
    # np.sinc(x) = sin(πx)/(πx): avoids the 0/0 at zero rotation without a branch.
    sin_over_angle = np.sinc(angle / np.pi)
    return np.concatenate([np.cos(angle)[:, None], sin_over_angle[:, None] * v], axis=-1)


# ---------------------------------------------------------------------------------------------------
# States and bodies
# ---------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TargetState:
    """Observed target state at ``t = 0``.

    ``attitude_wxyz``: ``q_world_body``, unit (within 1e-6; stored renormalised).
    ``omega_body_rad_s``: angular velocity of the body w.r.t. the world, in the body frame (rad/s).
    Invalid values raise ``TargetStateError`` naming the field.
    """

    attitude_wxyz: NDArray[np.float64]
    omega_body_rad_s: NDArray[np.float64]

    def __post_init__(self) -> None:
        q_world_body = _validate_vector(self.attitude_wxyz, 4, "attitude_wxyz", TargetStateError)
        norm = float(np.linalg.norm(q_world_body))
        if abs(norm - 1.0) > UNIT_QUATERNION_TOL:
            raise TargetStateError(
                f"attitude_wxyz: must be a unit quaternion [w, x, y, z]"
                f" (|norm - 1| <= {UNIT_QUATERNION_TOL:g}), got norm {norm:.9g}"
            )
        omega_body = _validate_vector(self.omega_body_rad_s, 3, "omega_body_rad_s", TargetStateError)
        # Frozen dataclass: object.__setattr__ is the sanctioned way to normalise fields in __post_init__.
        object.__setattr__(self, "attitude_wxyz", _frozen_copy(q_world_body / norm))
        object.__setattr__(self, "omega_body_rad_s", _frozen_copy(omega_body))


@dataclass(frozen=True)
class TargetBody:
    """Mass properties of the target and where its grasp frame is.

    ``mass_kg`` (kg, > 0); ``inertia_body_kg_m2`` (3×3 SPD, kg·m², about the COM in the principal-axis
    body frame); ``p_world_com`` (m, world, fixed in time); ``T_body_grasp`` (4×4 homogeneous, m, pose of
    the grasp frame in the body frame). Invalid values raise ``ConfigError`` naming the field.
    """

    mass_kg: float
    inertia_body_kg_m2: NDArray[np.float64]
    p_world_com: NDArray[np.float64]
    T_body_grasp: NDArray[np.float64]

    def __post_init__(self) -> None:
        mass = float(self.mass_kg)
        if not (np.isfinite(mass) and mass > 0.0):
            raise ConfigError(_CONFIG_SOURCE, "mass_kg", f"must be finite and > 0, got {self.mass_kg!r}")
        inertia = _validate_inertia(self.inertia_body_kg_m2)
        p_world_com = _validate_vector(self.p_world_com, 3, "p_world_com", ConfigError)
        T_body_grasp = np.asarray(self.T_body_grasp, dtype=float)
        if T_body_grasp.shape != (4, 4) or not np.all(np.isfinite(T_body_grasp)):
            raise ConfigError(_CONFIG_SOURCE, "T_body_grasp", "must be a finite 4x4 homogeneous transform")
        if not np.allclose(T_body_grasp[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=_ROTATION_TOL):
            raise ConfigError(_CONFIG_SOURCE, "T_body_grasp", "last row must be [0, 0, 0, 1]")
        R_body_grasp = T_body_grasp[:3, :3]
        if (
            np.max(np.abs(R_body_grasp.T @ R_body_grasp - np.eye(3))) > _ROTATION_TOL
            or abs(np.linalg.det(R_body_grasp) - 1.0) > _ROTATION_TOL
        ):
            raise ConfigError(_CONFIG_SOURCE, "T_body_grasp", "rotation part must be orthonormal with det +1")
        object.__setattr__(self, "mass_kg", mass)
        object.__setattr__(self, "inertia_body_kg_m2", _frozen_copy(inertia))
        object.__setattr__(self, "p_world_com", _frozen_copy(p_world_com))
        object.__setattr__(self, "T_body_grasp", _frozen_copy(T_body_grasp))


# ---------------------------------------------------------------------------------------------------
# Dynamics
# ---------------------------------------------------------------------------------------------------


def euler_rhs(inertia_body: ArrayLike, omega_body: ArrayLike) -> NDArray[np.float64]:
    """Torque-free Euler equations: ``ω̇ = I⁻¹ (-ω × I ω)`` (rad/s²), body frame.

    ``inertia_body`` is 3×3 (kg·m², body frame, validated: ``ConfigError`` if not SPD); ``omega_body``
    (rad/s) is ``(3,)`` or ``(n, 3)`` and the result has the same shape. A full (non-diagonal) inertia is
    accepted, since the equation holds in any body-fixed frame.
    """
    inertia = _validate_inertia(inertia_body)
    return _euler_rhs_unchecked(inertia, np.asarray(omega_body, dtype=float))


def _euler_rhs_unchecked(
    inertia: NDArray[np.float64], omega_body: NDArray[np.float64]
) -> NDArray[np.float64]:
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
    """Attitude and body rates of the target on ``[0, t_end_s]`` (s), evaluable at any time.

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

    def _raw_state(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Unnormalised ``q_world_body`` (n, 4) and ``ω_body`` (n, 3) at validated times."""
        times = _validate_times(times_s, self.t_end_s)
        q0_world_body = self.initial_state.attitude_wxyz
        omega0_body = self.initial_state.omega_body_rad_s
        if self.dense_solution is None:
            # Constant ω: q(t) = q0 ⊗ exp([0, ω t / 2]) solves q̇ = ½ q ⊗ [0, ω] exactly.
            half_rotation_body = 0.5 * times[:, None] * omega0_body[None, :]
            q_world_body = _quat_multiply_rows(q0_world_body[None, :], _quat_exp_pure(half_rotation_body))
            omega_body = np.broadcast_to(omega0_body, (times.size, 3)).copy()
            return q_world_body, omega_body
        if times.size == 0:
            return np.empty((0, 4)), np.empty((0, 3))
        y = self.dense_solution(times)  # (7, n)
        return y[:4].T.copy(), y[4:].T.copy()

    def attitude_wxyz(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """``q_world_body`` (n, 4), renormalised to unit length."""
        q_world_body, _ = self._raw_state(times_s)
        return q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)

    def omega_body(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Body rates (n, 3), rad/s, in the body frame."""
        return self._raw_state(times_s)[1]

    def omega_dot_body(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Body angular acceleration (n, 3), rad/s², body frame, from Euler's equations at ``ω(t)``.

        Equal to the time derivative of ``omega_body`` since the body frame is the one ω is expressed in.
        """
        return _euler_rhs_unchecked(self.inertia_body_kg_m2, self.omega_body(times_s))

    def R_world_body(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Rotation matrices (n, 3, 3) mapping body vectors into the world."""
        return _quats_to_matrices(self.attitude_wxyz(times_s))


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
    """Propagate torque-free attitude motion from ``state`` (at t = 0) to ``t_end_s`` (s).

    ``inertia_body`` (3×3 SPD, kg·m², body frame; ``ConfigError`` otherwise). A pure spin about a principal
    axis is evaluated in closed form; otherwise DOP853 (rtol = atol = 1e-12) with dense output integrates
    ``[q, ω]``. ``force_integration`` skips the closed-form shortcut (for cross-checks).
    """
    inertia = _validate_inertia(inertia_body)
    if not isinstance(state, TargetState):
        raise TypeError(f"state must be a TargetState, got {type(state).__name__}")
    t_end = float(t_end_s)
    if not (np.isfinite(t_end) and t_end > 0.0):
        raise ValueError(f"t_end_s must be finite and > 0, got {t_end_s!r}")
    if not force_integration and _is_pure_spin(inertia, state.omega_body_rad_s):
        return AttitudeTrajectory(_frozen_copy(inertia), state, t_end, None, 0)

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
    return AttitudeTrajectory(_frozen_copy(inertia), state, t_end, solution.sol, int(solution.nfev))


# ---------------------------------------------------------------------------------------------------
# Grasp frame kinematics
# ---------------------------------------------------------------------------------------------------


class TargetMotion:
    """A :class:`TargetBody` moving torque-free from ``state``: body and grasp-frame kinematics in world.

    Times are a scalar or 1-D array in ``[0, t_end_s]`` (s); results have a leading axis ``n``.
    The COM is inertially fixed, so the grasp point's velocity and acceleration are purely rotational.
    """

    def __init__(
        self, body: TargetBody, state: TargetState, t_end_s: float, *, force_integration: bool = False
    ) -> None:
        self._body = body
        self._trajectory = propagate(
            body.inertia_body_kg_m2, state, t_end_s, force_integration=force_integration
        )
        self._R_body_grasp = body.T_body_grasp[:3, :3]
        self._p_body_grasp = body.T_body_grasp[:3, 3]

    @property
    def body(self) -> TargetBody:
        return self._body

    @property
    def trajectory(self) -> AttitudeTrajectory:
        return self._trajectory

    @property
    def t_end_s(self) -> float:
        return self._trajectory.t_end_s

    def body_pose(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``R_world_body`` (n, 3, 3) and ``p_world_com`` (n, 3), m."""
        R_world_body = self._trajectory.R_world_body(times_s)
        p_world_com = np.broadcast_to(self._body.p_world_com, (R_world_body.shape[0], 3)).copy()
        return R_world_body, p_world_com

    def _lever_arm_world(self, R_world_body: NDArray[np.float64]) -> NDArray[np.float64]:
        """``r = R_world_body p_body_grasp`` (n, 3), m: COM → grasp point, in world."""
        return R_world_body @ self._p_body_grasp

    def grasp_pose(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``R_world_grasp`` (n, 3, 3) and ``p_world_grasp`` (n, 3), m."""
        R_world_body = self._trajectory.R_world_body(times_s)
        R_world_grasp = R_world_body @ self._R_body_grasp
        p_world_grasp = self._body.p_world_com + self._lever_arm_world(R_world_body)
        return R_world_grasp, p_world_grasp

    def grasp_twist(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Grasp-point velocity ``v_world_grasp`` (n, 3), m/s, and angular velocity ``omega_world`` (n, 3),
        rad/s, both in world. ``v = ω × r`` because the COM is fixed."""
        q_world_body, omega_body = self._trajectory._raw_state(times_s)
        q_world_body = q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)
        R_world_body = _quats_to_matrices(q_world_body)
        omega_world = np.einsum("nij,nj->ni", R_world_body, omega_body)
        v_world_grasp = np.cross(omega_world, self._lever_arm_world(R_world_body))
        return v_world_grasp, omega_world

    def grasp_acceleration(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Grasp-point acceleration ``a_world_grasp`` (n, 3), m/s², and angular acceleration
        ``alpha_world`` (n, 3), rad/s², both in world: ``a = α × r + ω × (ω × r)``.

        ``α_world = R ω̇_body``: the extra term ``R (ω_body × ω_body)`` of d/dt(R ω_body) vanishes.
        """
        q_world_body, omega_body = self._trajectory._raw_state(times_s)
        q_world_body = q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)
        R_world_body = _quats_to_matrices(q_world_body)
        omega_dot_body = _euler_rhs_unchecked(self._trajectory.inertia_body_kg_m2, omega_body)
        omega_world = np.einsum("nij,nj->ni", R_world_body, omega_body)
        alpha_world = np.einsum("nij,nj->ni", R_world_body, omega_dot_body)
        r_world = self._lever_arm_world(R_world_body)
        a_world_grasp = np.cross(alpha_world, r_world) + np.cross(omega_world, np.cross(omega_world, r_world))
        return a_world_grasp, alpha_world

    def kinetic_energy(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Kinetic energy (n,), J: rotational only, ``½ ωᵀ I ω``, since the COM does not move."""
        omega_body = self._trajectory.omega_body(times_s)
        inertia = self._trajectory.inertia_body_kg_m2
        return 0.5 * np.einsum("ni,ij,nj->n", omega_body, inertia, omega_body)

    def angular_momentum_world(self, times_s: ArrayLike) -> NDArray[np.float64]:
        """Angular momentum about the COM (n, 3), N·m·s, world: ``R_world_body I ω_body``."""
        q_world_body, omega_body = self._trajectory._raw_state(times_s)
        q_world_body = q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)
        R_world_body = _quats_to_matrices(q_world_body)
        h_body = omega_body @ self._trajectory.inertia_body_kg_m2.T
        return np.einsum("nij,nj->ni", R_world_body, h_body)
