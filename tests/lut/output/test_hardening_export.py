"""The exported plan: the robot named by a portable path, the whole inertia tensor, CSV columns with units,
and a write that fails in one line."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lut.output.export import csv_header, plan_document, write_json
from planner.errors import LutgenError
from tests.support.cli import ROOT, lutgen, write_golden_for_current_model

STATE = ("--attitude", "1,0,0,0", "--omega-deg-s", "0,0,3.75")  # between the golden table's points


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("export") / "golden.h5"
    write_golden_for_current_model(path)
    return path


@pytest.fixture(scope="module")
def golden_plan(table):
    """A plan and its report from the golden table's plans (interpolated, re-simulated, verified; no solve)."""
    from lut.query.table_query import TableQuery
    from planner.model.target import TargetState

    tq = TableQuery(table)
    result = tq.query(TargetState(np.array([1.0, 0, 0, 0]), np.radians([0, 0, 3.75])), budget_s=1.0)
    return result.plan, result.report


def test_query_exports_a_portable_robot_path_and_csv_units(table, tmp_path):
    plan_json, plan_csv = tmp_path / "q.json", tmp_path / "q.csv"
    proc = lutgen("query", table, *STATE, "--budget-s", "1", "--out", plan_json, "--csv", plan_csv,
                  cwd=ROOT)
    assert proc.returncode in (0, 2), proc.stderr
    doc = json.loads(plan_json.read_text())
    assert doc["robot_urdf"] == "configs/robots/chaser7.urdf"  # as the table's scenario names it, from here
    with plan_csv.open() as fh:
        header = next(csv.reader(fh))
    assert header == csv_header()
    assert header[0] == "t [s]" and "q_1 [rad]" in header and "qd_7 [rad/s]" in header
    assert "grasp_wrench_fx [N]" in header and "grasp_wrench_mz [N·m]" in header
    assert all(name.endswith("]") and " [" in name for name in header)


def test_plan_document_holds_the_full_body_frame_inertia(golden_plan):
    plan, report = golden_plan
    inertia = np.array([[5000.0, 120.0, -40.0], [120.0, 3000.0, 15.0], [-40.0, 15.0, 7000.0]])
    sc = plan.scenario
    skewed = replace(plan, scenario=replace(sc, target=replace(sc.target, inertia_body_kg_m2=inertia)))
    np.testing.assert_array_equal(np.array(plan_document(skewed, report)["target"]["inertia_kg_m2"]), inertia)


def test_an_unwritable_plan_path_is_one_error_line_and_no_temp_file(golden_plan, tmp_path):
    plan, report = golden_plan
    missing = tmp_path / "gone" / "p.json"
    with pytest.raises(LutgenError, match="cannot write"):
        write_json(missing, plan_document(plan, report))
    assert not list(tmp_path.rglob("*.tmp"))


def test_portable_path_is_never_absolute(tmp_path, monkeypatch):
    from lut.output.export import portable_path

    monkeypatch.chdir(tmp_path)
    given = ROOT / "configs" / "scenarios" / ".." / "robots" / "chaser7.urdf"
    path = portable_path(given)
    assert not Path(path).is_absolute() and ".." in path
    assert (tmp_path / path).resolve() == given.resolve()
