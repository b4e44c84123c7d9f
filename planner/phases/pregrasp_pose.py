"""The pre-grasp pose: the grasp frame at the angle the gripper holds it about a free axis, backed off along its z.

The tracking closes the back-off along the grasp frame turned to the gripper's angle (``tracking._DesiredPose``). A
pre-grasp backed off along the configured frame's z instead sits 2·b·sin(ψ/2) from the tracking's own start line
(0.35 m at ψ = 120° for b = 0.2 m): the blend then carries the gripper sideways, and at ψ near 180° through the handle.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.rotation import axis_angle_to_matrix
from planner.phases.approach_ik import PoseIK
from planner.phases.tracking import free_axis_angle

Array = NDArray[np.float64]


def pregrasp_position(scenario: Scenario, R_world_grasp: Array, p_world_grasp: Array) -> Array:
    """The pre-grasp point (3,) [m]: ``p_world_grasp`` backed off along the z axis of ``R_world_grasp`` (3, 3); numbers
    or CasADi expressions (the approach NLP's Eq. 20 row)."""
    return p_world_grasp - scenario.approach.pregrasp_backoff_m * R_world_grasp[:, 2]


def free_axis_turn(scenario: Scenario, R_world_grasp: Array, R_world_ee: Array) -> Array:
    """The rotation (3, 3) about the grasp's free axis from ``R_world_grasp`` to the angle the end-effector
    (``R_world_ee``) holds it at; the identity without a free axis."""
    axis = scenario.target.grasp.free_axis
    if axis is None:
        return np.eye(3)
    return axis_angle_to_matrix(axis, free_axis_angle(R_world_grasp, R_world_ee, axis))


def at_own_angle(scenario: Scenario, ik: PoseIK, R_world_grasp: Array, p_world_grasp: Array, x_pre: Array,
                 R_world_ee: Array, drift: tuple[Array, Array] | None = None) -> Array:
    """``x_pre`` ``[q, b_x, b_z]``, whose ee (``R_world_ee``, drift applied) holds the grasp frame at some angle about
    its free axis, solved again for the pre-grasp backed off along the frame turned to that angle (the whole
    orientation matched); ``x_pre`` itself without a free axis, or where that solve fails."""
    if scenario.target.grasp.free_axis is None:
        return x_pre
    R_G = R_world_grasp @ free_axis_turn(scenario, R_world_grasp, R_world_ee)
    x = ik.solve(pregrasp_position(scenario, R_G, p_world_grasp), R_G, np.eye(3), [x_pre], drift=drift)
    return x_pre if x is None else x
