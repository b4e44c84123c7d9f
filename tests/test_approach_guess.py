"""The approach's initial-guess IK (planner.phases.approach_guess) on configurations the tests can check."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from planner.phases.approach_guess import REACH_TOLERANCE, _PoseIK
from planner.robot import fk_function
from planner.scenario import load_scenario

SCENARIO_I = Path(__file__).resolve().parents[1] / "configs" / "scenarios" / "scenario_I.toml"


def test_pose_ik_with_a_pinned_base_reaches_the_pose_and_keeps_the_base_at_its_bound():
    """``base_offset_x_m = [0, 0]`` is a legal config (the base may not move along x); the bounded IK must
    accept equal bounds and return a base offset on them. Oracle: the pose is the FK of a known config."""
    sc = load_scenario(SCENARIO_I)
    sc = replace(sc, base_offset_bounds_m=((0.0, 0.0), (0.0, 0.0)))
    q_goal = sc.q_initial + np.array([0.3, -0.2, 0.25, -0.3, 0.2, 0.3, -0.2])
    out = fk_function(sc.robot)(q_goal)
    R_goal, p_goal = np.asarray(out[-2]), np.asarray(out[-1]).ravel()  # base at the orbital origin, unrotated
    x = _PoseIK(sc).solve(p_goal, R_goal, np.eye(3), [np.concatenate([sc.q_initial, [0.0, 0.0]])])
    assert x is not None
    assert np.abs(x[7:]).max() <= 1e-12
    out_x = fk_function(sc.robot)(x[:7])
    # a regularised IK for an NLP start: it must reach the pose to the module's reachability tolerance
    assert np.linalg.norm(np.asarray(out_x[-1]).ravel() - p_goal) < REACH_TOLERANCE
    assert np.linalg.norm(np.asarray(out_x[-2]) - R_goal) < REACH_TOLERANCE
