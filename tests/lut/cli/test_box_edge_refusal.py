"""A plan refused with the chaser on its base-offset box's edge says so (``planner.box_edge``), in its output and its
plan file, on a state whose grasp lies beyond the bundled ±1 m box: seed 8's scenario I flat spin 5 of the coverage
section, planned offline (no clock: the same plan every run). The wider box plans it (slow)."""

from __future__ import annotations

import json

import pytest

from planner.box_edge import BOX_EDGE_NOTE
from tests.support.cli import ROOT, lutgen

STATE = ("--attitude", "0.553430711045,0.536915106362,0.440130035412,-0.460132772752",
         "--omega-deg-s", "0,3.25557664736,0", "--offline")


def test_a_plan_refused_on_the_box_edge_names_the_bound_in_its_output_and_file(tmp_path):
    out = tmp_path / "plan.json"
    proc = lutgen("plan", ROOT / "configs" / "scenarios" / "scenario_I.toml", *STATE, "--out", out)
    assert proc.returncode == 2, proc.stderr[-2000:]
    notes = [line for line in proc.stdout.splitlines() if line.startswith("note: " + BOX_EDGE_NOTE)]
    assert len(notes) == 1 and "θ_b(0) z = +1.000 m, robot.base_offset_z_m = [-1, 1]" in notes[0], proc.stdout
    metrics = json.loads(out.read_text(encoding="utf-8"))["metrics"]
    assert abs(metrics["base_offset_m"]["z"] - 1.0) < 1e-3
    assert notes[0].removeprefix("note: ") in metrics["notes"]


@pytest.mark.slow
def test_the_wide_box_plans_the_same_state_feasible_off_its_edge():
    proc = lutgen("plan", ROOT / "configs" / "scenarios" / "scenario_I_wide.toml", *STATE)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert BOX_EDGE_NOTE not in proc.stdout
