"""The approach's initial-guess IK (planner.phases.approach_guess) on configurations the tests can check."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from planner.phases.approach_guess import REACH_TOLERANCE, _PoseIK
from planner.robot import fk_function
from planner.rotation import quat_to_matrix
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


def test_reach_bound_holds_for_pinocchio_fk_and_is_nearly_attained(robot):
    """``reach_from_joint1_m`` bounds the end-effector's distance from the first joint's origin for every
    configuration. Oracle: pinocchio's frame placements (base at the origin) at 3000 seeded random
    configurations; the bound is a sum of link lengths, so a stretched arm comes close to it."""
    import pinocchio as pin

    from planner.robot import pin_configuration

    model, data = robot.pin_model, robot.pin_model.createData()
    fid = model.getFrameId(robot.ee_frame)
    rng = np.random.default_rng(3)
    reach = robot.reach_from_joint1_m
    worst = 0.0
    for q in [np.zeros(7), *rng.uniform(robot.q_min, robot.q_max, size=(3000, 7))]:
        pin.framesForwardKinematics(model, data, pin_configuration(np.zeros(3), np.array([1.0, 0, 0, 0]), q))
        worst = max(worst, float(np.linalg.norm(data.oMf[fid].translation - robot.p_base_joint1_m)))
    assert worst <= reach + 1e-12
    assert worst >= 0.9 * reach  # not a vacuous bound: the chain is nearly straight somewhere


def test_out_of_reach_never_rejects_a_reachable_goal_and_rejects_one_beyond_the_arm():
    """Soundness: a goal that some admissible configuration attains (any joints, base offset and drift)
    is never called out of reach, else the scan would silently drop meeting times. A goal just beyond
    the arm's length from the nearest admissible shoulder is rejected."""
    sc = load_scenario(SCENARIO_I)
    ik = _PoseIK(sc)
    fk = fk_function(sc.robot)
    rng = np.random.default_rng(5)
    (bx, bz) = sc.base_offset_bounds_m
    for _ in range(300):
        q = rng.uniform(sc.robot.q_min, sc.robot.q_max)
        b = np.array([rng.uniform(*bx), rng.uniform(*bz)])
        dp = rng.normal(scale=0.05, size=3)
        dR = quat_to_matrix(rng.normal(size=4))
        p_ee = np.array([b[0], 0.0, b[1]]) + dp + dR @ np.asarray(fk(q)[-1]).ravel()
        assert not ik.out_of_reach(p_ee, None, (dp, dR))
        assert not ik.out_of_reach(p_ee, b, (dp, dR))
    # straight up from the highest admissible shoulder, a hair beyond the arm's reach
    shoulder = np.array([bx[1], 0.0, bz[1]]) + sc.robot.p_base_joint1_m
    beyond = shoulder + np.array([0.0, 0.0, sc.robot.reach_from_joint1_m + 2 * REACH_TOLERANCE])
    assert ik.out_of_reach(beyond, None, (np.zeros(3), np.eye(3)))
    assert not ik.out_of_reach(beyond - np.array([0.0, 0.0, 3 * REACH_TOLERANCE]), None, (np.zeros(3), np.eye(3)))
