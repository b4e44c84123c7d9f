"""A query of a state no meeting time brings within the arm's reach answers at once (exit 2), never solves; a
reachable state whose solve gives no plan (crashed, killed at its time limit) is answered infeasible too (exit 2,
never the exit 1 of bad input).

The state: a scenario II flat spin of the coverage section (seed 7) that no plan can reach (the reach proof: the
grasp's wrist point beyond the chaser's reach at every meeting time); on the golden table (scenario II, spin axis fixed
at orbital z) it lies off the grid, so the table's carried plans fail verify (and lie beyond what a flat-spin plan
carries). Before, the query then spent half its budget on a warm refine and the rest on a cold solve that said out of
reach (51 s).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from lut.query.result import QuerySource
from lut.query.table_query import TableQuery
from lut.table.point_result import PointResult, PointStatus
from planner.model.target import TargetState
from planner.plan import NoPlan, OutOfReach
from tests.support.cli import lutgen_in_process

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
ATTITUDE = "0.0983087415872,0.856991118432,0.473549649159,0.177911056536"
OMEGA_DEG_S = "0,0,1.00087763661"
STATE = TargetState([0.0983087415872, 0.856991118432, 0.473549649159, 0.177911056536],
                    [0.0, 0.0, 1.00087763661 * 3.141592653589793 / 180.0])


@pytest.fixture(scope="module")
def tq() -> TableQuery:
    return TableQuery(GOLDEN)


def _no_refine(*args, **kwargs):
    raise AssertionError("a state out of reach must not be solved")


def test_out_of_reach_with_a_table_plan_answers_it_infeasible_without_a_solve(tq, monkeypatch):
    """The table's plan moved 30 s later (carried to STATE it starts 2.4 s after the observation: too soon, below), and
    taken as within what a flat-spin plan carries (STATE's 1 °/s is 2.5 °/s from the table's rates, where the query
    would not try it at all: lut.query.carry): the branch a state out of reach near a table's plan takes."""
    found = tq.interpolate(STATE)
    monkeypatch.setattr(tq, "beyond_carry", lambda state, corners: None)
    later = replace(found, parameters=found.parameters.with_start_delay(found.parameters.approach.start_delay_s + 30))
    monkeypatch.setattr(tq, "interpolate", lambda state: later)
    monkeypatch.setattr(tq, "refine", _no_refine)
    result = tq.query(STATE, budget_s=100.0)
    assert not result.report.feasible and result.source is QuerySource.INTERPOLATED
    assert result.refine_failure.startswith("out of reach (proven): at every start delay within [0, 90] s")


def test_out_of_reach_with_table_plans_too_soon_for_the_answer_raises_it(tq, monkeypatch):
    """Carried to STATE (a 1 °/s spin: one turn is 360 s, past the window) the table's plans start 2.4 s after the
    observation, before any answer can come (2 s from now, rounded up to a whole second): none is tried, and with no
    solve for a state out of reach there is no plan at all."""
    assert all(c.parameters.approach.start_delay_s < 3.0 for c in tq.corner_candidates(STATE))
    monkeypatch.setattr(tq, "refine", _no_refine)
    with pytest.raises(OutOfReach, match="out of reach"):
        tq.query(STATE, budget_s=100.0)


def test_out_of_reach_without_a_table_plan_raises_it(tq, monkeypatch):
    monkeypatch.setattr(tq, "interpolate", lambda state: None)  # a table with no feasible point near it
    monkeypatch.setattr(tq, "refine", _no_refine)
    with pytest.raises(OutOfReach, match="out of reach"):
        tq.query(STATE, budget_s=100.0)


def test_the_cli_says_out_of_reach_in_one_line_and_exits_2_without_writing_a_plan(tmp_path, monkeypatch):
    monkeypatch.setattr(TableQuery, "interpolate", lambda self, state: None)
    out = tmp_path / "plan.json"
    proc = lutgen_in_process("query", GOLDEN, "--attitude", ATTITUDE, "--omega-deg-s", OMEGA_DEG_S, "--out", out)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr and not out.exists()
    lines = proc.stderr.splitlines()
    assert lines[0].startswith("INFEASIBLE (") and "out of reach (proven): " in lines[0]
    assert lines[1] == "no plan written: there is no trajectory to export"


def _killed(self, state, warm, budget_s):
    return PointResult(-1, PointStatus.FAILED, f"killed at its time limit of {budget_s:.0f} s")


def _no_table_plan_and_a_killed_solve(monkeypatch):
    monkeypatch.setattr(TableQuery, "interpolate", lambda self, state: None)
    monkeypatch.setattr(TableQuery, "out_of_reach", lambda self, state, t_start: None)
    monkeypatch.setattr(TableQuery, "refine", _killed)


def test_a_solve_that_gives_no_plan_raises_no_plan(tq, monkeypatch):
    _no_table_plan_and_a_killed_solve(monkeypatch)
    with pytest.raises(NoPlan, match="no plan: .*killed at its time limit"):
        tq.query(STATE, budget_s=100.0)


def test_the_cli_answers_a_state_without_a_plan_infeasible_never_as_bad_input(tmp_path, monkeypatch):
    _no_table_plan_and_a_killed_solve(monkeypatch)
    out = tmp_path / "plan.json"
    proc = lutgen_in_process("query", GOLDEN, "--attitude", ATTITUDE, "--omega-deg-s", OMEGA_DEG_S, "--out", out)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr and "error:" not in proc.stderr and not out.exists()
    lines = proc.stderr.splitlines()
    assert lines[0].startswith("INFEASIBLE (") and "no plan: " in lines[0] and "killed at its time limit" in lines[0]
    assert lines[1] == "no plan written: there is no trajectory to export"
