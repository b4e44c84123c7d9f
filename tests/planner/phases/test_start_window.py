"""The start-delay window that opens after the observation (``phases.min_start_delay_s``): the scan, the reach proof,
the approach NLP and a whole plan keep the approach's start inside [earliest, latest]; 0 is the window as before."""

from __future__ import annotations

import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import planner.phases.approach_solve as approach_solve
from planner.config.scenario import load_scenario
from planner.deadline import FLOOR_STEP_S, START_LEAD_S, STEADY_REACH_S, Deadline
from planner.model.target import TargetState
from planner.phases.approach import approach_spline
from planner.phases.approach_guess import reach_scan
from planner.phases.reach_proof import reach_proof, wrist_distance_over_window
from planner.phases.reach_scan_result import DELAY_STEP_S, ApproachGuess, MeetingOutcome, ReachScan, scan_times_s
from planner.plan import Planner
from planner.verify.verifier import verify
from tests.support.cli import ROOT

REACHED, BEYOND = MeetingOutcome.REACHED, MeetingOutcome.BEYOND_REACH
EARLIEST_S = 20.0  # scenario I's default state meets at a start delay of ~32.7 s with the window open from 0


@pytest.fixture(scope="module")
def scenario_I():
    return load_scenario(ROOT / "configs" / "scenarios" / "scenario_I.toml")


def _from(sc, earliest_s: float):
    return replace(sc, phases=replace(sc.phases, min_start_delay_s=earliest_s))


def test_the_bundled_window_opens_at_the_observation(scenario_I):
    assert scenario_I.phases.start_delay_window_s == (0.0, scenario_I.phases.max_start_delay_s)


def test_the_scan_and_the_proof_start_at_the_earliest_start(scenario_I):
    sc = _from(scenario_I, EARLIEST_S)
    state = sc.target_state.as_state()
    scan = reach_scan(sc, approach_spline(sc), state)
    latest = sc.phases.max_start_delay_s
    assert len(scan.outcomes) == int((latest - EARLIEST_S) // DELAY_STEP_S) + 1
    assert scan.reachable and all(EARLIEST_S <= g.start_delay_s <= latest for g in scan.guesses)
    assert scan.window_s == (EARLIEST_S, latest)
    delays, _ = wrist_distance_over_window(sc, state)
    assert delays[0] == EARLIEST_S and delays[-1] == latest
    proof = reach_proof(sc, state)
    assert proof.window_s == (EARLIEST_S, latest) and EARLIEST_S <= proof.start_delay_s <= latest


def test_a_window_no_whole_number_of_steps_long_is_scanned_at_its_end_too():
    """A window of 5–90 s is scanned at 5, 7, …, 89 s and at 90 s: seed 7's scenario I flat spin 5 reaches its grasp
    only at the window's end (its cold plan meets at 90 s), and a table built over the [5, 90] s window called it out
    of reach when 89 s was the last time scanned."""
    assert scan_times_s((5.0, 90.0)) == [5.0 + 2.0 * k for k in range(43)] + [90.0]
    assert scan_times_s((0.0, 90.0)) == [2.0 * k for k in range(46)]  # the end is a step: not scanned twice
    assert scan_times_s((0.0, 90.0 - 1e-12)) == [2.0 * k for k in range(45)] + [90.0 - 1e-12]
    assert scan_times_s((7.0, 7.0)) == [7.0]  # a window of one instant
    assert scan_times_s((5.0, 6.0)) == [5.0, 6.0]  # shorter than a step: both ends
    assert scan_times_s((5.0, 5.0 + 2e-10)) == [5.0 + 2e-10]  # within SAME_TIME_S: its end alone
    assert scan_times_s((3.5, 6.0)) == [3.5, 5.5, 6.0]
    reached_at_end = ReachScan([], (5.0, 9.0), (BEYOND, BEYOND, REACHED)).reached_start_delays_s()
    assert reached_at_end == [(9.0, 9.0)]
    uneven = ReachScan([], (3.5, 6.0), (BEYOND, REACHED, REACHED)).reached_start_delays_s()
    assert uneven == [(5.5, 6.0)]  # the end 0.5 s after the last step: one interval
    assert ReachScan([], (0.0, 90.0), ()).reached_start_delays_s() == []  # proven: nothing scanned


def test_a_grasp_reachable_only_at_the_windows_end_is_reached(scenario_I):
    """Seed 7's scenario I flat spin 5 with the window opening at 5 s (``--earliest-start-s 5``): reached at 90 s
    only, the window's end, which no step from 5 s lands on."""
    sc = _from(scenario_I, 5.0)
    state = TargetState(np.array([-0.483132140037, 0.705492500343, 0.516317087906, -0.0477528214917]),
                        np.radians([0.0, 1.81613700239, 0.0]))
    scan = reach_scan(sc, approach_spline(sc), state)
    assert scan.reachable, scan.reason()
    assert scan.reached_start_delays_s()[-1][1] == 90.0
    assert all(g.start_delay_s >= 88.0 for g in scan.guesses)


def test_a_window_closed_to_every_reachable_meeting_is_answered_with_it(scenario_I):
    """The default state reaches no meeting time from 40 s on: the refusal names the window it scanned."""
    sc = _from(scenario_I, 40.0)
    scan = reach_scan(sc, approach_spline(sc), sc.target_state.as_state())
    assert not scan.reachable
    assert "start-delay window [40, 90] s" in scan.reason()


def test_a_plan_starts_no_earlier_than_the_window_and_verifies(scenario_I):
    planner = Planner(_from(scenario_I, EARLIEST_S))
    delay = planner.approach.decision.slice("start_delay_s").start
    assert planner.approach.lbw[delay] == EARLIEST_S  # the NLP's own bound, not only its start
    plan = planner.plan(scenario_I.target_state.as_state())
    assert plan.approach.start_delay_s >= EARLIEST_S
    assert verify(plan).feasible
    assert np.isclose(plan.phases["approach"][0], plan.approach.start_delay_s)


# a scenario I flat spin (coverage section, seed 7, state 17) whose approach meets at 0.68 s with the window open
EARLY_STATE = ((0.378483351335, -0.0140455517503, 0.597285821665, 0.706967271149), (0.0, 1.60531163556, 0.0))


def test_a_live_plans_approach_starts_after_its_answer_can_come(scenario_I):
    """Planned offline the approach meets at once (0.68 s, before any answer could come); planned live, every
    approach solve keeps its start delay past the time since the observation plus the lead, and the plan verifies."""
    state = TargetState(np.array(EARLY_STATE[0]), np.radians(EARLY_STATE[1]))
    planner = Planner(scenario_I)
    assert planner.plan(state).approach.start_delay_s < 1.0  # the premise
    observed = time.monotonic()
    plan = planner.plan(state, deadline=Deadline.after(100.0, observed).observed(observed))
    assert plan.approach.start_delay_s >= START_LEAD_S
    assert verify(plan).feasible


def test_a_scanned_guess_meeting_well_before_the_answer_is_not_started_from(scenario_I, monkeypatch):
    """Guesses 3 s before the earliest start (more than one scan step): skipped; 1 s before: started from, its start
    delay raised to the earliest by the NLP's bound; after it: started from as it is."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    started: list[tuple[float, float]] = []  # (the guess's start delay, the solve's lower bound)

    def recorded(problem, state, w0, scale, lbw=None, ubw=None, **kwargs):
        bound = approach_solve._live_bounds(problem, w0, lbw, ubw, kwargs["deadline"])[0][delay]  # the solve's own
        started.append((float(w0[delay]), float(bound)))
        return SimpleNamespace(success=False, iterations=1, start_guess=None)

    monkeypatch.setattr(approach_solve, "_solve_once", recorded)
    monkeypatch.setattr(approach_solve, "replace", lambda result, **kwargs: result)
    observed = time.monotonic() - 20.0  # the earliest start is now 20 s + the lead after the observation
    floor = 20.0 + START_LEAD_S
    params = np.zeros(problem.n_params)  # only their start delays matter: the solve is a stand-in
    guesses = [ApproachGuess(params, np.zeros(2), tau, np.zeros(7), np.zeros((3, 7)), 0.1)
               for tau in (floor - 3.0, floor - 1.0, floor + 5.0)]
    scan = SimpleNamespace(serves=lambda state, count: True, result=SimpleNamespace(guesses=guesses))
    approach_solve.solve_approach(problem, scenario_I.target_state.as_state(), max_starts=3, scan=scan,
                                  deadline=Deadline.after(100.0, observed).observed(observed))
    assert [tau for tau, _ in started] == [floor - 1.0, floor + 5.0]
    # the floor rounded up to a whole FLOOR_STEP_S (the test itself takes far less than a second)
    assert all(floor <= bound <= floor + 2 * FLOOR_STEP_S and bound % FLOOR_STEP_S == 0 for _, bound in started)


def test_too_early_guesses_take_no_start_the_next_in_time_ones_have_them(scenario_I, monkeypatch):
    """Two starts asked for, the scan's two best guesses too early: the two guesses after them are started from (a
    skipped guess is not a start; once it was, and a live plan's first approach started from one guess of three)."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    started: list[float] = []

    def recorded(problem, state, w0, scale, lbw=None, ubw=None, **kwargs):
        started.append(float(w0[delay]))
        return SimpleNamespace(success=False, iterations=1, start_guess=None)

    monkeypatch.setattr(approach_solve, "_solve_once", recorded)
    monkeypatch.setattr(approach_solve, "replace", lambda result, **kwargs: result)
    observed = time.monotonic() - 20.0
    floor = 20.0 + START_LEAD_S
    params = np.zeros(problem.n_params)
    guesses = [ApproachGuess(params, np.zeros(2), tau, np.zeros(7), np.zeros((3, 7)), 0.1)
               for tau in (floor - 10.0, floor - 8.0, floor + 2.0, floor + 4.0, floor + 6.0)]
    scan = SimpleNamespace(serves=lambda state, count: True, result=SimpleNamespace(guesses=guesses))
    approach_solve.solve_approach(problem, scenario_I.target_state.as_state(), max_starts=2, scan=scan,
                                  deadline=Deadline.after(100.0, observed).observed(observed))
    assert started == [floor + 2.0, floor + 4.0]
    started.clear()
    approach_solve.solve_approach(problem, scenario_I.target_state.as_state(), max_starts=2, scan=scan)  # offline
    assert started == [floor - 10.0, floor - 8.0]


def test_the_earliest_start_raises_the_bound_and_pins_it_at_a_closed_window(scenario_I):
    """No observation: the bounds as they are; within the window: the lower bound raised; past the window's end (an
    answer that cannot come before the latest start): pinned at the latest (a live solve there ends at once, by
    ``start_deadline``: none of its starts could be on time)."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    latest = scenario_I.phases.max_start_delay_s
    lbw, ubw = approach_solve._not_before(problem, problem.lbw, problem.ubw, -np.inf)
    assert lbw is problem.lbw and ubw is problem.ubw
    raised, _ = approach_solve._not_before(problem, problem.lbw, problem.ubw, 12.5)
    assert raised[delay] == 12.5 and problem.lbw[delay] == 0.0  # a copy: the problem's own bounds untouched
    np.testing.assert_array_equal(np.delete(raised, delay), np.delete(problem.lbw, delay))
    at_end, _ = approach_solve._not_before(problem, problem.lbw, problem.ubw, latest)
    closed, ub = approach_solve._not_before(problem, problem.lbw, problem.ubw, latest + 30.0)
    assert at_end[delay] == latest and closed[delay] == latest == ub[delay]


def test_the_live_bound_is_taken_from_the_guess_clipped_to_the_window(scenario_I):
    """A guess's start delay outside the NLP's bounds is clipped to them before the bound is taken from it: a guess past
    the window's end bounds the solve STEADY_REACH_S before the end (unclipped, its bound would close the window at the
    end), one before the window's start at the earliest start; a guess exactly STEADY_REACH_S past the earliest start
    gives the earliest start itself."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    latest = scenario_I.phases.max_start_delay_s
    deadline = _live(0.2)  # the earliest start rounds to the same whole second for the next 0.8 s
    earliest = deadline.earliest_start_s()
    w0 = np.zeros(problem.n_w)
    for guess_s, lower_s in ((latest + 100.0, latest - STEADY_REACH_S), (latest, latest - STEADY_REACH_S),
                             (-5.0, earliest), (earliest + STEADY_REACH_S, earliest)):
        w0[delay] = guess_s
        lbw, ubw = approach_solve._live_bounds(problem, w0, None, None, deadline)
        assert (lbw[delay], ubw[delay]) == (lower_s, latest), guess_s
        np.testing.assert_array_equal(np.delete(lbw, delay), np.delete(problem.lbw, delay))
    # offline (no observation) the bounds are the problem's own, whatever the guess
    w0[delay] = latest + 100.0
    assert approach_solve._live_bounds(problem, w0, None, None, Deadline())[0] is problem.lbw


def _live(since_s: float) -> Deadline:
    observed = time.monotonic() - since_s
    return Deadline.after(100.0, observed).observed(observed)


def test_a_live_solve_ends_the_start_lead_before_the_latest_start_its_bounds_allow(scenario_I):
    """Solved on past START_LEAD_S before the latest start its bounds allow, no start within them could be tracked,
    braked and answered in time; the plan's own deadline when that comes first; a table point (no observation) keeps
    its whole budget."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    ubw = problem.ubw.copy()
    ubw[delay] = 35.0
    live = _live(10.0)
    assert approach_solve.start_deadline(problem, ubw, live).at_s == pytest.approx(live.observed_at_s + 30.0)
    soon = Deadline(time.monotonic() + 5.0).observed(live.observed_at_s)  # the plan's own budget ends first
    assert approach_solve.start_deadline(problem, ubw, soon) is soon
    table_point = Deadline.after(100.0)
    assert approach_solve.start_deadline(problem, ubw, table_point) is table_point


def test_each_live_ipopt_run_is_armed_with_its_own_starts_deadline(scenario_I, monkeypatch):
    """The deadline the NLP's callback enforces is the one of the bounds the run is given (a retry's meeting-time box,
    a re-solve's), not only the plan's."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    armed = []

    class Armed(Exception):
        pass

    def arm(*args, deadline, **kwargs):
        armed.append(deadline)
        raise Armed

    monkeypatch.setattr(problem.budget, "arm", arm)
    lbw, ubw = problem.lbw.copy(), problem.ubw.copy()
    lbw[delay], ubw[delay] = 40.0, 46.0
    live = _live(10.0)
    w0 = np.zeros(problem.n_w)
    w0[delay] = 43.0
    with pytest.raises(Armed):
        approach_solve._solve_once(problem, scenario_I.target_state.as_state(), w0, 1.0, lbw, ubw, deadline=live)
    assert armed[0].at_s == pytest.approx(live.observed_at_s + 46.0 - START_LEAD_S)


def test_a_start_stopped_for_its_own_start_ends_the_solve_and_the_search_goes_on(scenario_I, monkeypatch):
    """A start that ran out of time for its own latest start ends the solve (its status Out_Of_Time, its guess named),
    as the plan's deadline does: a re-solve's cold fallback after a warm start cut for time cost a coverage plan
    (seed 10, scenario II flat spin 5) the ~5 s that brought its last in-time guess after its time. The grasp search
    goes on from the guess after the one named (``GraspSearch._grasps``)."""
    problem = Planner(scenario_I).approach
    delay = problem.decision.slice("start_delay_s").start
    started: list[float] = []

    def cut(problem, state, w0, scale, lbw=None, ubw=None, **kwargs):
        started.append(float(w0[delay]))
        problem.budget.out_of_time = True  # as the callback leaves it after a deadline
        return SimpleNamespace(success=False, iterations=1, start_guess=None, status="Out_Of_Time")

    monkeypatch.setattr(approach_solve, "_solve_once", cut)
    monkeypatch.setattr(approach_solve, "replace", lambda result, **kwargs: result)
    params = np.zeros(problem.n_params)
    guesses = [ApproachGuess(params, np.zeros(2), tau, np.zeros(7), np.zeros((3, 7)), 0.1) for tau in (30.0, 50.0)]
    scan = SimpleNamespace(serves=lambda state, count: True, result=SimpleNamespace(guesses=guesses))
    out = approach_solve.solve_approach(problem, scenario_I.target_state.as_state(), max_starts=2, scan=scan,
                                        deadline=_live(10.0))
    assert started == [30.0] and out.status == "Out_Of_Time"
