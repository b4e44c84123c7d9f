"""A re-plan's solve plans against the re-plan's budget in its child process, as a query's refine does: at a tiny
budget it returns a verified answer or the previous plan, on time, never a killed solve (or a hang)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from lut.output.plan_replay import replay_inputs
from lut.query.pinned_solve import PINNED_SOLVER
from lut.solve.point_process import run_point
from lut.table.point_result import PointStatus
from tests.support.cli import ROOT, replay_plan_for_current_model

SINCE_S = 8.0  # the newer estimate's age after the previous one [s] (before the previous approach starts)


@pytest.fixture(scope="module")
def changed():
    """Scenario II's default plan and a newer estimate 0.3° and 0.01 °/s off its propagated state, at which the
    previous plan (shifted) is infeasible: a re-plan has to solve."""
    from planner.config.scenario import load_scenario
    from planner.model.rotation import matrix_to_quat, quat_multiply
    from planner.model.target import TargetState

    doc = replay_plan_for_current_model()
    inputs = replay_inputs(doc, "plan")
    scenario = load_scenario(ROOT / inputs.scenario_file)
    motion = scenario.target.motion(inputs.state, SINCE_S + 1.0)
    q = matrix_to_quat(motion.body_pose(np.array([SINCE_S]))[0][0])
    omega = motion.trajectory.raw_state(np.array([SINCE_S]))[1][0]
    a = np.radians(0.3)
    state = TargetState(quat_multiply(q, [np.cos(a / 2), np.sin(a / 2), 0.0, 0.0]),
                        omega + np.radians([0.0, 0.0, 0.01]))
    return scenario, inputs.parameters, state


def test_a_pinned_solve_past_its_deadline_returns_a_verified_plan_not_a_timeout(changed):
    scenario, previous, state = changed
    # the child's plan must end at its launch: its deadline (less the verification's reserve) has passed at once
    result = run_point(PINNED_SOLVER, str(scenario.source), -1, state, previous, -SINCE_S, timeout_s=120.0,
                       plan_budget_s=0.0)
    assert result.status in (PointStatus.FEASIBLE, PointStatus.INFEASIBLE), result.failure_reason
    assert result.parameters is not None
    assert np.array_equal(result.parameters.approach.base_offset_m, previous.approach.base_offset_m)  # pinned
    assert result.iterations <= 2  # the approach stopped at its first callback; no stabilization NLP solved


def test_a_re_plan_without_time_to_solve_returns_the_previous_plan(changed):
    from lut.query.replan import FINISH_RESERVE_S, MIN_SOLVE_S, replan

    scenario, previous, state = changed
    # the Planner build and the shifted plan's verification take the last of the budget's MIN_SOLVE_S
    result = replan(scenario, previous, state, SINCE_S, FINISH_RESERVE_S + MIN_SOLVE_S)
    assert result.source == "previous plan" and not result.report.feasible
    assert "no time left to re-solve" in result.solve_failure
    assert result.start_shift_s == 0.0


@pytest.mark.slow
def test_a_re_plan_with_a_tiny_budget_returns_on_time_with_a_verified_answer(changed):
    from lut.query.replan import replan

    scenario, previous, state = changed
    budget_s = 40.0  # room for the child's start, its cut-short plan and verification; far from a full re-solve
    t0 = time.perf_counter()
    result = replan(scenario, previous, state, SINCE_S, budget_s)
    wall_s = time.perf_counter() - t0
    assert result.source in ("previous plan", "re-solved")
    # the child's plan ended at its deadline and was verified: not killed at the budget with nothing
    assert "timeout" not in result.solve_failure, result.solve_failure
    assert result.source == "re-solved" or result.solve_failure
    # a hang guard (the re-simulation and verification after the budget), not a speed target
    assert wall_s < budget_s + 15.0
