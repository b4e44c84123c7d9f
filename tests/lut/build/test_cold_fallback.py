"""A build point warm-started from a neighbour whose plan verify refuses is planned again cold, and the cold plan
is kept only if it is feasible (a neighbour's solution can lead into a family that does not work at this point).
The planner and verify are stand-ins: this checks the worker's decisions, not the NLPs."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest

import lut.solve.point_worker as worker
import planner.verify.verifier as verifier
from lut.table.point_result import PointResult, PointStatus
from lut.table.records import from_record
from planner.deadline import VERIFY_RESERVE_S, Deadline
from planner.plan_parameters import ApproachParameters, PlanParameters

WARM = PlanParameters(ApproachParameters(np.zeros(3), np.zeros(2), 10.0, np.zeros((3, 7))), np.zeros(4))


class _Planner:
    """Answers a warm plan and a cold plan with the verdicts the test chose; records the warm starts it got."""

    def __init__(self, warm_ok: bool, cold_ok: bool) -> None:
        self.scenario = SimpleNamespace(phases=SimpleNamespace(start_delay_window_s=(0.0, 60.0)),
                                        target=SimpleNamespace(inertia_body_kg_m2=np.diag([800.0, 1100.0, 1500.0])))
        self.warm_starts: list[PlanParameters | None] = []
        self.verdicts = {"warm": warm_ok, "cold": cold_ok}
        self.calls: list[str] = []
        self.deadlines: list[tuple[Deadline, Deadline | None]] = []

    def plan(self, state, warm_start, deadline, grasp_by=None):
        self.calls.append("cold" if warm_start is None else "warm")
        self.warm_starts.append(warm_start)
        self.deadlines.append((deadline, grasp_by))
        return self.calls[-1]


@pytest.fixture
def stand_ins(monkeypatch):
    def install(warm_ok: bool, cold_ok: bool) -> _Planner:
        planner = _Planner(warm_ok, cold_ok)
        monkeypatch.setattr(worker, "_planner", lambda path, wall, earliest=None: planner)
        monkeypatch.setattr(verifier, "verify", lambda plan: plan)
        monkeypatch.setattr(worker, "result_from_plan", lambda point, plan, report: PointResult(
            point, PointStatus.FEASIBLE if planner.verdicts[plan] else PointStatus.INFEASIBLE, plan, 1.0,
            iterations=10 if plan == "warm" else 20, parameters=WARM))  # the reason field names the plan kept
        return planner

    return install


def _solve(warm, cold_fallback: bool, deadline_at_s: float | None = None) -> PointResult:
    return from_record(worker.solve_point("s.toml", 3, np.array([1.0, 0, 0, 0]), np.radians([0, 0, 4.0]), warm, 0.0,
                                          deadline_at_s=deadline_at_s, cold_fallback=cold_fallback))


@pytest.mark.parametrize("warm_ok, cold_ok, calls, kept, iterations", [
    (True, True, ["warm"], "warm", 10),  # a feasible warm plan is the answer: no cold plan
    (False, True, ["warm", "cold"], "cold", 30),  # the cold plan rescues the point; both solves counted
    (False, False, ["warm", "cold"], "warm", 30),  # neither: the warm plan's verdict stays (the neighbour's family)
])
def test_an_infeasible_warm_plan_is_followed_by_a_cold_one(stand_ins, warm_ok, cold_ok, calls, kept, iterations):
    planner = stand_ins(warm_ok, cold_ok)
    result = _solve(WARM, cold_fallback=True)
    assert planner.calls == calls and result.iterations == iterations
    assert result.failure_reason == kept and (result.status is PointStatus.FEASIBLE) == (warm_ok or cold_ok)


def test_without_the_fallback_or_a_warm_start_there_is_one_plan(stand_ins):
    planner = stand_ins(False, True)
    assert _solve(WARM, cold_fallback=False).status is PointStatus.INFEASIBLE and planner.calls == ["warm"]
    planner = stand_ins(False, True)
    assert _solve(None, cold_fallback=True).status is PointStatus.FEASIBLE and planner.calls == ["cold"]


def test_a_warm_plan_a_cold_one_follows_must_find_its_grasp_in_its_share_of_the_time(stand_ins):
    """The warm plan's grasp is due at WARM_SHARE of the time left (its descent may still run to the deadline); the
    cold plan after it has the whole rest; without a fallback the warm plan has it all."""
    planner = stand_ins(False, True)
    at_s = time.monotonic() + 100.0
    _solve(WARM, cold_fallback=True, deadline_at_s=at_s)
    (warm_end, warm_grasp_by), (cold_end, cold_grasp_by) = planner.deadlines
    assert warm_end.at_s == cold_end.at_s == pytest.approx(at_s - VERIFY_RESERVE_S)
    left_s = at_s - VERIFY_RESERVE_S - time.monotonic()
    assert warm_grasp_by.remaining_s() == pytest.approx(worker.WARM_SHARE * left_s, abs=1.0)
    # a plan cut by the share says so, not that the point's budget ran out
    assert "share" in warm_grasp_by.what and warm_end.what == "the plan's time budget"
    assert cold_grasp_by is None
    planner = stand_ins(False, True)
    _solve(WARM, cold_fallback=False, deadline_at_s=at_s)
    assert planner.deadlines[0][1] is None


@pytest.mark.parametrize("omega_deg_s, start_s", [
    ((0.0, 0.0, 4.0), 5.0),  # a spin about a principal axis: 10 + 85 s is past the window (60 s), a turn (90 s) back
    ((4.0, 4.0, 4.0), 95.0),  # a tumble never repeats: its 2π/|ω| = 52 s is no period, the start stays
])
def test_a_warm_start_moves_by_whole_periods_only_where_the_motion_repeats(stand_ins, omega_deg_s, start_s):
    planner = stand_ins(True, True)
    worker.solve_point("s.toml", 3, np.array([1.0, 0, 0, 0]), np.radians(omega_deg_s), WARM, 85.0)
    assert planner.warm_starts[0].approach.start_delay_s == pytest.approx(start_s)
