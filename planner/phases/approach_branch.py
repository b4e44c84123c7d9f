"""The approach's branch: the side of each singular joint angle its end and tracking nodes keep, so that the tracking
IK joins them through no singularity."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.phases.approach import ApproachProblem
from planner.phases.tracking_profile import TRACKING_NODES

Array = NDArray[np.float64]

# the approach's end and the tracking nodes keep this far [rad] on one side of each singular joint angle: the
# tracking IK's rates grow like 1/sin of the distance to it (scenario II: 16× the limit at 0.02 rad)
SINGULARITY_CLEARANCE_RAD = 0.2


def one_side_of_singularities(problem: ApproachProblem, w0: Array, lbw: Array, ubw: Array, lbg: Array,
                              ubg: Array) -> tuple[Array, Array]:
    """Bounds ``(lbw, ubw)`` (copies) and, in place, ``lbg``/``ubg`` that keep the approach's end (its last via
    point's joint row) and every tracking node on the side of each singular joint angle
    (:mod:`planner.model.singular_joints`) where the start ``w0``'s tracking nodes are,
    :data:`SINGULARITY_CLEARANCE_RAD` from it: the tracking IK joins them through no singularity. A joint whose
    start nodes lie on both sides is left free: forcing a side on a start that crosses moves it by more than the
    clearance (scenario I's base-pinned start took 587 iterations instead of 18)."""
    lbw, ubw = lbw.copy(), ubw.copy()
    n = problem.robot.n_joints
    nodes = problem.decision.slice("tracking_nodes").start
    q_end_row = problem.constraints.slice("joint_positions").start + (problem.k - 1) * n
    for s in problem.singular_angles:
        j, angle = s.joint_index, s.angle_rad
        rows = [nodes + node * n + j for node in range(len(TRACKING_NODES))]
        above = w0[rows] >= angle
        if above.any() != above.all():
            continue
        if above.all():
            lbw[rows] = np.maximum(lbw[rows], angle + SINGULARITY_CLEARANCE_RAD)
            lbg[q_end_row + j] = max(lbg[q_end_row + j], angle + SINGULARITY_CLEARANCE_RAD)
        else:
            ubw[rows] = np.minimum(ubw[rows], angle - SINGULARITY_CLEARANCE_RAD)
            ubg[q_end_row + j] = min(ubg[q_end_row + j], angle - SINGULARITY_CLEARANCE_RAD)
    return lbw, ubw
