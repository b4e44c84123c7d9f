"""A tumble table's plans keep their start: a tumble never repeats its attitude, so no spin period moves them.

Once a tumble table's query moved every plan by 2π/|ω| (a flat spin's period) into [0, 2π/|ω|): at its own grid
point (4, 4, 4) °/s, whose plan starts at 77 s (2π/|ω| = 52 s), the stored plan was simulated at 25.5 s, 0.9 m from the
handle at the grasp, and the answer was INFEASIBLE after a refine.

Beyond what a tumble plan carries (lut.query.carry), the query plans at the state at once: the table's plans and a
warm refine from them would only spend the budget (README "How far a plan carries"); ``--robust`` judges only the
corners a tumble plan carries to."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lut.query.carry import nearest_displacement
from lut.query.result import QuerySource
from lut.query.robust_choice import RobustRequest, robust_query
from lut.query.table_query import TableQuery
from lut.robustness.error_model import ErrorModel
from lut.table.point_result import PointResult, PointStatus
from planner.model.rotation import quat_multiply
from planner.model.target import TargetState
from planner.plan import NoPlan
from tests.support.cli import lutgen_in_process

ROOT = Path(__file__).resolve().parents[3]
AXES = {"omega_x_deg_s": 4.0, "omega_y_deg_s": 4.0, "omega_z_deg_s": 4.0, "roll_deg": 0.0, "pitch_deg": 0.0,
        "yaw_deg": 0.0}


@pytest.fixture(scope="module")
def tumble_table(tmp_path_factory) -> Path:
    """A one-point scenario I tumble table at (4, 4, 4) °/s, attitude identity (seconds to build)."""
    folder = tmp_path_factory.mktemp("tumble")
    scenario = (ROOT / "configs" / "scenarios" / "scenario_I.toml").as_posix()
    axes = "".join(f'[[axes]]\nname = "{n}"\nmin = {v}\nmax = {v}\ncount = 1\n' for n, v in AXES.items())
    grid = folder / "tumble1.toml"
    grid.write_text(f'name = "tumble1"\nscenario = "{scenario}"\nkind = "tumble"\n{axes}')
    out = folder / "tumble1.h5"
    built = lutgen_in_process("build", grid, "--out", out, "--no-progress")
    assert built.returncode == 0, built.stderr
    return out


def test_a_tumble_tables_query_at_its_own_point_answers_with_its_plan_as_stored(tumble_table):
    tq = TableQuery(tumble_table)
    stored = tq.points[0].parameters
    state = tq.grid.state_at(tq.grid.coordinates(0))
    assert stored is not None and stored.approach.start_delay_s > 60.0  # later than 2π/|ω| = 52 s: the case at stake
    result = tq.query(state, budget_s=100.0)
    assert result.source is QuerySource.INTERPOLATED and result.report.feasible
    assert result.plan.approach.start_delay_s == stored.approach.start_delay_s


def _recorded(tq: TableQuery, monkeypatch) -> list[str]:
    """The query's stages as they run: each table plan re-simulated, each solve (warm or cold; none gives a plan)."""
    tried: list[str] = []

    def simulate_and_verify(state, parameters, latency):
        tried.append("table plan")
        return original(state, parameters, latency)

    def refine(state, warm, budget_s):
        tried.append("warm" if warm is not None else "cold")
        return PointResult(-1, PointStatus.FAILED, "stand-in: no solve")

    original = tq.simulate_and_verify
    monkeypatch.setattr(tq, "simulate_and_verify", simulate_and_verify)
    monkeypatch.setattr(tq, "refine", refine)
    monkeypatch.setattr(tq, "out_of_reach", lambda state, t_start: None)
    return tried


def _displaced(tq: TableQuery, attitude_deg: float, rate_deg_s: float) -> TargetState:
    """The table's point turned by ``attitude_deg`` about body z, its body rate changed by ``rate_deg_s`` about x."""
    point = tq.grid.state(0)
    half = np.radians(attitude_deg) / 2
    turned = quat_multiply(point.attitude_wxyz, [np.cos(half), 0.0, 0.0, np.sin(half)])
    return TargetState(turned, point.omega_body_rad_s + np.radians([rate_deg_s, 0.0, 0.0]))


@pytest.mark.parametrize(("attitude_deg", "rate_deg_s"), [(30.0, 0.0), (0.0, 1.5), (90.0, 2.0)])
def test_a_state_beyond_the_carry_of_every_plan_is_planned_at_once_without_the_tables_plans(
        tumble_table, monkeypatch, attitude_deg, rate_deg_s):
    """No table plan is re-simulated and no warm refine spends the budget: the cold solve is the first stage, and
    the answer says why (here the stand-in solve gives nothing: exit 2's NoPlan, naming the point and distances)."""
    tq = TableQuery(tumble_table)
    tried = _recorded(tq, monkeypatch)
    with pytest.raises(NoPlan, match="point 0.*beyond what a tumble plan carries"):
        tq.query(_displaced(tq, attitude_deg, rate_deg_s), budget_s=100.0)
    assert tried == ["cold"]


def test_a_state_within_carry_tries_the_tables_plan_first(tumble_table, monkeypatch):
    tq = TableQuery(tumble_table)
    tried = _recorded(tq, monkeypatch)
    result = tq.query(_displaced(tq, 2.0, 0.1), budget_s=100.0)
    assert tried[0] == "table plan" and not any("carries" in note for note in result.notes)


def test_a_flat_spin_tables_plans_are_always_tried_however_far():
    """A flat spin's phase is an exact time shift and its corners carry across coarse cells: no carry rule there, even
    for a state 90° and 2 °/s from every point of the table."""
    tq = TableQuery(ROOT / "tests" / "data" / "ci_golden.h5")
    point = tq.grid.state(0)
    far = TargetState(quat_multiply(point.attitude_wxyz, [np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0]),
                      point.omega_body_rad_s + np.radians([2.0, 0.0, 0.0]))
    found = tq.interpolate(far)
    assert found is not None and nearest_displacement(found.corners, far, tq.grid.state).beyond_carry
    assert tq.beyond_carry(far, found.corners) is None


@pytest.mark.parametrize(("attitude_deg", "rate_deg_s", "corner_tried"), [(30.0, 0.0, False), (2.0, 0.1, True)])
def test_a_robust_query_judges_only_the_corners_a_tumble_plan_carries_to(tumble_table, monkeypatch, attitude_deg,
                                                                          rate_deg_s, corner_tried):
    """``--robust`` re-simulates each corner of the cell as a candidate: in a tumble table, only one within what a
    tumble plan carries (a corner 30° away would cost its simulation and verification and never verify)."""
    tq = TableQuery(tumble_table)
    tried = _recorded(tq, monkeypatch)
    infeasible = SimpleNamespace(feasible=False, violations=["stand-in"])
    plain = SimpleNamespace(source=QuerySource.SOLVED_COLD, plan=None, report=infeasible, corners_used=[])
    monkeypatch.setattr(tq, "query", lambda state, budget_s: plain)
    request = RobustRequest(ErrorModel.from_sigmas(np.radians(0.5), np.radians(0.05)), samples=1, seed=0, jobs=1)
    choice = robust_query(tq, _displaced(tq, attitude_deg, rate_deg_s), request, budget_s=100.0, refine=False)
    assert tried == (["table plan"] if corner_tried else [])
    assert [c.label for c in choice.candidates][1:] == (["corner 0"] if corner_tried else [])
