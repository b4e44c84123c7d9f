"""A scan's shared context (planner.phases.approach_guess._Scan) for one target state, built as the scan builds it but
with no extra IK starts: what the scan tests evaluate its pieces in."""

from __future__ import annotations

import numpy as np

from planner.collision.nlp_scene import build_scene
from planner.config.scenario import Scenario
from planner.model.robot import fk_function
from planner.model.target import TargetState
from planner.phases import approach_guess
from planner.phases.approach_ik import PoseIK
from planner.phases.approach_start import StartClearance


def scan_context(sc: Scenario, state: TargetState) -> approach_guess._Scan:
    """The context of a scan of ``state`` (the grasp frame whole: the full orientation matched)."""
    motion, scene = sc.target.motion(state, approach_guess._horizon_s(sc)), build_scene(sc)
    home = np.concatenate([sc.q_initial, sc.base_offset_guess_m])
    return approach_guess._Scan(sc, motion, fk_function(sc.robot), scene, PoseIK.shared(sc), np.eye(3), home, [], state,
                                StartClearance(sc, scene, motion))
