"""A query tries a table plan only where it can start after the answer: one that would start before is moved whole spin
periods later (a flat spin repeats itself) when the window holds it, else not tried, and the answer says which."""

from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lut.query.result import QuerySource, TableAnswer
from lut.query.table_query import TableQuery
from lut.table.point_result import PointResult, PointStatus
from planner.model.target import TargetState
from planner.plan import NoPlan
from tests.support.cli import ON_GRID_STATE, assert_one_line_error, lutgen_in_process

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def opened() -> TableQuery:
    return TableQuery(GOLDEN)


def _flat_spin(rate_deg_s: float) -> TargetState:
    return TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.0, 0.0, rate_deg_s * DEG]))


def _no_solve(monkeypatch, tq: TableQuery) -> list[float]:
    """Solves replaced by a failing stand-in; returns the start delays [s] the query re-simulates, in order (each
    verified feasible by a stand-in)."""
    simulated: list[float] = []

    def simulate_and_verify(state, parameters, latency):
        simulated.append(parameters.approach.start_delay_s)
        return SimpleNamespace(approach=parameters.approach), SimpleNamespace(feasible=True, checks={})

    monkeypatch.setattr(tq, "simulate_and_verify", simulate_and_verify)
    monkeypatch.setattr(tq, "out_of_reach", lambda state, t_start: None)
    monkeypatch.setattr(tq, "refine", lambda *a, **k: PointResult(-1, PointStatus.FAILED, "stand-in: no solve"))
    return simulated


def test_a_flat_spin_plan_started_one_period_later_meets_the_same_grasp(opened):
    """The symmetry the move rests on, by the re-simulation itself: a golden point's plan at its own state and the
    same plan 90 s (one turn at 4 °/s) later verify alike, to the re-simulation's integration error."""
    point = 2
    state = opened.grid.state_at(opened.grid.coordinates(point))
    stored = opened.points[point].parameters
    period = 2 * math.pi / float(np.linalg.norm(state.omega_body_rad_s))
    now = opened.simulate_and_verify(state, stored, {})[1]
    later = opened.simulate_and_verify(state, stored.with_start_delay(stored.approach.start_delay_s + period), {})[1]
    assert now.feasible and later.feasible
    for name, check in now.checks.items():
        assert later.checks[name].value == pytest.approx(check.value, rel=1e-3, abs=1e-3), name


def test_a_table_plan_that_would_start_before_the_answer_is_tried_a_period_later(opened, monkeypatch):
    state = _flat_spin(4.5)  # beyond the grid: answered at its 4 °/s edge; one turn takes 80 s
    found = opened.interpolate(state)
    early = replace(found, parameters=found.parameters.with_start_delay(3.0))
    monkeypatch.setattr(opened, "interpolate", lambda s: early)
    simulated = _no_solve(monkeypatch, opened)
    result = opened.query(state, budget_s=100.0, since_s=time.monotonic() - 10.0)  # observed 10 s ago
    assert simulated == [pytest.approx(83.0, abs=1e-9)]
    assert result.source is QuerySource.INTERPOLATED and not result.late


def test_table_plans_no_period_can_move_into_time_are_not_tried_and_the_answer_says_which(opened, monkeypatch):
    state = _flat_spin(3.8)  # one turn takes 95 s: no table plan (18-40 s) can start a turn later within 90 s
    simulated = _no_solve(monkeypatch, opened)
    with pytest.raises(NoPlan) as refused:
        opened.query(state, budget_s=100.0, since_s=time.monotonic() - 60.0)  # the answer 62 s after it at best
    assert simulated == []
    message = str(refused.value)
    assert "would start too soon" in message and "the interpolated plan of points" in message
    assert "the corner plan of points" in message


def test_a_query_observed_now_tries_its_table_plan_where_the_table_holds_it(opened, monkeypatch):
    state = _flat_spin(3.8)
    found = opened.interpolate(state)
    assert isinstance(found, TableAnswer)
    simulated = _no_solve(monkeypatch, opened)
    opened.query(state, budget_s=100.0)
    assert simulated == [found.parameters.approach.start_delay_s]  # in time: the very plan, not moved


def test_the_operators_earliest_start_holds_the_table_plans_and_reaches_the_solves(opened, monkeypatch):
    """``--earliest-start-s 60``: the table's plans (18-40 s, no turn of 95 s brings them within 90 s) are not tried,
    and a solve is told the earliest start with the observation."""
    state = _flat_spin(3.8)
    simulated = _no_solve(monkeypatch, opened)
    told: list[dict] = []
    monkeypatch.setattr(opened, "refine", lambda *a, **k: told.append(opened._solver_kwargs()) or PointResult(
        -1, PointStatus.FAILED, "stand-in: no solve"))
    monkeypatch.setattr(opened, "earliest_start_s", 60.0)
    with pytest.raises(NoPlan, match="would start too soon"):
        opened.query(state, budget_s=100.0)
    assert simulated == [] and told and all(kw["earliest_start_s"] == 60.0 for kw in told)
    assert all(kw["observed_at_s"] == opened.observed_at_s for kw in told)


def _refines_recorded(monkeypatch, tq: TableQuery, feasible: bool) -> list[float | None]:
    """Every table plan re-simulated verifies ``feasible`` (stand-in), the reach scan passes, and each refine is a
    failing stand-in; returns the start delay [s] of each refine's warm start (None: a cold solve), in order."""
    _no_solve(monkeypatch, tq)
    monkeypatch.setattr(tq, "simulate_and_verify", lambda state, parameters, latency: (
        SimpleNamespace(approach=parameters.approach), SimpleNamespace(feasible=feasible, checks={})))
    warm_starts: list[float | None] = []

    def refine(state, warm, budget_s):
        warm_starts.append(None if warm is None else warm.approach.start_delay_s)
        return PointResult(-1, PointStatus.FAILED, "stand-in: no solve")

    monkeypatch.setattr(tq, "refine", refine)
    return warm_starts


def test_a_refine_starts_warm_from_the_table_plan_as_placed_a_period_later(opened, monkeypatch):
    """The interpolated plan starts at 3 s, before the answer of a state observed 10 s ago: the query tries it a turn
    (80 s) later, and when it fails there the warm refine starts from it there, not from its passed meeting time."""
    state = _flat_spin(4.5)
    found = opened.interpolate(state)
    monkeypatch.setattr(opened, "interpolate",
                        lambda s: replace(found, parameters=found.parameters.with_start_delay(3.0)))
    warm_starts = _refines_recorded(monkeypatch, opened, feasible=False)
    monkeypatch.setattr(opened, "corner_plan", lambda *a, **k: None)  # the interpolated plan's alone
    with pytest.raises(NoPlan):
        opened.query(state, budget_s=100.0, since_s=time.monotonic() - 10.0)
    assert warm_starts == [pytest.approx(83.0, abs=1e-9), None]  # warm, then cold


def test_no_refine_starts_warm_from_a_table_plan_no_period_brings_into_time(opened, monkeypatch):
    """Observed 60 s ago, a 3.8 °/s spin (a turn of 95 s): the table's plans (18-40 s) cannot start in time, so the
    refine from them is not made (its grasp has passed); the cold solve gets the budget at once."""
    warm_starts = _refines_recorded(monkeypatch, opened, feasible=True)
    with pytest.raises(NoPlan, match="would start too soon"):
        opened.query(_flat_spin(3.8), budget_s=100.0, since_s=time.monotonic() - 60.0)
    assert warm_starts == [None]
    observed_now = _refines_recorded(monkeypatch, opened, feasible=False)  # the same table plan, in time
    assert opened.query(_flat_spin(3.8), budget_s=100.0).source is QuerySource.INTERPOLATED  # infeasible, the least
    found = opened.interpolate(_flat_spin(3.8))
    assert observed_now == [found.parameters.approach.start_delay_s, None]


def test_query_takes_earliest_start_and_says_which_table_plans_it_held_back():
    """End to end, with no time left to solve (8 s): the answer names the plans held back, exit 2, no plan."""
    proc = lutgen_in_process("query", GOLDEN, *ON_GRID_STATE, "--earliest-start-s", "60", "--budget-s", "8")
    assert proc.returncode == 2, proc.stderr
    assert "would start too soon" in proc.stdout + proc.stderr


def test_an_earliest_start_outside_the_scenarios_window_is_refused_in_one_line():
    proc = lutgen_in_process("query", GOLDEN, *ON_GRID_STATE, "--earliest-start-s", "95")
    assert_one_line_error(proc, "--earliest-start-s", "95")


def test_a_solve_for_an_earliest_start_plans_with_the_window_raised_to_it():
    from lut.solve import point_worker

    scenario = str(Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_I.toml")
    assert point_worker._planner(scenario, None, 30.0).scenario.phases.start_delay_window_s == (30.0, 90.0)
    assert point_worker._planner(scenario, None).scenario.phases.start_delay_window_s == (0.0, 90.0)
