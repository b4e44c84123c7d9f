"""Whether the tracking IK's motion keeps the contact rule's clearances, on the approach NLP's own distance engine.

The approach NLP holds the tracking's clearances at its tracking nodes only (the last 40 % of the phase, paper Eq. 19);
while the desired pose blends from the pre-grasp onto the moving grasp frame before the first node, the IK moves the
arm where no NLP row looks, and a link can sweep into the target (a scenario II tumble: link 2 12.5 cm into the panel
1.8 s into its tracking). No bound at the nodes holds the IK's own path there, so a grasp whose tracking dips below
its clearance does not hold, and the grasp search tries another (verify would refuse it whatever its braking).
"""

from __future__ import annotations

import numpy as np

from planner.collision.contact_rule import TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import scene_layout
from planner.model.target import TargetMotion
from planner.phases.approach_clearance import ApproachClearance, ClearanceDip
from planner.phases.tracking import TrackingResult


def tracking_dip(clearance: ApproachClearance, tr: TrackingResult, motion: TargetMotion) -> ClearanceDip | None:
    """The deepest dip of ``tr`` below the contact rule's clearance (its time in s from the start of tracking), or
    None when every pair keeps it at every step of the IK."""
    sc = clearance.problem.scenario
    pairs = clearance.problem.scene.pairs
    handle = scene_layout(sc.robot, sc.target).gripper_handle
    into_s = tr.t - tr.t[0]
    required = np.array([required_clearance_m(pairs, handle, sc.limits.collision_margin_m, TRACKING,
                                              closed_backoff_m(sc.approach.pregrasp_backoff_m, t, sc.phases.tracking_s))
                         for t in into_s])
    distances = clearance.distances_at(tr.t, tr.q, tr.x_base, motion)
    depth = distances - required
    i, pair = np.unravel_index(np.argmin(depth), depth.shape)
    if depth[i, pair] >= 0.0:
        return None
    a, b = pairs[pair]
    return ClearanceDip(f"{a}-{b}", float(into_s[i]), float(distances[i, pair]), float(required[i, pair]))
