"""A kept solver process builds a planner once per model: the same files give the same planner, an edited scenario
a new one (a kept process serves later builds, whose configs may have changed), and only the last few are kept."""

from __future__ import annotations

import shutil

from lut.solve import point_worker
from tests.support.cli import ROOT


def _copy_configs(tmp_path):
    for folder in ("scenarios", "robots", "targets"):
        shutil.copytree(ROOT / "configs" / folder, tmp_path / folder)
    return tmp_path / "scenarios" / "scenario_I.toml"


def test_the_same_files_reuse_the_planner_and_an_edit_builds_a_new_one(tmp_path, monkeypatch):
    monkeypatch.setattr(point_worker, "_PLANNERS", {})
    scenario = _copy_configs(tmp_path)
    first = point_worker._planner(str(scenario), None)
    assert point_worker._planner(str(scenario), None) is first
    scenario.write_text(scenario.read_text().replace("tol = 1.0e-6", "tol = 2.0e-6"))
    edited = point_worker._planner(str(scenario), None)
    assert edited is not first and edited.scenario.solver.tol == 2.0e-6
    limited = point_worker._planner(str(scenario), 30.0)
    assert limited.scenario.solver.max_wall_s == 30.0
    assert len(point_worker._PLANNERS) == point_worker.PLANNERS_KEPT == 2  # the first one dropped
    assert first not in point_worker._PLANNERS.values()
