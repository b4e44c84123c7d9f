"""Reading the chaser from a URDF: a pinocchio model with a free-flyer root, one serial revolute chain.

Collision geometry convention (URDF has no capsule): a ``<cylinder radius=r length=L>`` collision
element is read as a **capsule** — the segment of length L along the element frame's z axis, swept by
a sphere of radius r. ``<box size=…>`` elements are boxes. Other geometry is refused.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.errors import ConfigFileError, FieldTypeError, RobotModelError
from planner.model.robot import ArmJoint, BodyInertia, RobotModel
from planner.model.rotation import rpy_to_matrix
from planner.model.shapes import Box, Capsule, PlacedShape, make_transform

Array = NDArray[np.float64]


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
