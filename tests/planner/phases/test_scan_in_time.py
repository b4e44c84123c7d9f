"""A live plan's stage that comes late scans the meeting times still in time (planner.phases.scan_in_time): the window
from the earliest start, a scan made again only when none of its guesses meets in time, the base-offset scans, and a
grasp search handed a scan whose every guess is too early finding an approach that starts after its answer."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import planner.phases.approach_guess as approach_guess
import planner.phases.approach_solve as approach_solve
from planner.config.scenario import load_scenario
from planner.deadline import START_LEAD_S, Deadline
from planner.nlp.outcome import SolveOutcome
from planner.phases.approach import approach_spline
from planner.phases.approach_guess import ScanOnDemand
from planner.phases.reach_scan_result import DELAY_STEP_S, ApproachGuess, ReachScan
from planner.phases.scan_in_time import meets_in_time, scan_in_time, window_in_time
from planner.phases.tracking_profile import TRACKING_NODES
from planner.plan import Planner
from planner.plan_grasps import GraspSearch
from tests.support.cli import ROOT

SINCE_S = 13.0  # the observation was this long ago: the earliest start is ~18 s, the rescan's window opens at ~20 s


@pytest.fixture(scope="module")
def scenario_I():
    return load_scenario(ROOT / "configs" / "scenarios" / "scenario_I.toml")


def _live(since_s: float) -> Deadline:
    observed = time.monotonic() - since_s
    return Deadline.after(100.0, observed).observed(observed)


def _stale_scan(sc, state, tau_s: float = 5.0) -> ScanOnDemand:
    """A scan made at the plan's start whose one guess meets at ``tau_s``."""
    scan = ScanOnDemand(sc, approach_spline(sc), state, 3)
    guess = ApproachGuess(np.zeros(1), np.zeros(2), tau_s, np.zeros(7), np.zeros((3, 7)), 0.1)
    scan._result = ReachScan([guess], sc.phases.start_delay_window_s, ())
    return scan


def test_a_guess_is_in_time_up_to_one_scan_step_before_the_earliest_start():
    deadline = _live(10.0)
    floor = deadline.earliest_start_s()
    assert meets_in_time(floor - DELAY_STEP_S + 0.05, deadline) and not meets_in_time(floor - DELAY_STEP_S - 0.05,
                                                                                      deadline)
    assert meets_in_time(-1e9, Deadline.after(100.0))  # no observation: every guess


def test_the_window_opens_a_scan_step_after_the_earliest_start(scenario_I):
    sc = scenario_I
    assert window_in_time(sc, Deadline.after(100.0)) is sc  # no observation
    later = window_in_time(sc, _live(SINCE_S))
    opens = SINCE_S + START_LEAD_S + DELAY_STEP_S
    assert opens <= later.phases.min_start_delay_s < opens + DELAY_STEP_S + 1.0
    assert later.phases.min_start_delay_s % DELAY_STEP_S == 0.0  # on the whole window's grid of meeting times
    assert later.phases.max_start_delay_s == sc.phases.max_start_delay_s
    assert window_in_time(sc, _live(sc.phases.max_start_delay_s)) is sc  # it would close: kept (judged late)
    own = replace(sc, phases=replace(sc.phases, min_start_delay_s=60.0))
    assert window_in_time(own, _live(SINCE_S)) is own  # the scenario's own window starts later still


def _earliest_at(earliest_s: float) -> SimpleNamespace:
    """A deadline whose earliest start is ``earliest_s`` exactly (the clock left out: the edges are exact)."""
    return SimpleNamespace(earliest_start_s=lambda: earliest_s)


@pytest.mark.parametrize(("earliest_s", "opens_s"), [
    (18.0, 20.0),  # one step after lands on the grid: there
    (18.0 + 1e-9, 22.0),  # a hair past it: the next meeting time of the grid
    (-DELAY_STEP_S, None),  # one step after is the window's own start: unchanged
    (-math.inf, None),  # no observation
    (88.0, 90.0),  # one step after is the latest start: a window of one meeting time
    (88.0 + 1e-9, None),  # past it: the window would close, unchanged (the plan is judged late)
])
def test_the_windows_edges(scenario_I, earliest_s, opens_s):
    later = window_in_time(scenario_I, _earliest_at(earliest_s))
    if opens_s is None:
        assert later is scenario_I
    else:
        assert later.phases.start_delay_window_s == (opens_s, scenario_I.phases.max_start_delay_s)


def test_a_guess_exactly_one_scan_step_before_the_earliest_start_is_in_time():
    assert meets_in_time(18.0, _earliest_at(20.0)) and not meets_in_time(18.0 - 1e-9, _earliest_at(20.0))


def test_a_scan_is_made_again_only_when_none_of_its_guesses_is_in_time(scenario_I):
    sc, state = scenario_I, scenario_I.target_state.as_state()
    fresh = ScanOnDemand(sc, approach_spline(sc), state, 3)
    assert scan_in_time(fresh, _live(60.0)) is fresh and not fresh.made  # not made: nothing is scanned to judge it
    in_time = _stale_scan(sc, state, tau_s=40.0)
    assert scan_in_time(in_time, _live(SINCE_S)) is in_time
    stale = _stale_scan(sc, state)
    assert scan_in_time(stale, Deadline.after(100.0)) is stale  # offline: every guess serves
    empty = _stale_scan(sc, state)
    empty._result = ReachScan([], sc.phases.start_delay_window_s, ())
    assert scan_in_time(empty, _live(SINCE_S)) is empty  # it reached nothing: kept (the plan answers out of reach)
    again = scan_in_time(stale, _live(SINCE_S))
    assert again is not stale and not again.made and again.count == stale.count
    window = again.scenario.phases.start_delay_window_s
    assert again.result.reachable and all(window[0] <= g.start_delay_s <= window[1] for g in again.result.guesses)
    assert window[0] >= SINCE_S + START_LEAD_S + DELAY_STEP_S


def test_an_approach_from_another_base_scans_the_window_still_in_time(scenario_I, monkeypatch):
    """Its scan of the whole window first (a plan's first approach: as before); where every guess of it meets too early
    (an approach from another base offset late in a plan), a scan of the window still in time."""
    scanned: list[tuple[float, float]] = []
    problem = Planner(scenario_I).approach
    early = ApproachGuess(np.zeros(problem.n_params), np.zeros(2), 5.0, np.zeros(7),
                          np.zeros((len(TRACKING_NODES), 7)), 0.1)

    def recorded(sc, spline, state, count, held_angles=True):
        scanned.append(sc.phases.start_delay_window_s)
        return ReachScan([early] if len(scanned) == 1 else [], sc.phases.start_delay_window_s, ())

    monkeypatch.setattr(approach_guess, "reach_scan", recorded)
    started: list[float] = []
    monkeypatch.setattr(approach_solve, "_solve_once", lambda problem, state, w0, *args, **kwargs: started.append(
        float(w0[problem.decision.slice("start_delay_s").start])) or SimpleNamespace(success=False, iterations=1))
    monkeypatch.setattr(approach_solve, "replace", lambda result, **kwargs: result)
    state = scenario_I.target_state.as_state()
    out = approach_solve.solve_approach_from_base(problem, state, np.zeros(2), 1, 1.0, _live(SINCE_S))
    assert not out.success and started == [] and len(scanned) == 2 and out.status == SolveOutcome.NO_GUESS_IN_TIME
    assert scanned[0] == scenario_I.phases.start_delay_window_s
    assert scanned[1][0] >= SINCE_S + START_LEAD_S + DELAY_STEP_S
    scanned.clear()
    approach_solve.solve_approach_from_base(problem, state, np.zeros(2), 1, 1.0, Deadline.after(100.0))
    assert scanned == [scenario_I.phases.start_delay_window_s] and started == [5.0]  # offline: the early guess


def test_a_grasp_search_whose_scan_came_too_early_plans_after_its_answer(scenario_I):
    """Handed a scan whose only guess meets at 5 s, 13 s after the observation (a costed plan's feasibility stage
    after the costed optimum's share of the budget): the search scans again from ~20 s and its first grasp's approach
    starts after the earliest start; before, it had no guess to start from."""
    planner = Planner(scenario_I)
    state = scenario_I.target_state.as_state()
    deadline = _live(SINCE_S)
    search = GraspSearch(planner, state, None, _stale_scan(scenario_I, state), planner.motion(state), deadline)
    candidate, stab = search.run()
    assert candidate.app.success and stab.success
    assert candidate.app.start_delay_s >= SINCE_S + START_LEAD_S


@pytest.mark.parametrize(("delays_s", "status"), [((5.0, 9.0), SolveOutcome.NO_GUESS_IN_TIME),
                                                  ((), SolveOutcome.NO_GUESS_LEFT)])
def test_an_approach_with_no_start_says_whether_its_guesses_came_too_early(scenario_I, delays_s, status):
    """Every scanned guess before the answer can come (13 s after the observation: the earliest start ~18 s): the
    approach says so, not that no guess was left; with no guess at all (the degenerate scan), none left."""
    problem = Planner(scenario_I).approach
    guesses = [ApproachGuess(np.zeros(problem.n_params), np.zeros(2), t, np.zeros(7),
                             np.zeros((len(TRACKING_NODES), 7)), 0.1) for t in delays_s]
    scan = SimpleNamespace(serves=lambda state, count: True, scenario=scenario_I, made=True,
                           result=SimpleNamespace(guesses=guesses))
    out = approach_solve.solve_approach(problem, scenario_I.target_state.as_state(), max_starts=3, scan=scan,
                                        deadline=_live(SINCE_S))
    assert not out.success and out.iterations == 0 and out.status == status
