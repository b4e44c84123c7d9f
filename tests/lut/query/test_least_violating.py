"""An infeasible query answers with its least violating attempt: fewer failed checks first, then the smaller excess
relative to the limits; a feasible plan always wins and is never replaced by an infeasible one."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from lut.query.least_violating import violates_less, violation
from lut.query.table_query import TableQuery
from lut.table.point_result import PointResult, PointStatus
from planner.verify.checks import make_check
from tests.lut.query.test_query_out_of_reach import STATE

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
# the table's plans carried to STATE start 2.4 s after the observation, too soon for any answer (the query does not try
# them); 30 s later they are tried, and still fail verify (the state is out of reach at every start)
LATER_S = 30.0


def _later(tq: TableQuery) -> list:
    """``tq``'s corner candidates at STATE, each started :data:`LATER_S` later."""
    return [replace(c, parameters=c.parameters.with_start_delay(c.parameters.approach.start_delay_s + LATER_S))
            for c in tq.corner_candidates(STATE)]


def _as_if_within_carry(tq: TableQuery, monkeypatch) -> None:
    """STATE (1 °/s) is 2.5 °/s from the table's rates, beyond what a flat-spin plan carries (lut.query.carry): the
    query would not try its plans at all. These tests are of the choice among plans tried, as at a state within."""
    monkeypatch.setattr(tq, "beyond_carry", lambda state, corners: None)


def _report(*checks):
    return SimpleNamespace(checks={c.name: c for c in checks}, feasible=all(c.passed for c in checks))


def _torque(value_nm):
    return make_check("grasp_torque", value_nm, 10.0, "N·m", "", None)


def _joint(value_rad):
    return make_check("joint_position", value_rad, 2.0944, "rad", "", None)


def _collision(distance_m):
    return make_check("collision", distance_m, 0.02, "m", "", None, lower=True)


def _join(jump):
    return make_check("join_velocity", jump, 0.0, "rad/s", "", None)


def test_a_feasible_report_scores_nothing_and_wins():
    feasible, bad = _report(_torque(9.0), _joint(1.0)), _report(_torque(11.0))
    assert violation(feasible) == (0, 0.0)
    assert violates_less(feasible, bad) and not violates_less(bad, feasible)
    assert not violates_less(feasible, _report(_torque(9.5)))  # a feasible answer is never replaced


def test_fewer_failed_checks_first_then_the_smaller_relative_excess():
    one_big = _report(_joint(194.0))  # 192 rad past a 2.09 rad limit: 92 limits over
    two_small = _report(_torque(10.5), _collision(0.019))
    assert violates_less(one_big, two_small)  # one failed check beats two, however large
    torque_11 = _report(_torque(11.0))  # 0.1 of its limit over
    collision_in = _report(_collision(-0.3))  # 0.32 m below a 0.02 m clearance: 16 limits
    assert violation(torque_11) == (1, pytest.approx(0.1))
    assert violation(collision_in) == (1, pytest.approx(16.0))
    assert violates_less(torque_11, collision_in) and not violates_less(collision_in, torque_11)
    assert not violates_less(torque_11, _report(_torque(11.0)))  # equal: the first answer stays


def test_a_zero_limit_counts_its_excess_in_its_units_and_nan_as_infinite():
    assert violation(_report(_join(3e-4))) == (1, pytest.approx(3e-4))
    nan = _report(make_check("grasp_torque", math.nan, 10.0, "N·m", "", None))
    assert not nan.feasible and violation(nan) == (1, math.inf)
    assert violates_less(_report(_torque(50.0)), nan)


def test_the_query_answers_with_the_least_violating_of_its_table_plans(monkeypatch):
    """The golden table's plans carried to a state off its grid all fail verify (no solve: the state is out of
    reach). The interpolation is made the worst of them (the corner plan that violates most, as an interpolation
    across solution families can be): the answer is another corner's plan, the least violating."""
    tq = TableQuery(GOLDEN)
    _as_if_within_carry(tq, monkeypatch)
    found, later = tq.interpolate(STATE), _later(tq)
    tried = {c.corner: (c.parameters, tq.simulate_and_verify(STATE, c.parameters, {})[1]) for c in later}
    assert len(tried) >= 2 and not any(report.feasible for _, report in tried.values())
    monkeypatch.setattr(tq, "corner_candidates", lambda state: later)
    worst = max(tried, key=lambda c: violation(tried[c][1]))
    best = min(tried, key=lambda c: violation(tried[c][1]))
    assert violation(tried[best][1]) < violation(tried[worst][1])
    monkeypatch.setattr(tq, "interpolate", lambda state: replace(found, parameters=tried[worst][0]))
    monkeypatch.setattr(tq, "refine", lambda *a, **k: pytest.fail("a state out of reach is never solved"))
    result = tq.query(STATE, budget_s=100.0)
    assert not result.report.feasible
    assert result.corners_used == [best] and str(result.source) == "corner"
    assert violation(result.report) == violation(tried[best][1])


def test_an_infeasible_refine_that_violates_less_replaces_the_table_plan(monkeypatch):
    tq = TableQuery(GOLDEN)
    _as_if_within_carry(tq, monkeypatch)
    found = tq.interpolate(STATE)
    # started in time (``_later``): the table's plan is tried, and the warm refine starts from it (a plan too soon to
    # be tried gives no warm start)
    tried = {c.corner: (c.parameters, tq.simulate_and_verify(STATE, c.parameters, {})[1]) for c in _later(tq)}
    worst = max(tried, key=lambda c: violation(tried[c][1]))
    best = min(tried, key=lambda c: violation(tried[c][1]))
    monkeypatch.setattr(tq, "interpolate", lambda state: replace(found, parameters=tried[worst][0]))
    monkeypatch.setattr(tq, "corner_candidates", lambda state: [])
    monkeypatch.setattr(tq, "out_of_reach", lambda state, t_start: None)
    monkeypatch.setattr(tq, "refine", lambda state, warm, budget_s: PointResult(
        -1, PointStatus.INFEASIBLE, "grasp torque", parameters=tried[best][0]))
    result = tq.query(STATE, budget_s=100.0)
    assert not result.report.feasible and str(result.source) == "refined"
    assert violation(result.report) == violation(tried[best][1])
