"""A plan's deadline: an instant on the monotonic clock, passed or not, with room kept back before it."""

from __future__ import annotations

import math
import time

from planner.deadline import ANSWER_LEAD_S, FLOOR_STEP_S, NO_DEADLINE, START_LEAD_S, Deadline


def test_no_deadline_never_passes_and_leaves_all_the_time():
    assert not NO_DEADLINE.bounded and not NO_DEADLINE.passed
    assert NO_DEADLINE.remaining_s() == math.inf and NO_DEADLINE.earlier(5.0).remaining_s() == math.inf
    assert Deadline.after(None) == NO_DEADLINE


def test_a_deadline_counts_from_the_given_instant():
    now = time.monotonic()
    started = now - 10.0  # a command that began 10 s ago with a 12 s budget has ~2 s left
    deadline = Deadline.after(12.0, started)
    assert deadline.bounded and not deadline.passed
    assert 0.0 < deadline.remaining_s() <= 2.0
    assert deadline.earlier(3.0).passed and deadline.earlier(3.0).remaining_s() < 0.0
    assert Deadline.after(0.0, now - 1e-3).passed  # a zero budget is over at once


def test_only_a_live_plans_deadline_dates_the_earliest_start():
    """A table point's deadline has no observation: its approach may start anywhere in the window; a live plan's
    approach solved now starts no earlier than the time since the observation plus the lead, through every share
    of its budget (``earlier``)."""
    assert Deadline.after(30.0).earliest_start_s() == -math.inf and NO_DEADLINE.earliest_start_s() == -math.inf
    observed = time.monotonic() - 7.0
    live = Deadline.after(100.0, observed).observed(observed)
    for deadline in (live, live.earlier(5.0), live.earlier(40.0, "a share"), NO_DEADLINE.observed(observed)):
        floor = deadline.earliest_start_s()
        # rounded up to a whole second; the test itself takes far less than 1 s
        assert 7.0 + START_LEAD_S <= floor <= 7.0 + START_LEAD_S + 2 * FLOOR_STEP_S and floor % FLOOR_STEP_S == 0
    assert live.earlier(5.0).at_s == live.at_s - 5.0 and live.earlier(5.0).observed_at_s == observed


def test_plans_observed_a_fraction_of_a_second_apart_get_the_same_earliest_start():
    """The floor is rounded up to a whole step, so the same state planned 0.4 s later meets the same NLP bounds (and
    IPOPT the same path); only a floor crossing a whole second moves it, by one step."""
    now = time.monotonic()
    sooner, later = (Deadline(observed_at_s=now - since).earliest_start_s() for since in (7.2, 7.6))
    assert sooner == later == 7.0 + START_LEAD_S + FLOOR_STEP_S
    assert Deadline(observed_at_s=now - 7.2).earliest_start_s(ANSWER_LEAD_S) == 7.0 + ANSWER_LEAD_S + FLOOR_STEP_S


def test_a_floor_on_a_whole_second_stays_there_and_a_hair_past_it_goes_to_the_next(monkeypatch):
    """The rounding's edges, on a clock the test sets: 7 s since the observation and the 5 s lead give exactly 12 s
    (kept, not raised to 13); a nanosecond later, 13 s."""
    import planner.deadline as deadline_module

    observed = 1000.0
    for since_s, floor_s in ((7.0, 12.0), (7.0 + 1e-9, 13.0), (6.5, 12.0)):
        monkeypatch.setattr(deadline_module.time, "monotonic", lambda since_s=since_s: observed + since_s)
        assert Deadline(observed_at_s=observed).earliest_start_s() == floor_s, since_s


def test_a_live_plan_must_stop_solving_the_lead_before_its_approach_starts():
    """``in_time_for``: the earlier of the budget's end and the approach's start less the lead, for a live plan only;
    at exactly the budget's end the budget is kept (its name too)."""
    observed = time.monotonic()
    budget = Deadline.after(100.0, observed)
    live = budget.observed(observed)
    assert live.in_time_for(30.0).at_s == observed + 30.0 - ANSWER_LEAD_S
    assert live.in_time_for(30.0).observed_at_s == observed and live.in_time_for(30.0).what == live.what
    assert live.in_time_for(100.0 + ANSWER_LEAD_S) == live  # the start's lead ends with the budget: the budget's
    assert live.in_time_for(200.0) == live
    assert budget.in_time_for(0.0) == budget and NO_DEADLINE.in_time_for(0.0) == NO_DEADLINE  # no observation
    assert NO_DEADLINE.observed(observed).in_time_for(ANSWER_LEAD_S - 1.0).passed  # its start is within the lead
