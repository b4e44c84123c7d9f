"""A plan file carries what re-executes it: the parameters read back re-simulate the stored trajectory, and a
file without them (or with broken ones, or for another model) is refused in one line."""

from __future__ import annotations

import copy
import gzip
import json

import numpy as np
import pytest

from lut.output.plan_file import PlanFileError, load_plan, sample_arrays
from lut.output.plan_replay import replay_inputs, resolve_scenario
from tests.support.cli import ROOT, assert_one_line_error, lutgen_in_process
from tests.support.cli import replay_plan_for_current_model as current_model_doc

DATA = ROOT / "tests" / "data"


def test_parameters_re_simulate_the_stored_samples():
    doc = current_model_doc()
    inputs = replay_inputs(doc, "plan")
    scenario = resolve_scenario(inputs, "plan")
    from planner.plan import Planner

    plan = Planner(scenario).simulate(inputs.state, inputs.parameters)
    s = sample_arrays(doc)
    # the file's samples are the plan's own at their times: a re-simulation from its parameters lands on them
    idx = np.searchsorted(plan.t, s["t"])
    assert np.allclose(plan.t[idx], s["t"], atol=1e-9)
    assert np.abs(plan.q[idx] - s["q"]).max() < 1e-9
    assert np.abs(plan.x_base[idx, :3] - s["base_position"]).max() < 1e-9


def test_a_plan_without_parameters_is_refused_with_a_hint():
    with pytest.raises(PlanFileError, match="re-export"):
        replay_inputs(load_plan(DATA / "plan_II.json.gz"), "old.json")


@pytest.mark.parametrize("key, value, words", [
    ("approach_params", "x", "parameters.approach_params"),
    ("q_tracking_rad", [1.0, 2.0], "parameters.q_tracking_rad"),
    ("start_delay_s", None, "parameters.start_delay_s"),
    ("stabilization_params", [float("nan")], "parameters.stabilization_params"),
])
def test_broken_parameters_name_the_field(key, value, words):
    doc = copy.deepcopy(current_model_doc())
    doc["parameters"][key] = value
    with pytest.raises(PlanFileError, match=words):
        replay_inputs(doc, "plan")


def test_another_model_is_refused(tmp_path):
    doc = current_model_doc()
    doc["model_hash"] = "0" * 64
    with pytest.raises(PlanFileError, match="another model"):
        resolve_scenario(replay_inputs(doc, "plan"), "plan")


def test_plot_reads_a_plan_file_with_parameters(tmp_path):
    new = tmp_path / "new.json.gz"  # older files without them: tests/lut/output/test_plots.py
    with gzip.open(new, "wt", encoding="utf-8") as fh:
        json.dump(current_model_doc(), fh)
    res = lutgen_in_process("plot", new, "-o", tmp_path / "new")
    assert res.returncode == 0, res.stderr
    assert len(list((tmp_path / "new").glob("*.png"))) >= 5
    assert_one_line_error(lutgen_in_process("plot", tmp_path / "missing.json", "-o", tmp_path / "m"), "no such")


def test_a_plans_relative_urdf_is_found_from_another_folder(tmp_path, monkeypatch):
    from lut.output.plan_file import resolve_robot_urdf

    monkeypatch.chdir(tmp_path)  # not the repository: the relative path resolves against the repository root
    found = resolve_robot_urdf({"robot_urdf": "configs/robots/chaser7.urdf"})
    assert found is not None and found == (ROOT / "configs/robots/chaser7.urdf").resolve()
    assert resolve_robot_urdf({"robot_urdf": "configs/robots/missing.urdf"}) is None
