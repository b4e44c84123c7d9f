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
