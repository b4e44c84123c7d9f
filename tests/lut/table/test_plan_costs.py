"""The query's cost terms (issue 21): the scorer against independent values, and ``lutgen query`` printing its plan's
cost next to its corners' (table and plan file), or one line for a feasibility-only table."""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np
import pytest

from lut.cli.plan_output import cost_table
from lut.output.plan_file import load_plan
from lut.output.plan_replay import replay_inputs
from lut.query.table_query import TableQuery
from lut.table.model_identity import table_hash
from lut.table.plan_costs import CostScorer
from lut.table.store import Table
from planner.config.scenario import load_scenario
from planner.model.freefloating import FreeFloatingModel
from planner.model.target import TargetState
from planner.nlp.costs import manipulability
from planner.phases.approach import approach_spline
from planner.plan_parameters import ApproachParameters
from tests.support.cli import REPLAY_PLAN, lutgen_in_process

ROOT = Path(__file__).resolve().parents[3]
SCENARIOS = ROOT / "configs" / "scenarios"
GOLDEN = ROOT / "tests" / "data" / "ci_golden.h5"
OFF_GRID = ("--attitude", "0.9996573249755573,0,0,0.026176948307873", "--omega-deg-s", "0,0,3.8")  # phase 3°


def _scorer(name: str) -> CostScorer:
    scenario = load_scenario(SCENARIOS / f"{name}.toml")
    return CostScorer(scenario, FreeFloatingModel(scenario.robot),
                      approach_spline(scenario))


@pytest.fixture(scope="module")
def replay() -> tuple[ApproachParameters, dict]:
    doc = load_plan(REPLAY_PLAN)
    return replay_inputs(doc, "plan").parameters.approach, doc


def test_energy_term_is_the_squared_base_offset_and_the_total_its_weighted_sum(replay):
    approach, _ = replay
    row = _scorer("scenario_II_energy").score("plan", approach, 0.05)
    assert [t.name for t in row.terms] == ["approach_energy"]  # the other weights are 0: not scored
    x, z = approach.base_offset_m
    assert row.terms[0].value == pytest.approx(x * x + z * z, rel=1e-12)
    assert row.total == pytest.approx(x * x + z * z, rel=1e-12)


def test_manipulability_is_eq14_at_the_plans_own_joints_at_the_end_of_the_approach(replay):
    """The scorer evaluates the approach spline's end from the parameters alone; the plan's dense samples at
    t_f¹ (re-simulated by the planner) are the independent reference."""
    approach, doc = replay
    scorer = _scorer("scenario_II_safety")
    t = np.asarray(doc["samples"]["t"])
    end = int(np.argmin(np.abs(t - doc["phases"]["approach"][1])))
    q_end = np.asarray(doc["samples"]["q"])[end]
    expected = manipulability(np.asarray(scorer.ff.gen_jacobian(q_end)[0], dtype=float))
    row = scorer.score("plan", approach, 0.031)
    values = {t.name: t.value for t in row.terms}
    assert values["manipulability"] == pytest.approx(expected, rel=1e-6)
    assert values["min_distance"] == 0.031
    assert row.total == pytest.approx(-expected - 0.031, rel=1e-6)  # both maximised, weight 1
    perturbed = ApproachParameters(approach.params + 0.05, approach.base_offset_m, approach.start_delay_s,
                                   approach.q_tracking)
    assert abs(scorer.manipulability_end(perturbed) - expected) > 1e-4  # it reads the parameters


def test_a_feasibility_only_scenario_says_so_in_one_line_and_a_stabilization_weight_is_named():
    plain = _scorer("scenario_II")
    assert plain.feasibility_only and plain.weighted_terms == ()
    lines = cost_table((), plain, "interpolated")
    assert len(lines) == 1 and "feasibility-only" in lines[0]
    safety = _scorer("scenario_II_safety")
    assert not safety.feasibility_only and safety.unscored_weights == ()


def _relabel(table: Path, scenario_name: str) -> Path:
    """The golden table's real plans labelled as built from ``scenario_name`` (same shapes, other cost weights)."""
    scenario_path = SCENARIOS / f"{scenario_name}.toml"
    scenario = load_scenario(scenario_path)
    with h5py.File(table, "r+") as f:
        f.attrs["model_hash"] = table_hash(scenario)
        f.attrs["scenario_text"] = scenario.text
        f.attrs["scenario_path"] = os.path.relpath(scenario_path, table.parent)
    return table


@pytest.fixture(scope="module")
def safety_query(tmp_path_factory) -> tuple[Path, object, dict]:
    folder = tmp_path_factory.mktemp("optimal")
    table = folder / "safety.h5"
    table.write_bytes(GOLDEN.read_bytes())
    _relabel(table, "scenario_II_safety")
    out = folder / "plan.json"
    proc = lutgen_in_process("query", table, *OFF_GRID, "--budget-s", "1", "--out", out)
    assert proc.returncode in (0, 2), proc.stderr
    return table, proc, json.loads(out.read_text())


def test_query_prints_and_writes_its_cost_next_to_each_used_corners(safety_query):
    table, proc, doc = safety_query
    block = doc["query"]
    corners = block["corners"]
    assert len(corners) >= 2 and not block["feasibility_only"]
    assert block["cost_weights"] == {"manipulability": 1.0, "min_distance": 1.0}
    rows = block["costs"]
    assert [r["label"] for r in rows] == ["plan"] + [f"corner {c}" for c in corners]
    stored = Table.open(table).field("costs/min_distance_m")
    for corner, row in zip(corners, rows[1:], strict=True):
        assert row["min_distance"] == pytest.approx(stored[corner], rel=1e-12)
        assert row["total"] == pytest.approx(-row["manipulability"] - row["min_distance"], rel=1e-12)
    assert rows[0]["min_distance"] == pytest.approx(doc["metrics"]["costs"]["min_distance_m"], rel=1e-12)
    lines = proc.stdout.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("cost ("))
    assert "manipulability" in lines[header] and "min_distance [m]" in lines[header] and "total" in lines[header]
    assert lines[header + 1].startswith(f"plan ({block['source']})")
    for i, corner in enumerate(corners):
        assert lines[header + 2 + i].split()[:2] == ["corner", str(corner)]
        assert float(lines[header + 2 + i].split()[-1]) == pytest.approx(rows[1 + i]["total"], rel=1e-5)


def test_a_table_without_a_cost_dataset_still_answers_with_that_term_unknown(safety_query, tmp_path):
    table = tmp_path / "old.h5"
    table.write_bytes(safety_query[0].read_bytes())
    with h5py.File(table, "r+") as f:
        del f["points/costs/min_distance_m"]
    tq = TableQuery(table)
    res = tq.query(TargetState(np.array([0.9996573249755573, 0, 0, 0.026176948307873]),
                               np.radians([0.0, 0.0, 3.8])), budget_s=0.5)
    corners = [r for r in res.costs if r.label.startswith("corner")]
    assert corners and all(np.isnan(r.as_dict()["min_distance"]) for r in corners)
    assert np.isfinite(res.costs[0].total)  # the plan's own clearance comes from its verification


def test_query_of_a_feasibility_only_table_says_so(tmp_path):
    out = tmp_path / "plan.json"
    proc = lutgen_in_process("query", GOLDEN, *OFF_GRID, "--budget-s", "1", "--out", out)
    assert proc.returncode in (0, 2), proc.stderr
    cost_lines = [line for line in proc.stdout.splitlines() if line.startswith("cost")]
    assert len(cost_lines) == 1 and "feasibility-only" in cost_lines[0]
    block = json.loads(out.read_text())["query"]
    assert block["feasibility_only"] and block["costs"] == [] and block["source"] == "interpolated"
