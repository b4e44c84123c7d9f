"""How far the arm can hold a grasp from the free-floating chaser's centre of mass: a bound from the URDF alone.

The *wrist point* is the lowest body origin that the end-effector's pose fixes: a point on the axis of every joint
after it, which turning those joints leaves where it is in the end-effector frame. For the bundled chaser it is
joint 6's origin (link 6's frame), 0.5 m behind the grasp point along the approach axis.

With no external force the chaser's centre of mass c = Σ m_k p_k / M stays put, so for any configuration and base
pose ``|o − c| = |Σ m_k (o − p_k)| / M ≤ Σ m_k L_k / M``, L_k the length of the chain between body k's centre of
mass and the wrist point (rotations keep lengths, so the sum of the segments' norms bounds it): the *reach radius*.
It is attained, but for the links beyond the wrist point, by the arm stretched straight out from the base's centre
of mass.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.model.freefloating import momentum_map
from planner.model.per_robot import PerRobot
from planner.model.robot import RobotModel

Array = NDArray[np.float64]

# an offset within this of its joint's axis (relative to its length) counts as along it [1]
ALONG_AXIS_TOL = 1e-12


@dataclass(frozen=True)
class WristReach:
    """The wrist point and how far it can be from the chaser's centre of mass.

    ``body_index``: the body whose origin the wrist point is (0 the base, i the link after joint i);
    ``p_grasp_wrist_m``: the wrist point in the grasp (end-effector) frame [m], the same for every configuration;
    ``radius_m``: upper bound of ``|wrist point − centre of mass|`` over every configuration and base pose [m].
    """

    body_index: int
    p_grasp_wrist_m: Array
    radius_m: float


def wrist_reach(robot: RobotModel) -> WristReach:
    """The wrist point of ``robot`` and its reach radius about the chaser's centre of mass."""
    for index in range(robot.n_joints + 1):  # the lowest body whose origin the end-effector's pose fixes
        p_last = _fixed_in_last_link(robot, index)
        if p_last is not None:
            T_ee_last = np.linalg.inv(robot.T_last_ee)
            return WristReach(index, T_ee_last[:3, :3] @ p_last + T_ee_last[:3, 3], _radius(robot, index))
    raise AssertionError("the last link's origin is always fixed in the end-effector frame")


def centre_of_mass_m(robot: RobotModel, q: Array) -> Array:
    """The chaser's centre of mass (3,) in the base frame at joint angles ``q`` [rad] [m]: the free-floating model's
    own (:func:`planner.model.freefloating.momentum_map`)."""
    return np.asarray(_centre_of_mass_function(robot)(np.asarray(q, dtype=float))).ravel()


def _centre_of_mass(robot: RobotModel) -> ca.Function:
    """``q -> r_g`` (3,) of ``robot``, the base frame [m]."""
    q_sym = ca.SX.sym("q", robot.n_joints)
    return ca.Function("centre_of_mass", [q_sym], [momentum_map(robot, q_sym).r_g])


# centre-of-mass Functions kept per process, one per robot object: each reach proof asks for one (a cold plan makes
# a proof per place the chaser may wait), and building it took ~8 ms of a scenario II proof's ~32 ms
CENTRE_OF_MASS_FUNCTIONS_KEPT = 8
_centre_of_mass_function = PerRobot(_centre_of_mass, CENTRE_OF_MASS_FUNCTIONS_KEPT)


def _fixed_in_last_link(robot: RobotModel, index: int) -> Array | None:
    """Body ``index``'s origin in the last link's frame [m] when no later joint moves it there (it lies on each later
    joint's axis), else None."""
    point = np.zeros(3)  # in body ``index``'s frame, then in each later body's
    for joint in robot.joints[index:]:
        R, t = joint.T_parent_joint[:3, :3], joint.T_parent_joint[:3, 3]
        point = R.T @ (point - t)  # in the joint's frame, which its rotation turns about ``axis``
        if np.linalg.norm(np.cross(point, joint.axis)) > ALONG_AXIS_TOL * max(1.0, float(np.linalg.norm(point))):
            return None
    return point


def _radius(robot: RobotModel, wrist: int) -> float:
    """``Σ m_k L_k / M``: each body's chain length to the wrist point, weighted by its mass [m]."""
    offsets = [j.T_parent_joint[:3, 3] for j in robot.joints]  # offsets[i]: body i+1's origin in body i's frame
    total = 0.0
    for k, inertia in enumerate(robot.inertias):
        if k < wrist:  # from body k's centre of mass to the next origin, then origin to origin up to the wrist
            length = np.linalg.norm(offsets[k] - inertia.com_body_m) + sum(
                np.linalg.norm(offsets[i]) for i in range(k + 1, wrist))
        else:  # from the wrist point out to body k's origin, then to its centre of mass
            length = sum(np.linalg.norm(offsets[i]) for i in range(wrist, k)) + np.linalg.norm(inertia.com_body_m)
        total += inertia.mass_kg * float(length)
    return total / robot.total_mass_kg
