"""What verify reads of a plan: a structural type, so verify needs nothing of the planner that made it."""

from __future__ import annotations

from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.target_state import TargetState

Array = NDArray[np.float64]


class HeldTarget(Protocol):
    """The grasp as verify needs it: where the target sits in the gripper."""

    T_ee_target: Array  # (4, 4) target body frame in the ee frame [m]


class VerifiablePlan(Protocol):
    """The fields of a :class:`planner.plan.GraspPlan` that :func:`planner.verify.verifier.verify` reads."""

    scenario: Scenario
    target_state: TargetState
    phases: dict[str, tuple[float, float]]  # phase name → (start, end) [s since the observation]
    t: Array  # (n,) [s since the observation]
    q: Array  # (n, 7) [rad]
    qd: Array  # (n, 7) [rad/s]
    x_base: Array  # (n, 7) [p_world_base [m], quat_world_base]
    phase_index: Array  # (n,) 0 approach, 1 tracking, 2 stabilization
    grasp: HeldTarget
    T_body_grasp_used: Array  # (4, 4) grasp frame in the target body frame, free-axis angle applied
