"""Nothing lost: no command writes over one of its inputs, into a missing folder, or over a table.

Every refusal here comes before anything is solved (the commands answer in seconds), and the file that
would have been overwritten keeps its bytes.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.support.cli import (
    CI_GRID,
    ON_GRID_STATE,
    ROOT,
    assert_one_line_error,
    lutgen,
    lutgen_in_process,
    write_fake_table,
)

SCENARIO_II = ROOT / "configs" / "scenarios" / "scenario_II.toml"


@pytest.fixture()
def table(tmp_path: Path) -> Path:
    path = tmp_path / "ci.h5"
    write_fake_table(path)
    return path


def _configs_copy(tmp_path: Path) -> Path:
    """A copy of configs/ (the grid and scenario a test may try to overwrite)."""
    dest = tmp_path / "configs"
    shutil.copytree(ROOT / "configs", dest)
    return dest


@pytest.mark.parametrize("option", ["--out", "--csv"])
def test_query_output_onto_its_table_is_refused(table, option):
    before = table.read_bytes()
    proc = lutgen_in_process("query", table, *ON_GRID_STATE, "--budget-s", "1", option, table)
    assert_one_line_error(proc, option, "is an input")
    assert table.read_bytes() == before


def test_query_output_onto_another_table_is_refused(table, tmp_path):
    other = tmp_path / "other.h5"
    write_fake_table(other)
    before = other.read_bytes()
    proc = lutgen_in_process("query", table, *ON_GRID_STATE, "--out", other)
    assert_one_line_error(proc, "--out", "look-up table")
    assert other.read_bytes() == before


def test_plan_output_onto_its_scenario_is_refused(tmp_path):
    scenario = _configs_copy(tmp_path) / "scenarios" / "scenario_II.toml"
    before = scenario.read_bytes()
    for option in ("--out", "--csv"):
        proc = lutgen_in_process("plan", scenario, option, scenario)
        assert_one_line_error(proc, option, "is an input")
    assert scenario.read_bytes() == before


def test_plan_output_onto_its_robot_urdf_is_refused(tmp_path):
    configs = _configs_copy(tmp_path)
    urdf = configs / "robots" / "chaser7.urdf"
    before = urdf.read_bytes()
    proc = lutgen_in_process("plan", configs / "scenarios" / "scenario_II.toml", "--out", urdf)
    assert_one_line_error(proc, "is an input")
    assert urdf.read_bytes() == before


def test_plan_json_and_csv_on_one_path_are_refused(tmp_path):
    out = tmp_path / "p.json"
    proc = lutgen_in_process("plan", SCENARIO_II, "--out", out, "--csv", out)
    assert_one_line_error(proc, "--csv", "also the --out")


def test_build_output_onto_its_grid_is_refused(tmp_path):
    grid = _configs_copy(tmp_path) / "grids" / "ci.toml"
    before = grid.read_bytes()
    proc = lutgen_in_process("build", grid, "--out", grid, "--no-progress")
    assert_one_line_error(proc, "is an input")
    assert grid.read_bytes() == before
    assert not (grid.parent / "ci.toml.journal").exists()


@pytest.mark.parametrize("command", ["query", "plan", "build"])
def test_missing_output_folder_is_refused_before_computing(table, tmp_path, command):
    out = tmp_path / "nodir" / "x.out"
    args = {"query": ("query", table, *ON_GRID_STATE, "--out", out),
            "plan": ("plan", SCENARIO_II, "--csv", out),
            "build": ("build", CI_GRID, "--out", out, "--no-progress")}[command]
    proc = lutgen_in_process(*args)
    assert_one_line_error(proc, "does not exist")
    assert not out.parent.exists()


def test_read_only_output_folder_is_refused(table, tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        if _can_write(folder):
            pytest.skip("running as a user who writes anywhere (root)")
        proc = lutgen_in_process("query", table, *ON_GRID_STATE, "--out", folder / "q.json")
        assert_one_line_error(proc, "not writable")
    finally:
        folder.chmod(0o700)


def _can_write(folder: Path) -> bool:
    try:
        (folder / "probe").write_text("")
    except OSError:
        return False
    (folder / "probe").unlink()
    return True


def test_build_onto_an_existing_table_refuses_and_keeps_it(table):
    before = table.read_bytes()
    proc = lutgen_in_process("build", CI_GRID, "--out", table, "--no-progress")
    assert_one_line_error(proc, "exists", "--force")
    assert table.read_bytes() == before
    assert not table.with_name(table.name + ".journal").exists()


def test_resume_of_a_complete_table_says_so_and_changes_nothing(table):
    before, mtime = table.read_bytes(), table.stat().st_mtime_ns
    proc = lutgen_in_process("build", CI_GRID, "--out", table, "--resume", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert "is complete" in proc.stdout and "nothing changed" in proc.stdout
    assert table.read_bytes() == before and table.stat().st_mtime_ns == mtime
    assert not table.with_name(table.name + ".journal").exists()


def test_resume_of_a_table_of_another_grid_is_refused(table, tmp_path):
    grid = tmp_path / "grid.toml"
    grid.write_text(CI_GRID.read_text().replace("count = 2                                     # {0, 20}",
                                                "count = 3") .replace("max = 20.0", "max = 40.0")
                    .replace("../scenarios/", (ROOT / "configs" / "scenarios").as_posix() + "/"))
    before = table.read_bytes()
    proc = lutgen_in_process("build", grid, "--out", table, "--resume", "--no-progress")
    assert_one_line_error(proc, "another grid config", "--force")
    assert table.read_bytes() == before


def test_resume_and_force_together_are_refused(table):
    proc = lutgen_in_process("build", CI_GRID, "--out", table, "--resume", "--force")
    assert_one_line_error(proc, "--resume and --force")


@pytest.mark.parametrize("args", [("build",), ("plan", "x.toml", "--no-such-option"), ("no-such-command",),
                                  ("query", "t.h5", "--attitude", "1,0,0,0")])
def test_usage_errors_do_not_exit_2_which_means_infeasible(args):
    proc = lutgen_in_process(*args)
    assert proc.returncode == 64, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr and "Usage:" in proc.stderr


def test_the_installed_command_exits_64_on_a_usage_error():
    proc = lutgen("query", "t.h5", "--attitude", "1,0,0,0", timeout_s=60)
    assert proc.returncode == 64 and "Missing option '--omega-deg-s'" in proc.stderr, proc.stderr


def test_preview_onto_its_plan_is_refused(tmp_path):
    plan = tmp_path / "plan.json.gz"
    shutil.copy(ROOT / "tests" / "data" / "plan_I.json.gz", plan)
    before = plan.read_bytes()
    proc = lutgen_in_process("preview", plan, "-o", plan)
    assert_one_line_error(proc, "is an input")
    assert plan.read_bytes() == before
