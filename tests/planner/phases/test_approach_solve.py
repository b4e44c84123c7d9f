"""The approach NLP's two starts (planner.phases.approach_solve): cold from scanned guesses, warm from a solution."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import planner.phases.approach_guess as approach_guess_module
from planner.config.scenario import load_scenario
from planner.model.target import TargetState
from planner.nlp.outcome import SolveOutcome
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


def test_a_meeting_time_box_keeps_each_scanned_start_near_its_guess(scenario_and_problem):
    """The grasp search's retries box the start delay around their guess's (planner.plan_grasps): the solve from
    each of the next guesses ends within the box of that guess, so the retries reach grasps of their own."""
    from planner.phases.approach_guess import angles_apart, initial_guesses

    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    guesses = initial_guesses(sc, problem.spline, state, 3)
    solved = [solve_approach(problem, state, max_starts=3, skip_guesses=skip, meeting_time_box_s=3.0)
              for skip in (1, 2)]
    assert all(s.success for s in solved)
    for boxed in solved:
        assert abs(boxed.start_delay_s - guesses[boxed.start_guess].start_delay_s) <= 3.0 + 1e-9
    # the boxes of guesses at about one angle about the boom do not overlap
    for i, a in enumerate(guesses):
        for b in guesses[i + 1:]:
            assert abs(a.start_delay_s - b.start_delay_s) >= 6.0 or angles_apart(a.free_axis_angle_rad,
                                                                                 b.free_axis_angle_rad)


def test_a_cold_start_past_its_iterations_gives_way_to_the_next_guess(scenario_and_problem, monkeypatch):
    """Each start from a scanned guess gets COLD_START_ITERATIONS; past them the next guess is tried (a plan's whole
    budget is not spent on one start), and the plan's own budget still ends everything at once."""
    import planner.phases.approach_solve as approach_solve_module

    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    monkeypatch.setattr(approach_solve_module, "COLD_START_ITERATIONS", 2)
    capped = solve_approach(problem, state, max_starts=3)
    assert not capped.success and capped.status == "Iteration_Budget_Exhausted"
    assert capped.start_guess == 2  # every guess was tried
    assert 6 <= capped.iterations <= 9  # 2 each (a restoration-phase start calls back once more)
    monkeypatch.setattr(approach_solve_module, "COLD_START_ITERATIONS", 150)
    assert solve_approach(problem, state, max_starts=3).success


def test_each_scanned_guess_after_the_skipped_is_tried_once_when_fewer_remain_than_starts(scenario_and_problem,
                                                                                       monkeypatch):
    """A retry from the scan's last guesses asks for more starts than remain (scenario II's scan holds more guesses
    than a retry's ``max_starts``): each remaining guess is tried once, in order, and the solve ends there. Before,
    the guesses were appended again once the list ran out, and the angle of a guess past the end was read (an
    IndexError that ended a coverage plan with exit 70)."""
    import planner.phases.approach_solve as approach_solve_module
    from planner.phases.approach_guess import ScanOnDemand

    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    scan = ScanOnDemand(sc, problem.spline, state, 5)
    guesses = scan.result.guesses
    assert len(guesses) > 5  # the held angles' guesses come after the scan's own five
    tried: list[float] = []
    real = approach_solve_module._solve_once

    def recorded(problem, state, w0, *args, **kwargs):
        tried.append(float(w0[problem.decision.slice("start_delay_s")][0]))
        return real(problem, state, w0, *args, **kwargs)

    monkeypatch.setattr(approach_solve_module, "_solve_once", recorded)
    monkeypatch.setattr(approach_solve_module, "COLD_START_ITERATIONS", 1)  # every start fails at once
    skip = len(guesses) - 2
    failed = solve_approach(problem, state, max_starts=5, skip_guesses=skip, scan=scan)
    assert not failed.success
    assert tried == [g.start_delay_s for g in guesses[skip:]]
    assert failed.start_guess == len(guesses) - 1


def test_an_approach_from_a_base_offset_starts_from_at_most_its_max_starts(scenario_and_problem, monkeypatch):
    """The chaser waiting elsewhere starts from ``max_starts`` scanned guesses and no more, even when every start fails
    at once (before, every guess of the scan was tried: with the held angles, up to four more)."""
    import numpy as np

    import planner.phases.approach_solve as approach_solve_module
    from planner.phases.approach_solve import solve_approach_from_base

    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    starts = []
    real = approach_solve_module._solve_once
    monkeypatch.setattr(approach_solve_module, "_solve_once", lambda *a, **k: starts.append(a[2]) or real(*a, **k))
    monkeypatch.setattr(approach_solve_module, "COLD_START_ITERATIONS", 1)  # every start fails at once
    for max_starts in (1, 2):
        starts.clear()
        failed = solve_approach_from_base(problem, state, np.array([0.0, 0.0]), max_starts, 1.0, max_iterations=100)
        assert not failed.success and len(starts) == max_starts


def test_an_energy_solve_s_base_pinned_starts_share_its_iteration_budget():
    """A cold Eq. 16 solve pins the base first; those starts are part of the solve's iteration budget, each within
    PINNED_START_ITERATIONS (before, each ran to the scenario's max_iter: scenario II's states spent 17-52 s
    there with a 150-iteration budget). Oracle: the iteration caps every IPOPT run was armed with and the iterations
    they report, with the base's bounds telling pinned starts from free ones."""
    import numpy as np

    import planner.phases.approach_solve as approach_solve_module
    from planner.phases.approach_solve import PINNED_START_ITERATIONS

    sc = load_scenario(SCENARIO_II.with_name("scenario_II_energy.toml"))
    problem = ApproachProblem(sc)
    base = problem.decision.slice("base_offset_m")
    runs = []
    real = approach_solve_module._solve_once

    def record(prob, state, w0, scale, lbw, ubw, **kwargs):
        out = real(prob, state, w0, scale, lbw, ubw, **kwargs)
        runs.append((bool(np.all(lbw[base] == ubw[base])), kwargs.get("max_iterations"), out.iterations))
        return out

    budget = 60
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(approach_solve_module, "_solve_once", record)
        out = solve_approach(problem, sc.target_state.as_state(), max_iterations=budget)
    pinned = [r for r in runs if r[0]]
    assert pinned, "an Eq. 16 cold solve starts with the base pinned"
    assert all(cap is not None and cap <= PINNED_START_ITERATIONS for _, cap, _ in pinned)
    # a cold (restoration-phase) start calls back once more than its iteration count
    assert sum(its for *_, its in runs) <= budget + len(runs)
    assert out.iterations <= budget + len(runs)


@pytest.mark.parametrize(("starts", "budget", "caps"), [(3, None, [40, 40, 40]), (3, 150, [40, 40, 40]),
                                                        (3, 60, [40, 20]), (3, 30, [30]), (1, None, [40]),
                                                        (1, 30, [30]), (2, None, [40, 40]), (2, 150, [40, 40]),
                                                        (2, 40, [40])])
def test_each_pinned_start_gets_at_most_its_cap_and_what_is_left(scenario_and_problem, starts, budget, caps,
                                                                  monkeypatch):
    """Every base-pinned start fails at its cap (a stand-in IPOPT run that spends all it is given): each gets
    min(PINNED_START_ITERATIONS, what the solve's budget leaves), no start follows a spent budget, and without a
    budget (a table point's warm plan) each still gets the cap, not the scenario's max_iter; PINNED_STARTS of them."""
    from dataclasses import replace

    import planner.phases.approach_solve as approach_solve_module
    from planner.nlp.outcome import SolveOutcome
    from planner.phases.approach_solve import _solve_base_pinned

    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    armed = []
    failed = approach_solve_module._no_start(problem, SolveOutcome.ITERATION_BUDGET_EXHAUSTED, (0.0, 0.0), 0.0)

    def spend_all(prob, st, w0, scale, lbw, ubw, max_iterations=None, **kwargs):
        armed.append(max_iterations)
        return replace(failed, iterations=sc.solver.max_iter if max_iterations is None else max_iterations)

    monkeypatch.setattr(approach_solve_module, "_solve_once", spend_all)
    monkeypatch.setattr(approach_solve_module, "PINNED_STARTS", starts)
    out = _solve_base_pinned(problem, state, 1.0, approach_solve_module.NO_DEADLINE, budget)
    assert armed == caps and out.iterations == sum(caps) and not out.success


def test_a_cold_energy_solve_whose_pinned_start_fails_ends_there_and_a_warm_one_goes_on(scenario_and_problem,
                                                                                      monkeypatch):
    """Eq. 16's optimum is sought with the base pinned at its guess first; where no pinned start converges, a cold solve
    ends failed (no free start: those reach only the local minima the pin avoids), with the pinned solve's status and
    iterations; a warm solve (a table point's neighbour) goes on from its warm start. Stand-in IPOPT runs that fail
    pinned and succeed free, the base's bounds telling them apart."""
    from dataclasses import replace

    import numpy as np

    import planner.phases.approach_solve as approach_solve_module
    from planner.nlp.outcome import SolveOutcome

    sc, problem = scenario_and_problem
    sc = replace(sc, costs=replace(sc.costs, approach_energy=1.0))
    monkeypatch.setattr(problem, "scenario", sc)  # only the solve's choice of starts reads the weights
    base = problem.decision.slice("base_offset_m")
    runs = []
    failed = approach_solve_module._no_start(problem, SolveOutcome.ITERATION_BUDGET_EXHAUSTED, (0.0, 0.0), 0.0)

    def stand_in(prob, st, w0, scale, lbw, ubw, max_iterations=None, **kwargs):
        pinned = bool(np.all(lbw[base] == ubw[base]))
        runs.append(pinned)
        return replace(failed, iterations=7) if pinned else replace(failed, success=True, status="stand-in ok",
                                                                    iterations=3)

    monkeypatch.setattr(approach_solve_module, "_solve_once", stand_in)
    n = approach_solve_module.PINNED_STARTS
    cold = solve_approach(problem, sc.target_state.as_state(), max_iterations=150)
    assert runs == [True] * n and not cold.success and cold.iterations == 7 * n
    assert cold.status == SolveOutcome.ITERATION_BUDGET_EXHAUSTED
    runs.clear()
    warm = solve_approach(problem, sc.target_state.as_state(), warm_start=failed, max_iterations=150)
    assert runs == [True] * n + [False] and warm.success and warm.iterations == 7 * n + 3


@pytest.mark.parametrize(("reached", "status"), [(False, "NO_PINNED_START"), (True, "NO_GUESS_IN_TIME")])
def test_a_cold_energy_solve_with_no_pinned_start_ends_with_why(scenario_and_problem, monkeypatch, reached, status):
    """The degenerate pinned solve: no meeting time reachable from the base-offset guess (or none still in time for a
    live plan) is no optimum near the guess either; the cold solve ends with that status and makes no IPOPT run."""
    from dataclasses import replace

    import planner.phases.approach_solve as approach_solve_module
    from planner.nlp.outcome import SolveOutcome

    sc, problem = scenario_and_problem
    monkeypatch.setattr(problem, "scenario", replace(sc, costs=replace(sc.costs, approach_energy=1.0)))
    monkeypatch.setattr(approach_solve_module, "_guesses_in_time", lambda *args: ([], reached))
    monkeypatch.setattr(approach_solve_module, "_solve_once", lambda *a, **k: pytest.fail("no IPOPT run expected"))
    out = solve_approach(problem, sc.target_state.as_state(), max_iterations=150)
    assert not out.success and out.iterations == 0 and out.status == SolveOutcome[status]


# a scenario II general tumble of the coverage section (seed 7, state 4) whose scanned guesses all fail: from the first,
# IPOPT ran 146 iterations without coming within 1e-3 of feasible (its least violation 3.8)
HOPELESS_TUMBLE = TargetState(
    np.array([0.7004236691691397, 0.013938905346571063, -0.3862406615163186, -0.6000254511075473]),
    np.array([0.02642250431756234, 0.022405708107250868, -0.005016584340367115]))


def test_a_cold_feasibility_start_that_stalls_is_given_up_where_unarmed_it_runs_to_its_cap(scenario_and_problem,
                                                                                          monkeypatch):
    """APPROACH_STALL ends a start from a scanned guess whose least violation has stopped halving, far above the
    floor, and only such a start: unarmed, the same start spends its COLD_START_ITERATIONS and fails all the same."""
    import planner.phases.approach_solve as approach_solve_module

    _, problem = scenario_and_problem
    stalled = solve_approach(problem, HOPELESS_TUMBLE, max_starts=1)
    assert not stalled.success and stalled.status == SolveOutcome.STALLED and stalled.start_guess == 0
    rule, violations = approach_solve_module.APPROACH_STALL, problem.budget._violations
    # the rule counts the callbacks (iteration 0 and a restoration phase's own calls included), IPOPT its iterations
    assert max(rule.after, rule.over) <= len(violations) - 1 < approach_solve_module.COLD_START_ITERATIONS
    assert stalled.iterations < len(violations)
    assert min(violations) > 100 * rule.floor and rule.holds(violations)
    assert not rule.holds(violations[:-1])  # ended at the first iteration it held, not later
    monkeypatch.setattr(approach_solve_module, "APPROACH_STALL", None)
    unarmed = solve_approach(problem, HOPELESS_TUMBLE, max_starts=1)
    assert not unarmed.success and unarmed.status == SolveOutcome.ITERATION_BUDGET_EXHAUSTED
    assert len(problem.budget._violations) - 1 == approach_solve_module.COLD_START_ITERATIONS  # its whole cap
    assert min(problem.budget._violations) > rule.floor  # 120 more iterations never came near feasible either


def test_a_start_that_converges_is_the_same_with_the_stall_rule_armed_or_not(scenario_and_problem, monkeypatch):
    import planner.phases.approach_solve as approach_solve_module

    sc, problem = scenario_and_problem
    state = sc.target_state.as_state()
    armed = solve_approach(problem, state)
    monkeypatch.setattr(approach_solve_module, "APPROACH_STALL", None)
    unarmed = solve_approach(problem, state)
    assert armed.success and armed.iterations == unarmed.iterations
    np.testing.assert_array_equal(armed.params, unarmed.params)


@pytest.mark.parametrize(("cold", "costed", "armed"), [(True, False, True), (False, False, False),
                                                       (True, True, False), (False, True, False)])
def test_only_a_cold_start_of_a_feasibility_approach_is_armed_with_the_stall_rule(cold, costed, armed):
    """A costed approach's violation is not its only progress (it may leave the feasible set to lower its cost), and a
    warm start has no next guess to give way to."""
    from types import SimpleNamespace

    import planner.phases.approach_solve as approach_solve_module

    problem = SimpleNamespace(scenario=SimpleNamespace(costs=SimpleNamespace(weights_approach=costed)))
    rule = approach_solve_module._stall_rule(problem, cold)
    assert (rule is approach_solve_module.APPROACH_STALL) if armed else rule is None
