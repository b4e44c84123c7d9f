"""A query's refine plans against the query's deadline in its child process: when the time is up it returns
the plan it has, verified, instead of being killed with nothing (the monotonic clock is one for every process)."""

from __future__ import annotations

import numpy as np

from lut.solve.point_process import DEFAULT_SOLVER, run_point
from lut.table.point_result import PointStatus
from planner.config.scenario import load_scenario
from tests.support.cli import ROOT

SCENARIO_I = ROOT / "configs" / "scenarios" / "scenario_I.toml"


def test_a_refine_past_its_deadline_returns_a_verified_plan_not_a_timeout():
    state = load_scenario(SCENARIO_I).target_state.as_state()
    # the child's plan must end at its launch: its deadline (less the verification's reserve) has passed at once
    result = run_point(DEFAULT_SOLVER, str(SCENARIO_I), -1, state, None, 0.0, timeout_s=120.0, plan_budget_s=0.0)
    # judged by verify (infeasible: nothing was solved), with the parameters it had: not a killed, failed point
    assert result.status is PointStatus.INFEASIBLE, result.failure_reason
    assert result.parameters is not None and np.all(np.isfinite(result.parameters.approach.params))
    assert result.iterations <= 2  # the approach stopped at its first callback; no stabilization NLP solved


def test_a_querys_cold_solve_keeps_the_scenarios_nlp_wall_limit_and_a_warm_refine_gets_half(monkeypatch):
    """The cold solve is `lutgen plan`'s at the state, so it plans with the same settings: halved, an approach
    re-solved for its tracking's rates (40 s in all) was cut at 47 s of a 94 s budget and its grasp lost. A warm
    refine's NLPs each get at most half, so its approach cannot take its braking's time."""
    from lut.query import table_query
    from lut.query.table_query import TableQuery

    given: list[float | None] = []
    monkeypatch.setattr(table_query, "run_point", lambda *args, **kw: given.append(kw["max_wall_s"]))
    tq = TableQuery(ROOT / "tests" / "data" / "ci_golden.h5")
    state = tq.grid.state(0)
    tq.refine(state, None, 94.0)
    tq.refine(state, tq.points[0].parameters, 94.0)
    assert given == [None, 47.0]
