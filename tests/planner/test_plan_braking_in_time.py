"""A live plan brakes a grasp only while its answer can still come before that grasp's approach starts
(``GraspSearch._stabilize``): the braking ends :data:`ANSWER_LEAD_S` before the start, a grasp already past it is not
braked at all, and the notes say so; a table point (no observation) brakes within its whole budget."""

from __future__ import annotations

import time
from types import SimpleNamespace

import pytest

from planner.deadline import ANSWER_LEAD_S, Deadline
from planner.nlp.outcome import SolveOutcome
from planner.plan_grasps import GraspSearch

START_S = 32.0  # the grasp's approach starts this long after the observation [s]


class _Grasp:
    """A grasp whose braking records the deadline it is given and ends with ``status``."""

    def __init__(self, status: str = "stand-in ok") -> None:
        self.app = SimpleNamespace(start_delay_s=START_S)
        self.grasp_time_s = START_S + 15.0
        self.status, self.deadlines = status, []

    def stabilize(self, warm, budget, screen, deadline, stall=None):
        self.deadlines.append(deadline)
        return SimpleNamespace(status=self.status, success=self.status == "stand-in ok")

    def unbraked(self, status):
        return SimpleNamespace(status=status, success=False)


def _search(deadline: Deadline) -> GraspSearch:
    return GraspSearch(SimpleNamespace(), None, None, None, None, deadline)


def _live(since_s: float) -> Deadline:
    observed = time.monotonic() - since_s
    return Deadline.after(100.0, observed).observed(observed)


def test_a_live_braking_ends_the_lead_before_its_approach_starts():
    search, grasp = _search(_live(10.0)), _Grasp()
    assert search._stabilize(grasp, 120).success and search.notes == []
    (given,) = grasp.deadlines
    assert given.at_s == pytest.approx(search.deadline.observed_at_s + START_S - ANSWER_LEAD_S)


def test_a_table_points_braking_keeps_its_whole_budget():
    deadline, grasp = Deadline.after(100.0), _Grasp()
    _search(deadline)._stabilize(grasp, 120)
    assert grasp.deadlines == [deadline]


def test_a_grasp_whose_start_is_within_the_lead_is_not_braked_and_says_why():
    """Observed 31 s ago, the approach at 32 s: braked now, the plan could not answer before its start."""
    search, grasp = _search(_live(START_S - ANSWER_LEAD_S + 1.0)), _Grasp()
    out = search._stabilize(grasp, None)
    assert grasp.deadlines == [] and out.status == SolveOutcome.OUT_OF_TIME and not out.success
    assert search.notes == [f"the braking from the grasp at t = {START_S + 15.0:.1f} s stopped {ANSWER_LEAD_S:g} s "
                            f"before its approach's start ({START_S:.1f} s after the observation): braked later, the "
                            "plan would answer after it"]
    search._note_failure(grasp, out, "trying another grasp")  # not said twice
    assert len(search.notes) == 1


def test_a_braking_cut_at_the_lead_is_noted_once():
    search, grasp = _search(_live(10.0)), _Grasp(status=SolveOutcome.OUT_OF_TIME)
    out = search._stabilize(grasp, 120)
    assert len(grasp.deadlines) == 1 and out.status == SolveOutcome.OUT_OF_TIME
    assert len(search.notes) == 1
    assert f"stopped {ANSWER_LEAD_S:g} s before its approach's start (32.0 s" in search.notes[0]
    plan_out = _search(Deadline(time.monotonic() - 1.0))  # the plan's own budget ran out: its own note elsewhere
    plan_out._stabilize(_Grasp(), 120)
    assert plan_out.notes == []


def test_an_approach_stopped_for_its_own_start_says_so_the_plans_deadline_does_not():
    """A live approach solve ends START_LEAD_S before the latest start its bounds allow
    (``planner.phases.approach_solve.start_deadline``): its note says so while the plan's own deadline has not passed
    (then it is the plan's budget, noted elsewhere)."""
    from planner.deadline import START_LEAD_S

    app = SimpleNamespace(status=SolveOutcome.OUT_OF_TIME)
    assert _search(_live(10.0))._failed(app) == (f"Out_Of_Time; stopped {START_LEAD_S:g} s before the latest start "
                                                  "its meeting time allows")
    spent = Deadline(time.monotonic() - 1.0).observed(time.monotonic() - 10.0)
    assert _search(spent)._failed(app) == "Out_Of_Time"
    assert _search(_live(10.0))._failed(SimpleNamespace(status=SolveOutcome.INFEASIBLE)) == str(SolveOutcome.INFEASIBLE)
