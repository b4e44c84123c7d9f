"""A live approach NLP's lower bound on the start delay (``Deadline.start_bound_s``): taken from its guess where the
guess is far enough past the earliest start, so that the same state gets the same solve however long the plan's earlier
stages took; the earliest start itself where the guess is near it or before it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import planner.deadline as deadline_module
import planner.phases.approach_solve as approach_solve
from planner.config.scenario import load_scenario
from planner.deadline import START_LEAD_S, STEADY_REACH_S, Deadline
from planner.phases.approach_guess import ScanOnDemand
from planner.plan import Planner
from tests.support.cli import ROOT

NOW_S = 1000.0  # the clock the tests set [s, time.monotonic()]


def _live(monkeypatch, since_s: float) -> Deadline:
    """A live plan's deadline ``since_s`` [s] after its observation, on a clock that stands still."""
    monkeypatch.setattr(deadline_module.time, "monotonic", lambda: NOW_S)
    observed = NOW_S - since_s
    return Deadline.after(100.0, observed).observed(observed)


def test_a_guess_well_past_the_earliest_start_bounds_the_same_whatever_the_clock(monkeypatch):
    """2.0 s and 2.9 s since the observation: earliest starts 7 s and 8 s; a guess at 85 s is bounded at 65 s both
    times, and 1 ns past a whole second changes nothing either."""
    bounds = []
    for since_s in (2.0, 2.9, 3.0 + 1e-9):
        live = _live(monkeypatch, since_s)
        bounds.append(live.start_bound_s(85.0))
    assert bounds == [85.0 - STEADY_REACH_S] * 3
    assert _live(monkeypatch, 2.0).earliest_start_s() == 2.0 + START_LEAD_S  # the premise: the floors differ
    assert _live(monkeypatch, 2.9).earliest_start_s() == 3.0 + START_LEAD_S


@pytest.mark.parametrize("guess_past_earliest_s, bound_past_earliest_s", [
    (STEADY_REACH_S + 1.0, 1.0),  # far: from the guess
    (STEADY_REACH_S, 0.0),  # exactly the reach: both rules agree
    (STEADY_REACH_S - 1e-9, 0.0),  # a hair nearer: the earliest start
    (3.0, 0.0),  # near: the earliest start
    (-4.0, 0.0),  # a guess before the earliest start is raised to it, never below
])
def test_the_bound_is_never_before_the_earliest_start(monkeypatch, guess_past_earliest_s, bound_past_earliest_s):
    live = _live(monkeypatch, 12.3)
    earliest = live.earliest_start_s()
    assert live.start_bound_s(earliest + guess_past_earliest_s) == pytest.approx(earliest + bound_past_earliest_s,
                                                                                 abs=1e-12)
    assert live.start_bound_s(earliest + guess_past_earliest_s) >= earliest


def test_a_plan_with_no_observation_has_no_bound():
    """A table point or an offline plan: its times are hypothetical, its window whole."""
    assert Deadline.after(100.0).start_bound_s(85.0) == -math.inf
    assert Deadline().start_bound_s(0.0) == -math.inf


def test_the_same_state_solved_a_second_later_gives_the_same_approach_to_the_bit(monkeypatch):
    """Scenario II's default state from its best scanned guess well past the earliest start: solved at 2.0 s and at
    2.9 s after the observation (earliest starts 7 and 8 s) the approach is the same to the bit. With the earliest start
    as the bound (the rule before), the two solves differ: a bound that never binds still steers IPOPT's barrier."""
    scenario = load_scenario(ROOT / "configs" / "scenarios" / "scenario_II.toml")
    problem = Planner(scenario).approach
    state = scenario.target_state.as_state()
    guesses = ScanOnDemand(scenario, problem.spline, state, 10, held_angles=False).result.guesses
    guess = next(g for g in guesses if g.start_delay_s >= 8.0 + STEADY_REACH_S)  # far past either floor
    w0 = approach_solve.decision_vector(guess)

    def solved(since_s: float, steady: bool = True) -> np.ndarray:
        with monkeypatch.context() as patched:  # this solve's clock (and rule) only
            live = _live(patched, since_s)
            if not steady:
                patched.setattr(Deadline, "start_bound_s", lambda self, guess_s: self.earliest_start_s())
            app = approach_solve._solve_once(problem, state, w0, 1.0, cold=True, max_iterations=60, deadline=live)
        return np.concatenate([app.params, app.base_offset_m, [app.start_delay_s]])

    np.testing.assert_array_equal(solved(2.0), solved(2.9))
    assert not np.array_equal(solved(2.0, steady=False), solved(2.9, steady=False))


def test_a_start_beyond_its_bounds_is_bounded_from_where_the_nlp_starts(monkeypatch):
    """A starting point whose start delay lies past the NLP's upper bound (90 s) starts at that bound: the lower bound
    is 20 s before it (70 s), not 20 s before the point given (180 s), which would pin the start at the window's end."""
    scenario = load_scenario(ROOT / "configs" / "scenarios" / "scenario_I.toml")
    problem = Planner(scenario).approach
    delay = problem.decision.slice("start_delay_s").start
    bounds: list[float] = []

    class Recorded(Exception):
        pass

    def recorded(problem, lbw, ubw, earliest_s):
        bounds.append(earliest_s)
        raise Recorded

    monkeypatch.setattr(approach_solve, "_not_before", recorded)
    live = _live(monkeypatch, 10.0)
    w0 = np.zeros(problem.n_w)
    w0[delay] = problem.ubw[delay] + 110.0
    with pytest.raises(Recorded):
        approach_solve._solve_once(problem, scenario.target_state.as_state(), w0, 1.0, deadline=live)
    assert bounds == [problem.ubw[delay] - STEADY_REACH_S] and problem.ubw[delay] == 90.0
