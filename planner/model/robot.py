"""The chaser robot: URDF → pinocchio model with a free-flyer root, and CasADi kinematics of the arm.

Conventions
-----------
* Quaternions are ``[w, x, y, z]`` (see :mod:`planner.model.rotation`); pinocchio's free-flyer ``q`` stores
  ``[x, y, z, w]`` and is converted only in :func:`pin_configuration`.
* The arm kinematics are written in the **base frame** (they do not depend on the base pose); world
  quantities are ``p_world = p_world_base + R_world_base p_base``.
* Bodies are ordered base, link1 … link7 (the serial chain from the free-flyer root).

Collision geometry convention (URDF has no capsule): a ``<cylinder radius=r length=L>`` collision
element is read as a **capsule** — the segment of length L along the element frame's z axis, swept by
a sphere of radius r. ``<box size=…>`` elements are boxes. Other geometry is refused.

The symbolic model is built from the pinocchio model's numbers (joint placements, axes, inertias),
because the PyPI ``pin`` wheel has no ``pinocchio.casadi``; pinocchio itself is the test oracle.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, replace
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.errors import ConfigFileError, FieldTypeError, RobotModelError
from planner.model.rotation import rpy_to_matrix
from planner.model.shapes import Box, Capsule, PlacedShape, make_transform

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
# Loading


def load_robot(urdf_path: str | Path, ee_frame: str = "grasp_frame") -> RobotModel:
    """Parse a URDF into a :class:`RobotModel` (free-flyer root + serial revolute chain).

    Raises :class:`~planner.errors.ConfigFileError` when the URDF is missing or unreadable, and
    :class:`~planner.errors.RobotModelError` naming the offending element when it is not a single serial chain
    of revolute joints or lacks the ``ee_frame``.
    """
    src = str(urdf_path)
    tree, model = _read_urdf(Path(urdf_path), src)
    body_names = [_body_of_joint(model, 1)]
    inertias = [_inertia(model.inertias[1])]
    joints: list[ArmJoint] = []
    for jid in range(2, model.njoints):
        joints.append(_arm_joint(model, jid, src))
        body_names.append(_body_of_joint(model, jid))
        inertias.append(_inertia(model.inertias[jid]))
        _check_limits(joints[-1], src)
    if not joints:
        raise RobotModelError(src, "", "no revolute joints found")
    return RobotModel(
        urdf_path=src,
        pin_model=model,
        body_names=tuple(body_names),
        joints=tuple(joints),
        inertias=tuple(inertias),
        ee_frame=ee_frame,
        T_last_ee=_ee_placement(model, ee_frame, src),
        collision_shapes=_collision_shapes(tree, body_names, src),
    )


def _read_urdf(path: Path, src: str) -> tuple[ET.ElementTree, pin.Model]:
    """The URDF's XML tree and its pinocchio model with a free-flyer root."""
    if not path.is_file():
        raise ConfigFileError(src, "robot URDF file not found")
    try:
        tree = ET.parse(path)
    except ET.ParseError as exc:
        raise ConfigFileError(src, f"not valid XML ({exc})") from None
    try:
        model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    except (RuntimeError, ValueError) as exc:  # what pinocchio raises on a bad URDF
        raise ConfigFileError(src, f"pinocchio cannot read it ({str(exc).splitlines()[0]})") from None
    return tree, model


def _arm_joint(model: pin.Model, jid: int, src: str) -> ArmJoint:
    """Joint ``jid`` of the chain (its parent must be joint ``jid − 1``), with its placement, axis and limits."""
    jm = model.joints[jid]
    if model.parents[jid] != jid - 1:
        raise RobotModelError(src, f"joint {model.names[jid]}", "the arm must be a single serial chain")
    axis = _revolute_axis(jm)
    if axis is None:
        raise RobotModelError(src, f"joint {model.names[jid]}",
                              f"only revolute joints are supported, got {jm.shortname()}")
    placement = model.jointPlacements[jid]
    return ArmJoint(
        name=model.names[jid],
        T_parent_joint=make_transform(placement.rotation, placement.translation),
        axis=axis,
        lower_rad=float(model.lowerPositionLimit[jm.idx_q]),
        upper_rad=float(model.upperPositionLimit[jm.idx_q]),
        velocity_rad_s=float(model.velocityLimit[jm.idx_v]),
    )


def _check_limits(joint: ArmJoint, src: str) -> None:
    """A joint's position range must be non-empty and its velocity limit positive."""
    if not joint.lower_rad < joint.upper_rad:
        raise RobotModelError(src, f"joint {joint.name}.limit", "lower must be < upper")
    if not joint.velocity_rad_s > 0:
        raise RobotModelError(src, f"joint {joint.name}.limit.velocity", "must be > 0")


def _ee_placement(model: pin.Model, ee_frame: str, src: str) -> Array:
    """(4, 4) pose [m] of the ``ee_frame`` in the last link's frame; the frame must be on the last link."""
    if not model.existFrame(ee_frame):
        raise RobotModelError(src, "ee_frame", f"frame {ee_frame!r} not found in the URDF")
    frame = model.frames[model.getFrameId(ee_frame)]
    if frame.parentJoint != model.njoints - 1:
        raise RobotModelError(src, "ee_frame", f"frame {ee_frame!r} must be attached to the last link")
    return make_transform(frame.placement.rotation, frame.placement.translation)


def _revolute_axis(jm: pin.JointModel) -> Array | None:
    """(3,) unit axis of a revolute joint in its joint frame, or None when the joint is not revolute."""
    name = jm.shortname()
    if name in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return np.eye(3)["XYZ".index(name[-1])]
    if name == "JointModelRevoluteUnaligned":
        a = np.asarray(jm.extract().axis, dtype=float)
        return a / np.linalg.norm(a)
    return None


def _body_of_joint(model: pin.Model, jid: int) -> str:
    """Name of the URDF link carried directly by joint ``jid`` (the BODY frame at identity placement)."""
    for f in model.frames:
        if f.type == pin.FrameType.BODY and f.parentJoint == jid and np.allclose(f.placement.homogeneous, np.eye(4)):
            return f.name
    raise RobotModelError("URDF", f"joint {model.names[jid]}", "no link attached")


def _inertia(inertia: pin.Inertia) -> BodyInertia:
    """A pinocchio inertia as plain numbers: mass [kg], COM [m], inertia about the COM [kg·m²]."""
    return BodyInertia(float(inertia.mass), np.array(inertia.lever, dtype=float),
                       np.array(inertia.inertia, dtype=float))


def _collision_shapes(tree: ET.ElementTree, body_names: list[str], src: str) -> tuple[tuple[PlacedShape, ...], ...]:
    """Per body, its ``<collision>`` elements as shapes placed in the body frame (cylinders read as capsules)."""
    by_link = {link.get("name"): link for link in tree.getroot().iter("link")}
    result = []
    for body in body_names:
        shapes = []
        for k, col in enumerate(by_link[body].findall("collision")):
            name = col.get("name") or f"{body}_collision{k}"
            origin = col.find("origin")
            xyz = _floats(origin.get("xyz", "0 0 0") if origin is not None else "0 0 0", src, f"{body}.{name}.xyz")
            rpy = _floats(origin.get("rpy", "0 0 0") if origin is not None else "0 0 0", src, f"{body}.{name}.rpy")
            T = make_transform(rpy_to_matrix(rpy), np.asarray(xyz))
            geom = col.find("geometry")
            cyl = geom.find("cylinder") if geom is not None else None
            box = geom.find("box") if geom is not None else None
            if cyl is not None:
                r = float(cyl.get("radius", "nan"))
                length = float(cyl.get("length", "nan"))
                if not (r > 0 and length >= 0):
                    raise RobotModelError(src, f"link {body} collision {name}",
                                          "capsule needs radius > 0 and length >= 0")
                shapes.append(PlacedShape(name, Capsule(r, length), T))
            elif box is not None:
                size = _floats(box.get("size", ""), src, f"{body}.{name}.size")
                if len(size) != 3 or min(size) <= 0:
                    raise RobotModelError(src, f"link {body} collision {name}", "box size needs 3 positive numbers")
                shapes.append(PlacedShape(name, Box(tuple(size)), T))
            else:
                raise RobotModelError(src, f"link {body} collision {name}",
                                  "only <box> and <cylinder> (capsule) are supported")
        result.append(tuple(shapes))
    return tuple(result)


def _floats(text: str, src: str, field: str) -> list[float]:
    """The space-separated numbers of a URDF attribute."""
    try:
        return [float(x) for x in text.split()]
    except ValueError:
        raise FieldTypeError(src, field, f"expected numbers, got {text!r}", text) from None


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
