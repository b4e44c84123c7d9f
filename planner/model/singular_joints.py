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
from planner.model.rotation import axis_angle_to_matrix

Array = NDArray[np.float64]

SCAN_STEP_RAD = np.radians(0.5)  # scan of each joint's range for near-collinear neighbours
COLLINEAR_TOL = 1e-9  # squared sine of the axes' angle plus squared offset of the lines [1, m²]: collinear below


@dataclass(frozen=True)
class SingularAngle:
    """A joint angle at which the axes of the joint's two neighbours are collinear."""

    joint_index: int  # 0-based arm joint
    angle_rad: float


def collinearity(before: ArmJoint, joint: ArmJoint, after: ArmJoint, angle_rad: float) -> float:
    """Squared sine of the angle between the axes of ``before`` and ``after`` plus the squared distance [m²] of
    ``after``'s origin from ``before``'s axis line, with ``joint`` at ``angle_rad``: zero when the lines coincide.

    Expressed in ``before``'s joint frame (its own angle at 0: a rotation about its line changes nothing here).
    """
    a = before.axis
    T_j = joint.T_parent_joint
    R = T_j[:3, :3] @ axis_angle_to_matrix(joint.axis, angle_rad)
    origin = T_j[:3, 3] + R @ after.T_parent_joint[:3, 3]
    direction = R @ after.T_parent_joint[:3, :3] @ after.axis
    return float(np.sum(np.cross(a, direction) ** 2) + np.sum(np.cross(origin, a) ** 2))


def singular_angles(robot: RobotModel) -> tuple[SingularAngle, ...]:
    """Every interior joint's angles within its limits where its neighbours' axes are collinear."""
    found: list[SingularAngle] = []
    joints = robot.joints
    for j in range(1, len(joints) - 1):
        before, joint, after = joints[j - 1], joints[j], joints[j + 1]
        count = int(np.ceil((joint.upper_rad - joint.lower_rad) / SCAN_STEP_RAD)) + 1
        grid = np.linspace(joint.lower_rad, joint.upper_rad, count)  # both limits scanned, nothing beyond them
        values = np.array([collinearity(before, joint, after, a) for a in grid])
        for i in range(len(grid)):
            lo, hi = max(i - 1, 0), min(i + 1, len(grid) - 1)
            if values[i] > min(values[lo], values[hi]) or (i > 0 and values[i] == values[i - 1]):
                continue  # not a local minimum of the scan (a plateau counts once)
            angle = _refined_root(before, joint, after, grid[lo], grid[hi])
            if collinearity(before, joint, after, angle) < COLLINEAR_TOL:
                found.append(SingularAngle(j, angle if abs(angle) > SCAN_STEP_RAD * 1e-6 else 0.0))  # 0 stays 0
    return tuple(found)


def _refined_root(before: ArmJoint, joint: ArmJoint, after: ArmJoint, lo_rad: float, hi_rad: float) -> float:
    """The angle in [lo_rad, hi_rad] where the neighbours come closest to collinear: Brent's method on the square root
    of :func:`collinearity` (V-shaped at a root, where the squared sum is flat), or an end of the interval (a joint
    limit) when that is closer, which the bounded method only approaches."""
    def distance(angle: float) -> float:
        return float(np.sqrt(collinearity(before, joint, after, angle)))

    best = minimize_scalar(distance, bounds=(lo_rad, hi_rad), method="bounded", options={"xatol": 1e-12})
    return float(min((best.x, lo_rad, hi_rad), key=distance))
