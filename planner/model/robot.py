"""The chaser robot: its model (bodies, joints, inertias, shapes), the pinocchio boundary and CasADi kinematics.

Conventions
-----------
* Quaternions are ``[w, x, y, z]`` (see :mod:`planner.model.rotation`); pinocchio's free-flyer ``q`` stores
  ``[x, y, z, w]`` and is converted only in :func:`pin_configuration`.
* The arm kinematics are written in the **base frame** (they do not depend on the base pose); world
  quantities are ``p_world = p_world_base + R_world_base p_base``.
* Bodies are ordered base, link1 … link7 (the serial chain from the free-flyer root).

The model is read from a URDF by :func:`planner.model.urdf.load_robot`.
The symbolic model is built from the pinocchio model's numbers (joint placements, axes, inertias),
because the PyPI ``pin`` wheel has no ``pinocchio.casadi``; pinocchio itself is the test oracle.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.model.shapes import PlacedShape

Array = NDArray[np.float64]


@dataclass(frozen=True)
class BodyInertia:
    """Rigid-body inertia in its body frame: mass [kg], COM [m], inertia about the COM [kg·m²]."""

    mass_kg: float
    com_body_m: Array
    inertia_com_kg_m2: Array


@dataclass(frozen=True)
class ArmJoint:
    """One revolute joint of the serial chain: placement in its parent body frame and unit axis."""

    name: str
    T_parent_joint: Array  # 4×4, the joint frame (= child body frame at q = 0) in the parent body frame
    axis: Array  # unit axis in the joint frame
    lower_rad: float
    upper_rad: float
    velocity_rad_s: float


@dataclass(frozen=True)
class RobotModel:
    """A free-floating base carrying one serial chain of revolute joints.

    ``pin_model`` is the pinocchio model with a free-flyer root (the oracle and the numeric backend of
    tests); the other fields are plain numbers from it, used to write the CasADi kinematics.
    """

    urdf_path: str
    pin_model: pin.Model
    body_names: tuple[str, ...]  # base first, then one body per joint
    joints: tuple[ArmJoint, ...]
    inertias: tuple[BodyInertia, ...]  # per body, same order as body_names
    ee_frame: str
    T_last_ee: Array  # grasp frame in the last link's frame
    collision_shapes: tuple[tuple[PlacedShape, ...], ...]  # per body

    @property
    def n_joints(self) -> int:
        """Number of arm joints (7 for the paper's chaser)."""
        return len(self.joints)

    @property
    def q_min(self) -> Array:
        """(n_joints,) lower joint limits [rad]."""
        return np.array([j.lower_rad for j in self.joints])

    @property
    def q_max(self) -> Array:
        """(n_joints,) upper joint limits [rad]."""
        return np.array([j.upper_rad for j in self.joints])

    @property
    def qd_max(self) -> Array:
        """(n_joints,) joint rate limits [rad/s]."""
        return np.array([j.velocity_rad_s for j in self.joints])

    @property
    def p_base_joint1_m(self) -> Array:
        """Origin of the first joint in the base frame [m]; its axis passes through it for every q."""
        return self.joints[0].T_parent_joint[:3, 3].copy()

    @property
    def reach_from_joint1_m(self) -> float:
        """Upper bound of ``|p_ee(q) − p_joint1|`` over all q [m].

        The end-effector position is the first joint's origin plus the chain's later translations, each
        rotated by the joints before it; rotations keep lengths, so the sum of their norms bounds it.
        """
        offsets = [j.T_parent_joint[:3, 3] for j in self.joints[1:]] + [self.T_last_ee[:3, 3]]
        return float(sum(np.linalg.norm(t) for t in offsets))

    @property
    def total_mass_kg(self) -> float:
        """Mass of the base and every link [kg]."""
        return float(sum(b.mass_kg for b in self.inertias))

    def with_payload(self, payload: BodyInertia, T_ee_payload: Array) -> RobotModel:
        """The compound robot with a payload rigidly attached to the end-effector frame (stabilization).

        ``payload`` is given in its own frame, placed at ``T_ee_payload`` in the ee frame. The payload's
        inertia is added to the last link's (rigid attachment, paper §4.1.1 "the inertial parameters of
        the last robot link are updated accordingly").
        """
        T_last_payload = self.T_last_ee @ T_ee_payload
        last = self.inertias[-1]
        combined = _add_inertias(last, payload, T_last_payload)
        model = self.pin_model.copy()
        jid = model.njoints - 1
        R, p = T_last_payload[:3, :3], T_last_payload[:3, 3]
        model.inertias[jid] = model.inertias[jid] + pin.SE3(R, p).act(
            pin.Inertia(payload.mass_kg, payload.com_body_m, payload.inertia_com_kg_m2)
        )
        return replace(self, pin_model=model, inertias=(*self.inertias[:-1], combined))


def _add_inertias(a: BodyInertia, b: BodyInertia, T_a_b: Array) -> BodyInertia:
    """Inertia of two rigidly joined bodies, in a's frame (parallel-axis theorem)."""
    R, p = T_a_b[:3, :3], T_a_b[:3, 3]
    com_b_in_a = p + R @ b.com_body_m
    m = a.mass_kg + b.mass_kg
    com = (a.mass_kg * a.com_body_m + b.mass_kg * com_b_in_a) / m

    def shifted(I_com: Array, mass: float, c: Array) -> Array:
        d = c - com
        return I_com + mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))

    inertia = shifted(a.inertia_com_kg_m2, a.mass_kg, a.com_body_m) + shifted(
        R @ b.inertia_com_kg_m2 @ R.T, b.mass_kg, com_b_in_a
    )
    return BodyInertia(m, com, inertia)


# ----------------------------------------------------------------------------------------------------
# Pinocchio boundary


def pin_configuration(p_world_base: Array, quat_world_base_wxyz: Array, q_arm: Array) -> Array:
    """Pinocchio configuration vector ``[p, quat(x,y,z,w), q_arm]`` from our base pose and joints."""
    w, x, y, z = quat_world_base_wxyz
    return np.concatenate([p_world_base, [x, y, z, w], q_arm])


def pin_velocity(R_world_base: Array, v_world_base: Array, omega_world_base: Array, qd_arm: Array) -> Array:
    """Pinocchio free-flyer velocity (base twist in the LOCAL base frame) from world-frame base rates.

    ``v_world_base`` is the velocity of the base frame origin in world coordinates.
    """
    return np.concatenate([R_world_base.T @ v_world_base, R_world_base.T @ omega_world_base, qd_arm])


# ----------------------------------------------------------------------------------------------------
# CasADi kinematics in the base frame


def _rodrigues(axis: Array, angle: ca.SX | ca.MX) -> ca.SX | ca.MX:
    """Rotation about a constant unit axis by a symbolic angle [rad]."""
    K = ca.DM(np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]))
    return ca.DM.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * ca.mtimes(K, K)


@dataclass(frozen=True)
class ChainKinematics:
    """Symbolic poses of the bodies in the base frame, and what the momentum map needs.

    ``R[i]``, ``p[i]``: body i frame in the base frame (i = 0 is the base itself).
    ``axes_base[j]``, ``origins_base[j]``: joint j's axis and origin in the base frame.
    ``R_ee``, ``p_ee``: end-effector frame.
    """

    R: list[ca.SX | ca.MX]  # (3, 3) each
    p: list[ca.SX | ca.MX]  # (3,) each [m]
    axes_base: list[ca.SX | ca.MX]
    origins_base: list[ca.SX | ca.MX]
    R_ee: ca.SX | ca.MX
    p_ee: ca.SX | ca.MX


def chain_kinematics(robot: RobotModel, q: ca.SX | ca.MX) -> ChainKinematics:
    """Forward kinematics of the serial chain in the base frame for symbolic joint angles ``q`` [rad]."""
    R = [ca.SX.eye(3) if isinstance(q, ca.SX) else ca.MX.eye(3)]
    p = [ca.SX.zeros(3) if isinstance(q, ca.SX) else ca.MX.zeros(3)]
    axes, origins = [], []
    for j, joint in enumerate(robot.joints):
        R_pj = ca.DM(joint.T_parent_joint[:3, :3])
        p_pj = ca.DM(joint.T_parent_joint[:3, 3])
        R_joint = ca.mtimes(R[-1], R_pj)
        p_joint = p[-1] + ca.mtimes(R[-1], p_pj)
        axes.append(ca.mtimes(R_joint, ca.DM(joint.axis)))
        origins.append(p_joint)
        R.append(ca.mtimes(R_joint, _rodrigues(joint.axis, q[j])))
        p.append(p_joint)
    R_ee = ca.mtimes(R[-1], ca.DM(robot.T_last_ee[:3, :3]))
    p_ee = p[-1] + ca.mtimes(R[-1], ca.DM(robot.T_last_ee[:3, 3]))
    return ChainKinematics(R, p, axes, origins, R_ee, p_ee)


def fk_function(robot: RobotModel) -> ca.Function:
    """CasADi Function ``(q) -> (R_0, p_0, …, R_n, p_n, R_ee, p_ee)``, every body in the base frame."""
    q = ca.SX.sym("q", robot.n_joints)
    kin = chain_kinematics(robot, q)
    outs = []
    for R, p in zip(kin.R, kin.p, strict=True):
        outs += [R, p]
    outs += [kin.R_ee, kin.p_ee]
    return ca.Function("fk_base", [q], outs)
