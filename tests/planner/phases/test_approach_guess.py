"""The approach's initial-guess IK (planner.phases.approach_ik) on configurations the tests can check."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from planner.config.scenario import load_scenario
from planner.model.robot import fk_function
from planner.model.rotation import quat_to_matrix
from planner.phases.approach_ik import REACH_TOLERANCE, PoseIK

SCENARIO_I = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_I.toml"


def test_pose_ik_with_a_pinned_base_reaches_the_pose_and_keeps_the_base_at_its_bound():
    """``base_offset_x_m = [0, 0]`` is a legal config (the base may not move along x); the bounded IK must
    accept equal bounds and return a base offset on them. Oracle: the pose is the FK of a known config."""
    sc = load_scenario(SCENARIO_I)
    sc = replace(sc, base_offset_bounds_m=((0.0, 0.0), (0.0, 0.0)))
    q_goal = sc.q_initial + np.array([0.3, -0.2, 0.25, -0.3, 0.2, 0.3, -0.2])
    out = fk_function(sc.robot)(q_goal)
    R_goal, p_goal = np.asarray(out[-2]), np.asarray(out[-1]).ravel()  # base at the orbital origin, unrotated
    x = PoseIK(sc).solve(p_goal, R_goal, np.eye(3), [np.concatenate([sc.q_initial, [0.0, 0.0]])])
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

    from planner.model.robot import pin_configuration

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
    ik = PoseIK(sc)
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


def test_compiled_levenberg_marquardt_matches_scipy_on_the_scan_ik():
    """The scan's IK runs a projected Levenberg-Marquardt compiled into one CasADi call. Oracle:
    ``scipy.optimize.least_squares`` (trf, bounds, tolerances 1e-12, 2000 evaluations) on the same residual
    from the same start. Starts are 0.1 rad from a seeded reachable configuration, so that both solvers
    descend into the same local minimum of this non-convex problem.

    The regularised solve must match scipy's squared residual to 1e-9 relative at a stationary point of
    the bounded problem. The polish that follows it (weight 2e-3) only weakly holds the redundant arm's
    self-motion, along which the residual changes by ~1e-5 over centimetres of joint angle: 100 steps do not
    always settle that direction to the last digit, so there the test asks what the scan uses the polish
    for — the pose error, compared against REACH_TOLERANCE (1e-3) — to agree with scipy's to 1e-5."""
    from scipy.optimize import least_squares

    from planner.phases.approach_ik import POLISH_REGULARISATION, REGULARISATION, pack_ik_parameters

    sc = load_scenario(SCENARIO_I)
    ik = PoseIK(sc)
    fk = fk_function(sc.robot)
    rng = np.random.default_rng(11)

    def both(x0: np.ndarray, weight: float) -> tuple[np.ndarray, np.ndarray, tuple]:
        # no drift, base free, pulled toward the guess
        args = (p_goal, R_goal, np.eye(3), weight, np.zeros(3), np.eye(3), np.zeros(2), 0.0, sc.base_offset_guess_m)
        x_lm, _ = ik.lm(x0, pack_ik_parameters(*args))
        ref = least_squares(lambda x: np.asarray(ik.fn(x, *args)[0]).ravel(), x0,
                            jac=lambda x: np.asarray(ik.fn(x, *args)[1]), bounds=(ik.lo, ik.hi),
                            xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=2000)
        return np.asarray(x_lm).ravel(), ref.x, args

    for _ in range(6):
        q_goal = rng.uniform(0.6 * sc.robot.q_min, 0.6 * sc.robot.q_max)
        b_goal = rng.uniform(-0.5, 0.5, size=2)
        out = fk(q_goal)
        R_goal, p_goal = np.asarray(out[-2]), np.asarray(out[-1]).ravel() + np.array([b_goal[0], 0.0, b_goal[1]])
        x0 = np.clip(np.concatenate([q_goal, b_goal]) + rng.normal(scale=0.1, size=9), ik.lo, ik.hi)
        x_lm, x_ref, args = both(x0, REGULARISATION)
        r, J = (np.asarray(a).ravel() if i == 0 else np.asarray(a) for i, a in enumerate(ik.fn(x_lm, *args)))
        r_ref = np.asarray(ik.fn(x_ref, *args)[0]).ravel()
        assert abs(r @ r - r_ref @ r_ref) <= 1e-9 * (r_ref @ r_ref)
        grad = J.T @ r
        held = (x_lm <= ik.lo) & (grad > 0) | (x_lm >= ik.hi) & (grad < 0)
        assert np.abs(np.where(held, 0.0, grad)).max() < 1e-8
        x_lm, x_ref, args = both(x_lm, POLISH_REGULARISATION)
        pose_lm, pose_ref = (np.linalg.norm(np.asarray(ik.fn(x, *args)[0]).ravel()[:12]) for x in (x_lm, x_ref))
        assert abs(pose_lm - pose_ref) < 1e-5


def test_shared_pose_ik_is_one_per_problem_and_solves_as_a_fresh_one():
    """``PoseIK.shared`` keeps one IK per robot, θ_in, base-offset guess and bounds: a scenario loaded again gets
    the same object, one with other base bounds (the base-pinned scan) another. The shared IK holds no state
    between solves, so after solving other poses it answers bit for bit as a freshly built IK does; oracle for
    reachability: the goals are the FK of seeded configurations."""
    first, again = load_scenario(SCENARIO_I), load_scenario(SCENARIO_I)
    pinned = replace(first, base_offset_bounds_m=((0.0, 0.0), (0.0, 0.0)))
    shared = PoseIK.shared(first)
    assert PoseIK.shared(again) is shared
    assert PoseIK.shared(pinned) is not shared
    assert np.array_equal(PoseIK.shared(pinned).hi[7:], [0.0, 0.0])
    fresh = PoseIK(first)
    fk = fk_function(first.robot)
    rng = np.random.default_rng(17)
    starts = [np.concatenate([first.q_initial, first.base_offset_guess_m])]
    for _ in range(4):
        out = fk(rng.uniform(0.6 * first.robot.q_min, 0.6 * first.robot.q_max))
        R_goal, p_goal = np.asarray(out[-2]), np.asarray(out[-1]).ravel()
        x_shared = PoseIK.shared(again).solve(p_goal, R_goal, np.eye(3), starts)
        x_fresh = fresh.solve(p_goal, R_goal, np.eye(3), starts)
        assert (x_shared is None) == (x_fresh is None)
        if x_fresh is not None:
            np.testing.assert_array_equal(x_shared, x_fresh)


def test_shared_pose_iks_are_bounded_oldest_first(monkeypatch):
    """At most SHARED_IK_LIMIT IKs are kept; the oldest is dropped first."""
    from planner.phases import approach_ik

    monkeypatch.setattr(PoseIK, "_shared", {})
    monkeypatch.setattr(approach_ik, "SHARED_IK_LIMIT", 2)
    sc = load_scenario(SCENARIO_I)
    variants = [replace(sc, base_offset_bounds_m=((-0.1 * k, 0.1 * k), (-0.1, 0.1))) for k in (1, 2, 3)]
    iks = [PoseIK.shared(v) for v in variants]
    assert len(PoseIK._shared) == 2
    assert PoseIK.shared(variants[2]) is iks[2] and PoseIK.shared(variants[1]) is iks[1]
    assert PoseIK.shared(variants[0]) is not iks[0]  # dropped, built anew


def test_compiled_levenberg_marquardt_loop_equals_the_expanded_one_bit_for_bit(monkeypatch):
    """The scan's IK is a loop over one compiled step; without a compiler it is expanded into one SX Function.
    Both perform the same floating-point operations in the same order: the same answers to the last bit, from
    seeded starts around seeded reachable goals (with drift and a fixed base, too)."""
    from planner.phases.approach_ik import pack_ik_parameters

    sc = load_scenario(SCENARIO_I)
    fast = PoseIK(sc)
    monkeypatch.setenv("LUTGEN_COMPILE", "0")
    expanded = PoseIK(sc)
    assert fast.lm.is_a("External") and not expanded.lm.is_a("External")
    fk = fk_function(sc.robot)
    rng = np.random.default_rng(41)
    for k in range(8):
        out = fk(rng.uniform(0.6 * sc.robot.q_min, 0.6 * sc.robot.q_max))
        drift = (rng.normal(scale=0.02, size=3), quat_to_matrix([1.0, *rng.normal(scale=0.02, size=3)]))
        p = pack_ik_parameters(np.asarray(out[-1]).ravel(), np.asarray(out[-2]), np.eye(3), 0.02, *drift,
                               sc.base_offset_guess_m, float(k % 2), sc.base_offset_guess_m)
        x0 = np.clip(np.concatenate([sc.q_initial, sc.base_offset_guess_m]) + rng.normal(scale=0.3, size=9),
                     fast.lo, fast.hi)
        for a, b in zip(fast.lm(x0, p), expanded.lm(x0, p), strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
