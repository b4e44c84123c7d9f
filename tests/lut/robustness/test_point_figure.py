"""``lutgen build --robust``: a point's robustness figure is the robustness runs of its plan, it survives the
record and the table, reaches the point solver through the child process, and ``inspect --plot`` maps it."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest

from lut.output.plan_replay import replay_inputs
from lut.robustness.error_model import ErrorModel, perturbed_states, standard_draws
from lut.robustness.execution import run_one
from lut.robustness.point_figure import point_robustness
from lut.table.point_result import PointResult, PointStatus
from lut.table.records import from_record, to_record
from tests.support.cli import ROOT, lutgen_in_process, replay_plan_for_current_model, write_fake_table


def test_point_figure_counts_the_feasible_runs_of_its_draws():
    from planner.config.scenario import load_scenario
    from planner.plan import Planner

    doc = replay_plan_for_current_model()
    inputs = replay_inputs(doc, "plan")
    path = str(ROOT / inputs.scenario_file)
    planner = Planner(load_scenario(path))
    figure = point_robustness(planner, path, inputs.state, inputs.parameters, 0.05, 0.005, samples=2, seed=3)
    # the same draws (seed = the point index) run one by one
    model = ErrorModel.from_sigmas(math.radians(0.05), math.radians(0.005))
    verdicts = [run_one(planner, s, inputs.parameters, 0.02).feasible
                for s in perturbed_states(inputs.state, model, standard_draws(2, 3), 1.0)]
    assert figure["runs"] == 2 and figure["success_probability"] == sum(verdicts) / 2
    assert figure["wilson_low"] <= figure["success_probability"] <= figure["wilson_high"]
    assert (figure["attitude_sigma_deg"], figure["rate_sigma_deg_s"]) == (0.05, 0.005)


def test_figure_survives_the_record_and_a_point_without_one_has_none():
    figure = {"success_probability": 0.75, "wilson_low": 0.3, "wilson_high": 0.95, "runs": 4.0}
    result = PointResult(5, PointStatus.FEASIBLE, robustness=figure)
    assert from_record(to_record(result)).robustness == figure
    assert from_record(to_record(PointResult(6, PointStatus.FAILED, "timeout"))).robustness == {}


def test_inspect_maps_the_recorded_success(tmp_path):
    table = tmp_path / "t.h5"
    write_fake_table(table)
    with h5py.File(table, "r+") as f:  # the figure a --robust build records, at every point
        n = f["points/status"].shape[0]
        f.create_dataset("points/robustness/success_probability", data=np.linspace(0.0, 1.0, n))
    res = lutgen_in_process("inspect", table, "--plot", tmp_path / "maps")
    assert res.returncode == 0, res.stderr
    assert list((tmp_path / "maps").glob("coverage_robust_success*.png"))


@pytest.mark.slow
def test_a_robust_build_records_a_figure_at_every_feasible_point(tmp_path):
    """``lutgen build --robust``: the figure reaches the point solver through its child process and the table."""
    from lut.table.store import Table

    out = tmp_path / "ci.h5"
    res = lutgen_in_process("build", ROOT / "configs" / "grids" / "ci.toml", "--out", out, "-j", "2", "--robust",
                            "0.05,0.005", "--robust-samples", "2", "--no-progress")
    assert res.returncode == 0, res.stdout + res.stderr
    t = Table.open(out)
    feasible = t.status == PointStatus.FEASIBLE.code
    p = t.field("robustness/success_probability")
    assert feasible.any() and np.all((p[feasible] >= 0) & (p[feasible] <= 1))
    assert np.all(t.field("robustness/runs")[feasible] == 2)
    assert np.all(t.field("robustness/attitude_sigma_deg")[feasible] == 0.05)
