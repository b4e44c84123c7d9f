"""A tumble table's plans keep their start: a tumble never repeats its attitude, so no spin period moves them.

Once a tumble table's query moved every plan by 2π/|ω| (a flat spin's period) into [0, 2π/|ω|): at its own grid
point (4, 4, 4) °/s, whose plan starts at 77 s (2π/|ω| = 52 s), the stored plan was simulated at 25.5 s, 0.9 m from the
handle at the grasp, and the answer was INFEASIBLE after a refine.

Beyond what a tumble plan carries (lut.query.carry), the query plans at the state at once: the table's plans and a
warm refine from them would only spend the budget (README "How far a plan carries"); ``--robust`` judges only the
corners a tumble plan carries to. A flat-spin table's plans likewise, beyond what a flat-spin plan carries (its spin
axis and rate)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

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


def _ci_table_at(rate_deg_s: float, axis_deg: float) -> tuple[TableQuery, TargetState]:
    """The CI golden table (scenario II flat spins at 3.5-4 °/s, spin axis 90°, phase 0-20°) and the flat spin of
    that rate and spin axis, phase 10°."""
    tq = TableQuery(ROOT / "tests" / "data" / "ci_golden.h5")
    return tq, tq.grid.state_at([rate_deg_s, axis_deg, 10.0])


@pytest.mark.parametrize(("rate_deg_s", "axis_deg"), [(4.0, 125.0), (4.6, 90.0), (3.75, 270.0), (1.0, 60.0)])
def test_a_flat_spin_beyond_what_its_tables_plans_carry_is_planned_at_once(monkeypatch, rate_deg_s, axis_deg):
    """35° of spin axis, 0.6 °/s of rate, the opposite axis, both: outside the table's box by more than half the
    coarse envelope cell, where none of its plans verified; the cold solve is the first stage, and the answer says
    why (here the stand-in solve gives nothing: exit 2's NoPlan)."""
    tq, state = _ci_table_at(rate_deg_s, axis_deg)
    tried = _recorded(tq, monkeypatch)
    with pytest.raises(NoPlan, match="of spin axis and .* beyond what a flat-spin plan carries"):
        tq.query(state, budget_s=100.0)
    assert tried == ["cold"]


@pytest.mark.parametrize(("transverse_deg_s", "tilt_deg", "beyond"), [
    (2.0, 0.0, True), (0.0, 25.0, True), (0.03, 0.3, False), (0.9, 0.0, False)])
def test_a_tumble_given_to_a_flat_spin_table_is_planned_at_once_if_far_from_every_flat_spin(
        monkeypatch, transverse_deg_s, tilt_deg, beyond):
    """Grid point 0's flat spin (inside the grid) tilted about body x and given a transverse body rate about body x: a
    general tumble (2 °/s across, or 25° of tilt) is beyond what a plan carries from its own state, an estimator's flat
    spin (0.3°, 0.03 °/s) and 0.9 °/s across are not."""
    tq = TableQuery(ROOT / "tests" / "data" / "ci_golden.h5")
    point = tq.grid.state(0)
    half = np.radians(tilt_deg) / 2
    tumbling = TargetState(quat_multiply(point.attitude_wxyz, [np.cos(half), np.sin(half), 0.0, 0.0]),
                           point.omega_body_rad_s + np.radians([transverse_deg_s, 0.0, 0.0]))
    tried = _recorded(tq, monkeypatch)
    try:
        notes = tq.query(tumbling, budget_s=100.0).notes
    except NoPlan as exc:  # the stand-in solves give none
        notes = (str(exc),)
    assert (tried == ["cold"]) is beyond and (tried[0] == "table plan") is not beyond
    assert any("from its nearest flat spin, beyond what a tumble plan carries" in n for n in notes) is beyond


@pytest.mark.parametrize(("rate_deg_s", "axis_deg"), [(3.75, 90.0), (4.5, 90.0), (3.5, 120.0), (4.3, 65.0)])
def test_a_flat_spin_within_what_its_tables_plans_carry_tries_them_first(monkeypatch, rate_deg_s, axis_deg):
    """Inside the box, and outside it by at most 30° of spin axis and 0.5 °/s (the edges themselves included): the
    table's plan is re-simulated first and nothing notes a carry."""
    tq, state = _ci_table_at(rate_deg_s, axis_deg)
    tried = _recorded(tq, monkeypatch)
    try:
        result = tq.query(state, budget_s=100.0)
        notes = result.notes
    except NoPlan as exc:  # the table's plan infeasible there and the stand-in solves give none
        notes = (str(exc),)
    assert tried[0] == "table plan" and not any("carries" in note for note in notes)


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
