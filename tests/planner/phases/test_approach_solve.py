"""The approach NLP's two starts (planner.phases.approach_solve): cold from scanned guesses, warm from a solution."""

from __future__ import annotations

from pathlib import Path

import pytest

import planner.phases.approach_guess as approach_guess_module
from planner.config.scenario import load_scenario
from planner.phases.approach import ApproachProblem
from planner.phases.approach_solve import solve_approach

SCENARIO_II = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_II.toml"


@pytest.fixture(scope="module")
def scenario_and_problem():
    sc = load_scenario(SCENARIO_II)
    return sc, ApproachProblem(sc)


def test_warm_start_at_a_solution_succeeds_without_the_guess_scan(scenario_and_problem, monkeypatch):
    """Cold solves (scanned guesses, restoration-phase start) and warm solves (normal phase) take different
    paths through solve_approach. Oracle: a warm start at the cold solve's own solution is
    feasible, so it must succeed by itself, without falling back to the guess scan (made to raise)."""
    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    cold = solve_approach(problem, state)
    assert cold.success, cold.status

    def no_scan(*args, **kwargs):
        raise AssertionError("the warm start failed and the solve fell back to scanned guesses")

    monkeypatch.setattr(approach_guess_module, "reach_scan", no_scan)
    warm = solve_approach(problem, state, warm_start=cold)
    assert warm.success, warm.status
    # a pure feasibility solve: IPOPT's barrier recentres the start inside the feasible set, so the answer
    # is near, not equal to, the start (measured: meeting time 0.04 s later)
    assert abs(warm.start_delay_s - cold.start_delay_s) < 1.0
    assert warm.min_distance_m >= sc.limits.collision_margin_m


def test_an_iteration_budget_ends_the_solve_and_is_shared_by_the_starts(scenario_and_problem):
    """The planner's retries give the approach an iteration budget: it stops IPOPT once that many iterations
    are spent over all starts, and the solve is reported failed with its own status; without a budget the
    same solve runs as before, to the same answer (the callback only counts)."""
    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    free = solve_approach(problem, state)
    assert free.success and free.iterations > 4
    budgeted = solve_approach(problem, state, max_iterations=4)
    assert not budgeted.success and budgeted.status == "Iteration_Budget_Exhausted"
    # spent on the first start, so no other start is tried; a cold (restoration-phase) start calls back once
    # more than its iteration count
    assert budgeted.start_guess == 0 and budgeted.iterations in (3, 4)
    again = solve_approach(problem, state)
    assert again.success and again.iterations == free.iterations
    assert (again.params == free.params).all()
