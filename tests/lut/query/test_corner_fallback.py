"""A query whose interpolated plan fails verification tries to repair its stabilization, then its heaviest corners'
own plans (each repaired if need be) before any solve (issue 21): the first that verifies is the answer, the corners
at the cell's lowest cost are tried first, at most ``CORNER_TRIES`` corners for at most ``CORNER_STAGE_S`` are tried,
and an asked-for refine skips them all. A plan failing from one cause after its grasp (the wrench alone, or the arm's
path alone) is repaired at once, one failing from both only once every corner was verified as it is, fewest failed
checks first; one failing before its grasp never. The planner is replaced by a stand-in whose verdict depends on
which parameters it is given (and, for a repair, on the plan it repairs)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lut.query import corner_stage
from lut.query import table_query as tq_module
from lut.query.corner_stage import cheaper
from lut.query.interpolation import Candidate
from lut.query.result import QuerySource
from lut.query.table_query import TableQuery
from lut.table.point_result import PointResult, PointStatus
from planner.model.target import TargetState
from planner.verify.checks import CheckResult

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
STATE = TargetState(np.array([0.9996573249755573, 0, 0, 0.026176948307873]), np.radians([0.0, 0.0, 3.8]))


T_GRASP_S = 50.0
# what a stand-in plan fails: (check, time of its worst value [s]) — its braking alone, its arm's path alone, both
# after the grasp (two or three checks), or its approach
FAILURES = {"braking": (("grasp_torque", 60.0),),
            "path": (("collision", 70.0), ("joint_position", 80.0)),
            "arm": (("grasp_torque", 60.0), ("collision", 70.0)),
            "arm3": (("grasp_torque", 60.0), ("collision", 70.0), ("joint_position", 80.0)),
            "approach": (("grasp_torque", 60.0), ("collision", 30.0))}


@dataclass
class _Report:
    feasible: bool
    checks: dict = field(default_factory=dict)
    t_grasp_s: float = T_GRASP_S


def _report(feasible: bool, failure: str) -> _Report:
    """A stand-in verification: feasible, or failing the checks of ``FAILURES[failure]`` (each by the same excess)."""
    failed = () if feasible else FAILURES[failure]
    return _Report(feasible, {name: CheckResult(name, 2.0, 1.0, -1.0, False, "-", "", t_s) for name, t_s in failed})


@pytest.fixture(scope="module")
def opened() -> TableQuery:
    return TableQuery(GOLDEN)


def _stand_in(tq: TableQuery, monkeypatch, weights: dict[int, float], feasible: set[int],
              repairable: frozenset = frozenset(), costs: dict[int, float] | None = None,
              failures: dict | None = None) -> list:
    """Corners with these weights (and costs, default 0), each its own copy of one plan; a plan verifies iff it is
    one of ``feasible``'s own, its repair iff it is one of ``repairable``'s ("interpolated" for the interpolated
    plan); a plan that fails fails ``failures``' kind for it (default: its braking alone). Returns the tried order."""
    costs, failures = costs or {}, failures or {}
    # copies of one plan: every corner meets at the same time, so all are mutually consistent whatever the table holds
    candidates = [Candidate(c, w, replace(tq.points[1].parameters), costs.get(c, 0.0)) for c, w in weights.items()]
    owner = {id(c.parameters): c.corner for c in candidates}
    tried: list = []

    def simulate_and_verify(state, parameters, latency):
        corner = owner.get(id(parameters), "interpolated")
        tried.append(corner)
        return SimpleNamespace(corner=corner), _report(corner in feasible, failures.get(corner, "braking"))

    def repaired(made, report, deadline):
        corner = made.corner  # the plan the query has just verified is the one repaired
        tried.append(f"repair {corner}")
        return (object(), _report(True, "")) if corner in repairable else None

    def refine(state, warm, budget_s):
        tried.append("refine" if warm is not None else "cold")
        return PointResult(-1, PointStatus.FAILED, "stand-in: no solve")

    monkeypatch.setattr(tq, "corner_candidates", lambda state: candidates)
    monkeypatch.setattr(tq, "beyond_carry", lambda state, corners: None)  # stand-in corners are no grid points
    monkeypatch.setattr(tq, "simulate_and_verify", simulate_and_verify)
    monkeypatch.setattr(tq, "repaired", repaired)
    monkeypatch.setattr(tq, "refine", refine)
    return tried


def test_the_heaviest_corner_that_verifies_is_the_answer_without_a_solve(opened, monkeypatch):
    tried = _stand_in(opened, monkeypatch, {0: 0.1, 1: 0.5, 2: 0.4}, feasible={0, 2})
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", "repair interpolated", 1, "repair 1", 2]  # by weight; 0 is never reached
    assert res.source is QuerySource.CORNER and res.corners_used == [2] and res.report.feasible
    assert "corners_s" in res.latency_s and "refine_s" not in res.latency_s
    assert res.solve_notes == ()  # a table plan: no solve made it


def test_only_corner_tries_are_made_then_the_solves_run(opened, monkeypatch):
    monkeypatch.setattr(corner_stage, "CORNER_TRIES", 2)
    tried = _stand_in(opened, monkeypatch, {0: 0.1, 1: 0.5, 2: 0.4}, feasible={0})
    res = opened.query(STATE, budget_s=100.0)
    assert tried[:5] == ["interpolated", "repair interpolated", 1, "repair 1", 2]
    assert tried[5:] == ["repair 2", "refine", "cold"]  # warm from the interpolation, then cold: both give nothing here
    assert res.source is QuerySource.INTERPOLATED and not res.report.feasible


def test_no_corner_is_tried_once_the_corner_stage_has_taken_its_time(opened, monkeypatch):
    monkeypatch.setattr(corner_stage, "CORNER_STAGE_S", 0.0)
    tried = _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible={0, 1})
    opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", "repair interpolated", "refine", "cold"]


def test_corners_at_the_cells_lowest_cost_are_tried_first_and_alone_averaged(opened, monkeypatch):
    """An optimal table's corner left in a local minimum (Eq. 16 at 0.3 m² where its neighbours hold ~1e-9 m²) is
    neither averaged nor tried before the optimal corners, however heavy: the query would inherit its cost."""
    costs = {0: 0.3, 1: 1e-9, 2: 2e-9}
    weights = {0: 0.5, 1: 0.1, 2: 0.4}
    same = opened.points[1].parameters  # one meeting time: only the costs can split the corners
    alike = [Candidate(c, w, same, costs[c]) for c, w in weights.items()]
    monkeypatch.setattr(opened, "corner_candidates", lambda state: alike)
    assert sorted(opened.interpolate(STATE).corners) == [1, 2]
    tried = _stand_in(opened, monkeypatch, weights, feasible={0, 1, 2}, costs=costs)
    assert sorted(opened.interpolate(STATE).corners) == [1, 2]  # the stand-in's copies as well
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", "repair interpolated", 2]  # the cheap ones by weight: 2 (0.4) before 1 (0.1)
    assert res.corners_used == [2] and res.source is QuerySource.CORNER


def test_a_warm_refine_gets_half_of_what_is_left_at_most_its_cap_and_the_cold_solve_the_rest(opened, monkeypatch):
    budgets: list[tuple[str, float]] = []
    _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible=set())

    def refine(state, warm, budget_s):
        budgets.append(("warm" if warm is not None else "cold", budget_s))
        return PointResult(-1, PointStatus.FAILED, "stand-in: no solve")

    monkeypatch.setattr(opened, "refine", refine)
    opened.query(STATE, budget_s=100.0)  # ~90 s left after the table: half of it would be ~45 s
    (warm, warm_s), (cold, cold_s) = budgets
    assert (warm, cold) == ("warm", "cold") and warm_s == tq_module.WARM_REFINE_CAP_S
    # the stand-in's warm refine takes no time: the cold solve gets all that is left, not the other half
    assert 100.0 - tq_module.FINISH_RESERVE_S - 10.0 < cold_s <= 100.0 - tq_module.FINISH_RESERVE_S
    budgets.clear()
    # half of what is left after the table (a few seconds at most) is under the cap
    opened.query(STATE, budget_s=tq_module.FINISH_RESERVE_S + 2 * tq_module.WARM_REFINE_CAP_S - 1.0)
    assert budgets[0][1] < tq_module.WARM_REFINE_CAP_S
    assert budgets[0][1] == pytest.approx(tq_module.WARM_SHARE * budgets[1][1], abs=2.0)


def test_an_optimal_tables_warm_refine_keeps_the_longer_cap_its_descent_was_measured_with(opened, monkeypatch):
    """A table of optimal plans: its warm refine lowers the cost while it has time, so it keeps the cap its queries
    were measured with; a table of feasible plans gets the shorter one (README "Envelope tables")."""
    assert tq_module.WARM_REFINE_CAP_S < tq_module.COSTED_WARM_REFINE_CAP_S
    assert opened.scorer.feasibility_only and opened.warm_refine_cap_s == tq_module.WARM_REFINE_CAP_S
    budgets: list[float] = []
    _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible=set())

    def refine(state, warm, budget_s):
        budgets.append(budget_s)
        return PointResult(-1, PointStatus.FAILED, "stand-in: no solve")

    monkeypatch.setattr(opened, "refine", refine)
    monkeypatch.setattr(type(opened.scorer), "feasibility_only", property(lambda scorer: False))
    monkeypatch.setattr(opened, "cost_breakdowns", lambda plan, report, corners: ())
    opened.query(STATE, budget_s=100.0)
    assert budgets[0] == tq_module.COSTED_WARM_REFINE_CAP_S


def test_an_asked_for_refine_skips_the_corners(opened, monkeypatch):
    tried = _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible={0, 1})
    opened.query(STATE, budget_s=100.0, refine=True)
    assert tried[:2] == ["interpolated", "refine"] and 0 not in tried and 1 not in tried


def test_a_repaired_interpolation_is_the_answer_before_any_corner(opened, monkeypatch):
    tried = _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible={0, 1}, repairable=frozenset({"interpolated"}))
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", "repair interpolated"]
    assert res.source is QuerySource.REPAIRED and res.corners_used and set(res.corners_used) <= {0, 1}
    assert "repair_s" in res.latency_s


def test_a_corner_is_repaired_when_it_fails_as_it_is(opened, monkeypatch):
    tried = _stand_in(opened, monkeypatch, {2: 0.2, 1: 0.8}, feasible=set(), repairable=frozenset({1}))
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", "repair interpolated", 1, "repair 1"]
    assert res.source is QuerySource.REPAIRED and res.corners_used == [1]


def test_a_plan_failing_from_both_causes_is_repaired_once_every_corner_was_verified(opened, monkeypatch):
    """Repairs of a plan whose braking is too harsh while its arm hits a limit or a body mostly fail, at seconds each:
    a corner failing from one cause (its wrench, or its path) is verified and repaired before them, and they go
    fewest failed checks first."""
    failures = {"interpolated": "arm", 1: "arm3", 2: "arm", 0: "braking", 3: "path"}
    tried = _stand_in(opened, monkeypatch, {0: 0.2, 1: 0.4, 2: 0.3, 3: 0.1}, feasible=set(),
                      repairable=frozenset({2}), failures=failures)
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", 1, 2, 0, "repair 0", 3, "repair 3", "repair interpolated", "repair 2"]
    assert res.source is QuerySource.REPAIRED and res.corners_used == [2]


def test_a_plan_repaired_last_is_not_repaired_once_the_corner_stage_has_taken_its_time(opened, monkeypatch):
    """The deferred repairs belong to the corner stage: past it, the solves get the time, even for the interpolated
    plan's own repair."""
    monkeypatch.setattr(corner_stage, "CORNER_STAGE_S", 0.0)
    tried = _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible=set(), repairable=frozenset({"interpolated"}),
                      failures={"interpolated": "arm"})
    opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", "refine", "cold"]


def test_a_plan_failing_before_its_grasp_is_never_repaired(opened, monkeypatch):
    failures = {"interpolated": "approach", 0: "approach", 1: "approach"}
    tried = _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.5}, feasible=set(), repairable=frozenset({0, 1}),
                      failures=failures)
    opened.query(STATE, budget_s=100.0)
    assert not [t for t in tried if str(t).startswith("repair")] and tried[-2:] == ["refine", "cold"]


def test_the_interpolations_own_corner_is_not_tried_again(opened, monkeypatch):
    """An interpolation of one corner (the cell's only one at its lowest cost) is that corner's plan: verifying and
    repairing it again would repeat the same seconds."""
    costs = {0: 1e-9, 1: 0.3}
    tried = _stand_in(opened, monkeypatch, {0: 0.6, 1: 0.4}, feasible={0, 1}, costs=costs,
                      failures={"interpolated": "approach"})
    res = opened.query(STATE, budget_s=100.0)
    assert res.corners_used == [1] and tried == ["interpolated", 1]


def test_once_a_corner_verifies_only_cheaper_corners_are_tried_and_the_cheapest_feasible_is_the_answer(opened,
                                                                                                        monkeypatch):
    """Issue 21: within a band of cost the corners go nearest first, so the first to verify can be the band's costliest
    (scenario II, seed 9 state 7: corner 82 at 1.139 m² answered where a lighter corner at 0.978 m² was never tried;
    the fresh optimum 1.083 m²). After a feasible corner the rest of the order is tried only where cheaper."""
    costs = {0: 1.0, 5: 1.02, 1: 1.2, 2: 1.15, 3: 1.1, 4: 1.5}  # band 0: 0, 5; band 1: 1, 2, 3; band 2: 4
    weights = {0: 0.3, 5: 0.25, 1: 0.2, 2: 0.12, 3: 0.08, 4: 0.05}
    tried = _stand_in(opened, monkeypatch, weights, feasible={1, 2, 3, 4}, costs=costs,
                      failures={"interpolated": "approach", 0: "approach", 5: "approach"})
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", 0, 5, 1, 2, 3]  # 4 (1.5 m²) is not cheaper than 1's 1.2 m²: never tried
    assert res.corners_used == [3] and res.source is QuerySource.CORNER and res.report.feasible


def test_a_cheaper_corner_that_fails_leaves_the_feasible_answer_and_is_not_repaired_from_both_causes(opened,
                                                                                                    monkeypatch):
    """A cheaper corner failing from one cause is repaired at once, as before a corner was found; one failing from
    both (repairs that mostly fail, seconds each) is not kept for later once a feasible plan is in hand."""
    costs = {0: 1.0, 5: 1.02, 1: 1.2, 2: 1.15, 3: 1.12, 4: 1.1}
    weights = {0: 0.3, 5: 0.25, 1: 0.2, 2: 0.12, 3: 0.08, 4: 0.05}
    tried = _stand_in(opened, monkeypatch, weights, feasible={1}, costs=costs, repairable=frozenset({2, 3, 4}),
                      failures={"interpolated": "approach", 0: "approach", 5: "approach", 2: "arm", 4: "approach"})
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", 0, 5, 1, 2, 3, "repair 3", 4]  # 2 fails from both causes: never repaired
    assert res.corners_used == [3] and res.source is QuerySource.REPAIRED


def test_a_feasibility_only_table_answers_with_its_first_feasible_corner(opened, monkeypatch):
    """Costs all 0 (no cost weighted): no corner is cheaper than another, so the stage ends at the first feasible."""
    tried = _stand_in(opened, monkeypatch, {0: 0.5, 1: 0.3, 2: 0.2}, feasible={0, 1, 2},
                      failures={"interpolated": "approach"})
    res = opened.query(STATE, budget_s=100.0)
    assert tried == ["interpolated", 0] and res.corners_used == [0]


@pytest.mark.parametrize(("cost", "than", "worth"), [
    (1.0, 1.0, False),  # the same cost
    (1.0 - 1e-4, 1.0, False),  # lower by exactly the tolerance: a cost the query does not tell apart
    (1.0 - 2e-4, 1.0, True),
    (0.0, 0.0, False),  # a feasibility-only table: nothing is cheaper than its first feasible corner
    (float("nan"), 1.0, False), (0.5, float("nan"), False),  # an unknown cost on either side
])
def test_a_corner_is_worth_trying_after_a_feasible_one_only_when_cheaper_beyond_the_tolerance(cost, than, worth):
    assert cheaper(cost, than) is worth
