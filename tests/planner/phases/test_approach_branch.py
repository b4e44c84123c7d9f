"""The approach keeps the tracking on one branch of the arm (planner.phases.approach_solve): its end and the
tracking nodes on one side of every singular joint angle, so the tracking IK never flips the wrist; and a tracking
rate excess tightens only the segment it happened in (planner.plan_grasps)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.config.scenario import load_scenario
from planner.model.target_state import TargetState
from planner.phases.approach_branch import SINGULARITY_CLEARANCE_RAD, one_side_of_singularities
from planner.phases.approach_solve import solve_approach
from planner.phases.tracking_profile import TRACKING_NODES, node_segment
from planner.plan import Planner
from planner.plan_grasps import RATE_DEMAND_TOLERATED

SCENARIO_II = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_II.toml"
# a scenario II tumble whose cold approach put its end at q6 = +0.21 and its tracking nodes at q6 < −0.35: the
# tracking IK crossed q6 = 0 and asked for 16× the joint rate limit there (coverage state, seed 7)
FLIPPING_STATE = TargetState(np.array([0.976457334196, -0.0803263284169, 0.167796967635, 0.109192184293]),
                             np.radians([-0.605482367211, 3.24428377497, 0.0373453746682]))


@pytest.fixture(scope="module")
def planner_II():
    return Planner(load_scenario(SCENARIO_II))


def test_the_bounds_follow_the_start_grasp_nodes_side(planner_II):
    problem = planner_II.approach
    n, nodes = problem.robot.n_joints, problem.decision.slice("tracking_nodes").start
    q_end_row = problem.constraints.slice("joint_positions").start + (problem.k - 1) * n
    for side in (+1.0, -1.0):
        w0 = np.zeros(problem.n_w)
        rows = [nodes + node * n + 5 for node in range(len(TRACKING_NODES))]
        w0[rows] = 0.5 * side  # the tracking nodes' q6
        lbg, ubg = problem.lbg.copy(), problem.ubg.copy()
        lbw, ubw = one_side_of_singularities(problem, w0, problem.lbw, problem.ubw, lbg, ubg)
        bound = lbw if side > 0 else ubw
        g_bound = lbg if side > 0 else ubg
        assert np.all(bound[rows] == side * SINGULARITY_CLEARANCE_RAD)
        assert g_bound[q_end_row + 5] == side * SINGULARITY_CLEARANCE_RAD
        # joints 2 and 4 of the zero start are on the + side; every other bound is the problem's own
        pitch = [nodes + node * n + j for node in range(len(TRACKING_NODES)) for j in (1, 3)]
        assert np.all(lbw[pitch] == SINGULARITY_CLEARANCE_RAD)
        kept = np.setdiff1d(np.arange(problem.n_w), rows + pitch)
        assert np.array_equal(lbw[kept], problem.lbw[kept]) and np.array_equal(ubw[kept], problem.ubw[kept])
    assert np.array_equal(problem.lbw, planner_II.approach.lbw)  # the problem's own bounds untouched


@pytest.mark.parametrize("crossing", [(-0.04, 0.26, 0.506), (0.3, 0.0, -1e-9), (-0.5, -0.2, 0.0)])
def test_a_start_whose_nodes_cross_leaves_that_joint_free(planner_II, crossing):
    problem = planner_II.approach
    n, nodes = problem.robot.n_joints, problem.decision.slice("tracking_nodes").start
    q_end_row = problem.constraints.slice("joint_positions").start + (problem.k - 1) * n
    w0 = np.full(problem.n_w, 0.7)
    rows = [nodes + node * n + 5 for node in range(len(TRACKING_NODES))]
    w0[rows] = crossing  # scenario I's base-pinned start (first case) crosses q6 = 0 between its nodes
    lbg, ubg = problem.lbg.copy(), problem.ubg.copy()
    lbw, ubw = one_side_of_singularities(problem, w0, problem.lbw, problem.ubw, lbg, ubg)
    assert np.array_equal(lbw[rows], problem.lbw[rows]) and np.array_equal(ubw[rows], problem.ubw[rows])
    assert lbg[q_end_row + 5] == problem.lbg[q_end_row + 5] and ubg[q_end_row + 5] == problem.ubg[q_end_row + 5]
    pitch = [nodes + node * n + j for node in range(len(TRACKING_NODES)) for j in (1, 3)]
    assert np.all(lbw[pitch] == SINGULARITY_CLEARANCE_RAD)  # the other joints' nodes, all at 0.7, are still held


def test_a_cold_approach_keeps_the_tracking_on_one_branch(planner_II):
    app = solve_approach(planner_II.approach, FLIPPING_STATE)
    assert app.success
    _, tr = planner_II.approach_and_tracking(app, planner_II.motion(FLIPPING_STATE))
    for s in planner_II.approach.singular_angles:
        signs = np.sign(tr.q[:, s.joint_index] - s.angle_rad)
        assert np.all(signs == signs[0]), f"joint {s.joint_index + 1} crossed its singular angle in tracking"
    # was 16.1× the limit with the crossing; what is left is the blend's pace (1.4×), which the planner's re-solve of
    # that tracking segment with tighter rate bounds takes down
    assert tr.peak_rate_demand < 2 * RATE_DEMAND_TOLERATED


@pytest.mark.parametrize(("t_s", "segment"), [(0.0, 0), (3.0, 0), (3.0 + 1e-9, 1), (4.0, 1), (4.5, 2), (5.0, 2),
                                              (6.0, 2)])
def test_node_segment_of_a_phase_time(t_s, segment):
    assert TRACKING_NODES == (0.6, 0.8, 1.0)
    assert node_segment(t_s, 5.0) == segment


def test_a_rate_excess_tightens_only_its_own_tracking_segment(planner_II, monkeypatch):
    from dataclasses import replace as dc_replace

    import planner.plan_grasps as plan_grasps_module
    from planner.phases.approach_guess import ScanOnDemand
    from planner.plan_grasps import TIGHTENING_MARGIN, GraspSearch

    state = FLIPPING_STATE
    app = solve_approach(planner_II.approach, state)
    scales = []

    iteration_caps = []

    def solve(problem, state_, warm, tracking_speed_scale, **options):
        scales.append(np.array(tracking_speed_scale, dtype=float))
        iteration_caps.append(options.get("max_iterations"))
        return app

    real = planner_II.approach_and_tracking
    demands = iter([(2.0, 1.0), (1.0, 0.0)])  # 2× the limit 1 s into tracking (the blend), then within the limits

    def tracked(app_, motion):
        samples, tr = real(app_, motion)
        peak, at = next(demands)
        return samples, dc_replace(tr, peak_rate_demand=peak, peak_demand_time_s=at)

    monkeypatch.setattr(plan_grasps_module, "solve_approach", solve)
    monkeypatch.setattr(planner_II, "approach_and_tracking", tracked)
    scan = ScanOnDemand(planner_II.scenario, planner_II.approach.spline, state, 3)
    search = GraspSearch(planner_II, state, None, scan, planner_II.motion(state), resolve_iterations=150)
    search._candidate(app)
    assert len(scales) == 1  # one re-solve, with the first segment's bounds only scaled
    assert np.allclose(scales[0], [TIGHTENING_MARGIN / 2.0, 1.0, 1.0])
    assert "tracking segment 1" in search.notes[0]
    assert iteration_caps == [150]  # a costed plan's feasibility stage caps it (planner.plan_costed)


def test_a_start_delay_just_outside_the_window_is_read_inside_it(planner_II):
    # IPOPT relaxes bounds by 1e-8: a scenario II flat spin's iterate ended at τ = −9.9e-9 s, and verify refused to
    # propagate the target to a time before the observation (a traceback, exit 1)
    from planner.phases.approach_solve import _within_window

    window = planner_II.scenario.phases.max_start_delay_s
    assert _within_window(planner_II.approach, -9.859211127463265e-09) == 0.0
    assert _within_window(planner_II.approach, window + 1e-8) == window
    assert _within_window(planner_II.approach, 12.5) == 12.5


def test_an_approach_with_the_distance_slack_solves_on_one_branch():
    # Eq. 15 adds a slack variable after w; the branch bounds were clipped against w with the slack appended (a
    # ValueError at every solve of a *_safety scenario)
    from planner.phases.approach import ApproachProblem

    sc = load_scenario(SCENARIO_II.with_name("scenario_I_safety.toml"))
    problem = ApproachProblem(sc)
    assert problem.n_extra == 1
    out = solve_approach(problem, sc.target_state.as_state(), max_iterations=2)
    assert out.status == "Iteration_Budget_Exhausted" and out.iterations in (2, 3)


@pytest.mark.parametrize(("guess_s", "avoid", "expected"), [
    (30.0, (), (27.0, 33.0)),  # the box alone
    (30.0, (27.5,), (29.5, 33.0)),  # a grasp tried below: kept 2 s above it
    (30.0, (32.0,), (27.0, 30.0)),  # above, exactly 2 s away: the box ends at the guess
    (30.0, (31.999,), None),  # closer than 2 s: this guess is the grasp already tried
    (30.0, (30.0,), None),  # the same meeting time
    (1.0, (), (0.0, 4.0)),  # at the window's start
    (89.0, (), (86.0, 90.0)),  # at its end
    (30.0, (26.0, 34.0), (28.0, 32.0)),  # one tried on each side
])
def test_a_retrys_meeting_time_box(planner_II, guess_s, avoid, expected):
    from planner.phases.approach_solve import _meeting_time_box

    problem = planner_II.approach
    delay = problem.decision.slice("start_delay_s").start
    w0 = np.zeros(problem.n_w)
    w0[delay] = guess_s
    lbw, ubw = _meeting_time_box(problem, w0, 3.0, avoid)
    if expected is None:
        assert lbw is None and ubw is None
    else:
        assert (lbw[delay], ubw[delay]) == pytest.approx(expected)
        others = np.arange(problem.n_w) != delay
        assert np.array_equal(lbw[:problem.n_w][others], problem.lbw[:problem.n_w][others])
    assert _meeting_time_box(problem, w0, None, avoid) == (problem.lbw, problem.ubw)  # no box: the problem's own
