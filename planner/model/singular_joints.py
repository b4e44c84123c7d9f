"""Joint angles where a serial arm is singular whatever its other joints: the two neighbouring axes collinear.

When joint j turns the axes of joints j−1 and j+1 onto one line (a wrist's q6 = 0, an elbow stretched straight,
a shoulder's q2 = 0 on the paper's chaser), those two joints move the end effector alike: the arm loses a degree of
freedom there. Whether that happens depends on q_j alone: a rotation about either line leaves the line where it
is, so the angles are found once per robot from its joint placements. Crossing such an angle flips the arm's
branch (the wrist's (q5, q6, q7) ↔ (q5 + π, −q6, q7 + π) hold one pose): near it the two neighbours swing in
opposite directions while the end effector hardly moves, so a Cartesian IK (the tracking phase, paper Eq. 7) asks
for joint rates that grow without bound; the configurations it joins must lie on one side of it
(:mod:`planner.phases.approach_solve`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize_scalar

from planner.model.robot import ArmJoint, RobotModel

Array = NDArray[np.float64]

SCAN_STEP_RAD = np.radians(0.5)  # scan of each joint's range for near-collinear neighbours
COLLINEAR_TOL = 1e-9  # squared sine of the axes' angle plus squared offset of the lines [1, m²]: collinear below


@dataclass(frozen=True)
class SingularAngle:
    """A joint angle at which the axes of the joint's two neighbours are collinear."""

    joint_index: int  # 0-based arm joint
    angle_rad: float


def _rotation(axis: Array, angle: float) -> Array:
    """Rotation ``(3, 3)`` about the unit ``axis`` by ``angle`` [rad] (Rodrigues)."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def collinearity(before: ArmJoint, joint: ArmJoint, after: ArmJoint, angle_rad: float) -> float:
    """Squared sine of the angle between the axes of ``before`` and ``after`` plus the squared distance [m²] of
    ``after``'s origin from ``before``'s axis line, with ``joint`` at ``angle_rad``: zero when the lines coincide.

    Expressed in ``before``'s joint frame (its own angle at 0: a rotation about its line changes nothing here).
    """
    a = before.axis
    T_j = joint.T_parent_joint
    R = T_j[:3, :3] @ _rotation(joint.axis, angle_rad)
    origin = T_j[:3, 3] + R @ after.T_parent_joint[:3, 3]
    direction = R @ after.T_parent_joint[:3, :3] @ after.axis
    return float(np.sum(np.cross(a, direction) ** 2) + np.sum(np.cross(origin, a) ** 2))


def singular_angles(robot: RobotModel) -> tuple[SingularAngle, ...]:
    """Every interior joint's angles within its limits where its neighbours' axes are collinear."""
    found: list[SingularAngle] = []
    joints = robot.joints
    for j in range(1, len(joints) - 1):
        before, joint, after = joints[j - 1], joints[j], joints[j + 1]
        grid = np.arange(joint.lower_rad, joint.upper_rad + SCAN_STEP_RAD, SCAN_STEP_RAD)
        values = np.array([collinearity(before, joint, after, a) for a in grid])
        for i in range(len(grid)):
            lo, hi = max(i - 1, 0), min(i + 1, len(grid) - 1)
            if values[i] > min(values[lo], values[hi]) or (i > 0 and values[i] == values[i - 1]):
                continue  # not a local minimum of the scan (a plateau counts once)
            # the square root is V-shaped at a root, where the squared sum is flat: Brent's method pins it down
            best = minimize_scalar(lambda a: np.sqrt(collinearity(before, joint, after, a)),  # noqa: B023
                                   bounds=(grid[lo], grid[hi]), method="bounded", options={"xatol": 1e-12})
            if best.fun**2 < COLLINEAR_TOL:
                angle = float(best.x) if abs(best.x) > SCAN_STEP_RAD * 1e-6 else 0.0  # a zero stays exactly zero
                found.append(SingularAngle(j, angle))
    return tuple(found)
