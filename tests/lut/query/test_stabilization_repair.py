"""A table plan that fails only from its grasp on is repaired by re-solving its stabilization warm (issue 21): the
repair keeps the table's approach bit for bit, verifies feasible, and is not attempted when anything before the
grasp failed. Judged by verify (pinocchio, its own distances), not by the NLP that made the repair."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lut.query.stabilization_repair import REPAIR_ITERATIONS, REPAIR_STALL, single_cause, stabilization_only
from lut.query.table_query import TableQuery
from planner.deadline import Deadline
from planner.nlp.outcome import SolveOutcome
from planner.plan_parameters import PlanParameters
from planner.verify.before_grasp import BEFORE_THE_GRASP, failed_before_grasp
from planner.verify.checks import CheckResult

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
T_GRASP = 50.0


def _report(*failed: tuple[str, float | None]) -> SimpleNamespace:
    """A verification report whose only failed checks are ``(name, time of the worst value)``."""
    checks = {"joint_position": CheckResult("joint_position", 0.0, 1.0, 1.0, True, "rad", "", 10.0)}
    for name, t_s in failed:
        checks[name] = CheckResult(name, 2.0, 1.0, -1.0, False, "-", "", t_s)
    return SimpleNamespace(checks=checks, t_grasp_s=T_GRASP)


@pytest.mark.parametrize(("failed", "expected"), [
    ((("grasp_torque", 60.0),), True),
    ((("collision", 70.0), ("end_velocity", 95.0)), True),
    ((("join_velocity_tracking_stabilization", T_GRASP),), True),  # at the grasp instant itself
    ((("grasp_torque", 60.0), ("collision", 30.0)), False),  # a collision in the approach
    ((("joint_velocity", T_GRASP - 1e-3),), False),  # a millisecond before the grasp
    ((("grasp_torque", None),), False),  # no time: cannot tell
    ((), False),  # nothing failed: nothing to repair
    *[(((name, T_GRASP),), False) for name in sorted(BEFORE_THE_GRASP)],
])
def test_only_failures_from_the_grasp_on_are_repairable(failed, expected):
    assert stabilization_only(_report(*failed)) is expected


@pytest.mark.parametrize(("failed", "expected"), [
    ((("grasp_torque", 60.0),), True),  # the braking alone too harsh
    ((("grasp_force", 60.0), ("grasp_torque", 61.0)), True),  # the wrench alone, both of its parts
    ((("joint_position", 70.0), ("joint_velocity", 71.0)), True),  # the arm's path alone
    ((("collision", 70.0),), True),
    ((("grasp_torque", 60.0), ("collision", 70.0)), False),  # both causes at once
    ((("grasp_force", 60.0), ("joint_velocity", 90.0)), False),
    ((("grasp_torque", 60.0), ("joint_position", 30.0)), False),  # a joint limit before the grasp: no repair at all
    ((), False),
])
def test_a_single_cause_is_the_wrench_alone_or_the_path_alone(failed, expected):
    assert single_cause(_report(*failed)) is expected


@pytest.fixture(scope="module")
def opened() -> TableQuery:
    return TableQuery(GOLDEN)


def _braking_too_hard(opened: TableQuery):
    """A golden grid point's state, its plan with the stabilization spline scaled by 0.8 (the grasp torque then
    exceeds its limit after the grasp only) and that plan's verification, and the stored parameters."""
    point = opened.feasible[1]
    state = opened.grid.state_at(opened.grid.coordinates(point))
    stored = opened.points[point].parameters
    harsh = PlanParameters(stored.approach, 0.8 * np.asarray(stored.stabilization_params))
    made, report = opened.simulate_and_verify(state, harsh, {})
    return state, harsh, made, report, stored


def test_a_spline_that_brakes_too_hard_is_re_solved_and_the_approach_kept(opened):
    _, _, made, report, stored = _braking_too_hard(opened)
    assert not report.checks["grasp_torque"].passed and stabilization_only(report)
    assert not failed_before_grasp(report)  # failed, but nothing before the grasp
    fixed = opened.repaired(made, report, Deadline.after(100.0))
    assert fixed is not None
    plan, repaired = fixed
    assert repaired.feasible and "re-solved warm" in plan.notes[-1]
    assert np.array_equal(plan.approach.parameters.params, stored.approach.params)
    assert np.array_equal(plan.approach.parameters.base_offset_m, stored.approach.base_offset_m)


def test_a_repair_reuses_the_verified_plans_approach_and_tracking_and_gives_the_same_plan(opened):
    """The query repairs the plan it has just verified: the repair brakes that plan's grasp (no second simulation of
    the approach and tracking, 0.3 s of a repair's 2-3.5 s) and is bit for bit the re-solve that simulates them
    again."""
    state, harsh, made, report, _ = _braking_too_hard(opened)
    anew = opened.planner.simulate(state, harsh, REPAIR_ITERATIONS, Deadline.after(100.0), REPAIR_STALL)
    reused = opened.repaired(made, report, Deadline.after(100.0))
    assert reused is not None and reused[1].feasible and anew.stabilization.success
    assert reused[0].candidate is made.candidate and anew.candidate is not made.candidate
    for name in ("t", "q", "qd", "x_base"):
        np.testing.assert_array_equal(getattr(reused[0], name), getattr(anew, name))
    np.testing.assert_array_equal(reused[0].stabilization.params, anew.stabilization.params)


def test_only_a_plan_a_planner_assembled_is_restabilized(opened):
    _, _, made, _, _ = _braking_too_hard(opened)
    with pytest.raises(ValueError, match="no grasp candidate"):
        opened.planner.restabilized(replace(made, candidate=None), REPAIR_ITERATIONS)


def test_a_repair_whose_violation_stops_falling_is_given_up_early(opened):
    """A golden point's braking doubled swings the arm past its limits and into the target as well: its repair's
    violation stalls, and it is given up after 5 iterations (the stall rule), where the whole 15 fail as well."""
    point = opened.feasible[1]
    state = opened.grid.state_at(opened.grid.coordinates(point))
    stored = opened.points[point].parameters
    doubled = PlanParameters(stored.approach, 2.0 * np.asarray(stored.stabilization_params))
    made, report = opened.simulate_and_verify(state, doubled, {})
    assert stabilization_only(report) and not single_cause(report)
    given_up = opened.planner.simulate(state, doubled, REPAIR_ITERATIONS, Deadline.after(100.0), REPAIR_STALL)
    assert given_up.stabilization.status == SolveOutcome.STALLED
    assert REPAIR_STALL.after <= given_up.stabilization.iterations < REPAIR_ITERATIONS
    whole = opened.planner.simulate(state, doubled, REPAIR_ITERATIONS, Deadline.after(100.0))
    assert not whole.stabilization.success and whole.stabilization.iterations == REPAIR_ITERATIONS
    assert opened.repaired(made, report, Deadline.after(100.0)) is None


def test_a_plan_that_fails_before_its_grasp_is_not_repaired(opened):
    point = opened.feasible[0]
    state = opened.grid.state_at(opened.grid.coordinates(point))
    stored = opened.points[point].parameters
    # the approach spline's jerk parameters 30 % larger: the joints overspeed 7 s before the grasp
    rushed = PlanParameters(replace(stored.approach, params=1.3 * stored.approach.params), stored.stabilization_params)
    made, report = opened.simulate_and_verify(state, rushed, {})
    velocity = report.checks["joint_velocity"]
    assert not velocity.passed and velocity.t_s < report.t_grasp_s and not stabilization_only(report)
    assert "joint_velocity" in [c.name for c in failed_before_grasp(report)]
    assert opened.repaired(made, report, Deadline.after(100.0)) is None


def test_no_repair_starts_without_the_time_to_finish_it(opened):
    _, _, made, report, _ = _braking_too_hard(opened)
    assert stabilization_only(report)
    assert opened.repaired(made, report, Deadline.after(3.0)) is None
