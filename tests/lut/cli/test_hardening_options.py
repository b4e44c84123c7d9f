"""Option values and grid sizes no run can use are refused in one line before anything is computed."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support.cli import ON_GRID_STATE, ROOT, assert_one_line_error, lutgen_in_process, write_fake_table

SCENARIO_II = ROOT / "configs" / "scenarios" / "scenario_II.toml"

GRID = """
name = "big"
scenario = "{scenario}"
kind = "tumble"
{axes}
"""
AXIS = """
[[axes]]
name = "{name}"
min = 0.0
max = 10.0
count = {count}
"""


def _grid(tmp_path: Path, counts: dict[str, int]) -> Path:
    axes = "".join(AXIS.format(name=name, count=count) for name, count in counts.items())
    path = tmp_path / "grid.toml"
    path.write_text(GRID.format(scenario=SCENARIO_II.as_posix(), axes=axes))
    return path


@pytest.mark.parametrize("spec, words", [
    ("overscale=abc", ("overscale", "must be a number")),
    ("overscale=0", ("overscale", "> 0")),
    ("overscale", ("overscale", "needs a value")),
    ("min_distance=-1", ("min_distance", ">= 0")),
    ("manipulability=nan", ("manipulability", "finite")),
    ("approach_energy=1e12", ("approach_energy", "sanity limit")),
])
def test_bad_cost_options_are_refused(spec, words):
    assert_one_line_error(lutgen_in_process("plan", SCENARIO_II, "--cost", spec), "--cost", *words)


def test_ten_million_point_grid_is_refused_at_once(tmp_path):
    grid = _grid(tmp_path, {"omega_x_deg_s": 100, "omega_y_deg_s": 100, "omega_z_deg_s": 100, "yaw_deg": 10})
    line = assert_one_line_error(lutgen_in_process("build", grid, "--out", tmp_path / "t.h5"), "axes")
    assert "10000000 points" in line and "sanity limit" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["grid.toml"]


def test_huge_axis_count_is_refused(tmp_path):
    grid = _grid(tmp_path, {"omega_z_deg_s": 10**8})
    assert_one_line_error(lutgen_in_process("build", grid, "--out", tmp_path / "t.h5"), "axes[0].count",
                          "sanity limit")


@pytest.mark.parametrize("budget", ["inf", "nan", "1e9"])
def test_unusable_query_budget_is_refused(tmp_path, budget):
    table = tmp_path / "t.h5"
    write_fake_table(table)
    assert_one_line_error(lutgen_in_process("query", table, *ON_GRID_STATE, "--budget-s", budget), "--budget-s")


@pytest.mark.parametrize("budget", ["inf", "nan", "0", "-5", "1e9"])
def test_unusable_plan_budget_is_refused(budget):
    assert_one_line_error(lutgen_in_process("plan", SCENARIO_II, "--budget-s", budget), "--budget-s")
