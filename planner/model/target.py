"""The target satellite's body (mass, inertia, grasp frame) and its grasp frame's motion in the world (SI units).

Frames:

* world ``O``: the inertial orbital frame. The target's centre of mass (COM) is fixed in it at
  ``p_world_com`` (same orbit as the chaser, no relative orbital dynamics over a grasp).
* body: the target's principal-axis frame at the COM; ``inertia_body_kg_m2`` is expressed in it.
* grasp: rigidly attached to the body, at ``T_body_grasp``.

The attitude's torque-free motion is :mod:`planner.model.attitude`; the observed state at t = 0 is
:class:`~planner.model.target_state.TargetState`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.errors import FieldValueError
from planner.model.attitude import AttitudeTrajectory, euler_rhs_unchecked, propagate
from planner.model.quaternion_rows import quats_to_matrices
from planner.model.target_state import TargetState
from planner.model.target_validation import (
    CONFIG_SOURCE,
    body_field_error,
    frozen_copy,
    validate_inertia,
    validate_vector,
)

# Tolerance on ‖RᵀR − I‖ and det R of the rotation part of T_body_grasp (config files print ~15 digits).
_ROTATION_TOL = 1e-9


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
            raise FieldValueError(CONFIG_SOURCE, "mass_kg", f"must be finite and > 0, got {self.mass_kg!r}",
                                  self.mass_kg)
        inertia = validate_inertia(self.inertia_body_kg_m2)
        p_world_com = validate_vector(self.p_world_com, 3, "p_world_com", body_field_error)
        T_body_grasp = np.asarray(self.T_body_grasp, dtype=float)
        if T_body_grasp.shape != (4, 4) or not np.all(np.isfinite(T_body_grasp)):
            raise FieldValueError(CONFIG_SOURCE, "T_body_grasp", "must be a finite 4x4 homogeneous transform",
                                  self.T_body_grasp)
        if not np.allclose(T_body_grasp[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=_ROTATION_TOL):
            raise FieldValueError(CONFIG_SOURCE, "T_body_grasp", "last row must be [0, 0, 0, 1]", T_body_grasp)
        R_body_grasp = T_body_grasp[:3, :3]
        if (
            np.max(np.abs(R_body_grasp.T @ R_body_grasp - np.eye(3))) > _ROTATION_TOL
            or abs(np.linalg.det(R_body_grasp) - 1.0) > _ROTATION_TOL
        ):
            raise FieldValueError(CONFIG_SOURCE, "T_body_grasp", "rotation part must be orthonormal with det +1",
                                  T_body_grasp)
        object.__setattr__(self, "mass_kg", mass)
        object.__setattr__(self, "inertia_body_kg_m2", frozen_copy(inertia))
        object.__setattr__(self, "p_world_com", frozen_copy(p_world_com))
        object.__setattr__(self, "T_body_grasp", frozen_copy(T_body_grasp))


class TargetMotion:
    """A :class:`TargetBody` moving torque-free from ``state``: body and grasp-frame kinematics in world.

    Times are a scalar or 1-D array in ``[0, t_end_s]`` [s]; results have a leading axis ``n``.
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
        """The moving body's mass properties and grasp frame."""
        return self._body

    @property
    def trajectory(self) -> AttitudeTrajectory:
        """The attitude and body rates over ``[0, t_end_s]``."""
        return self._trajectory

    @property
    def t_end_s(self) -> float:
        """End of the propagated interval [s]."""
        return self._trajectory.t_end_s

    def T_world_body(self, t_s: float) -> NDArray[np.float64]:
        """The body frame's pose (4, 4) at ``t_s`` [s]: rotation and COM [m], world."""
        R_world_body, p_world_com = self.body_pose(t_s)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_world_body[0], p_world_com[0]
        return T

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
        q_world_body, omega_body = self._trajectory.raw_state(times_s)
        q_world_body = q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)
        R_world_body = quats_to_matrices(q_world_body)
        omega_world = np.einsum("nij,nj->ni", R_world_body, omega_body)
        v_world_grasp = np.cross(omega_world, self._lever_arm_world(R_world_body))
        return v_world_grasp, omega_world

    def grasp_acceleration(self, times_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Grasp-point acceleration ``a_world_grasp`` (n, 3), m/s², and angular acceleration
        ``alpha_world`` (n, 3), rad/s², both in world: ``a = α × r + ω × (ω × r)``.

        ``α_world = R ω̇_body``: the extra term ``R (ω_body × ω_body)`` of d/dt(R ω_body) vanishes.
        """
        q_world_body, omega_body = self._trajectory.raw_state(times_s)
        q_world_body = q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)
        R_world_body = quats_to_matrices(q_world_body)
        omega_dot_body = euler_rhs_unchecked(self._trajectory.inertia_body_kg_m2, omega_body)
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
        q_world_body, omega_body = self._trajectory.raw_state(times_s)
        q_world_body = q_world_body / np.linalg.norm(q_world_body, axis=1, keepdims=True)
        R_world_body = quats_to_matrices(q_world_body)
        h_body = omega_body @ self._trajectory.inertia_body_kg_m2.T
        return np.einsum("nij,nj->ni", R_world_body, h_body)
