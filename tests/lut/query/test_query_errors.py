"""``lutgen query`` refuses bad input in one line with a non-zero exit, never a traceback.

The table here is written directly from the fast stand-in solver's records (no NLP): every error below
is raised before anything is interpolated or solved, so the records' values do not matter, only the
table's grid, schema and model hash, which are the real ones of ``configs/grids/ci.toml``.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.support.cli import ON_GRID_ATTITUDE, ON_GRID_OMEGA, ROOT, assert_one_line_error, lutgen, write_fake_table


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("query") / "ci.h5"
    write_fake_table(path)
    return path


def _query(table: Path, *args: str) -> subprocess.CompletedProcess:
    return lutgen("query", table, *args)


def test_state_outside_the_grid_is_planned_from_the_nearest_grid_state_and_says_so(table):
    """Not refused: the table answers at the grid's edge, the plan is simulated and verified at the observed
    state (here the stand-in records make it infeasible: exit 2, no refine in a 1 s budget)."""
    proc = _query(table, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", "0,0,4.4", "--budget-s", "1")
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "error:" not in proc.stderr
    assert ("note: outside the grid: spin_rate_deg_s = 4.4 not in [3.5, 4]; the table answers at 4; planned and "
            "verified at the observed state") in proc.stdout


def test_state_beyond_what_the_tables_plans_carry_is_solved_at_once_and_says_so(table):
    """2 °/s beyond the grid's rates: no table plan is tried; with no time to solve in a 1 s budget there is no plan
    at all (exit 2, never the exit 1 of bad input), and the answer names the nearest point and the carry."""
    proc = _query(table, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", "0,0,6", "--budget-s", "1")
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "error:" not in proc.stderr
    assert "beyond what a flat-spin plan carries (30°, 0.5 °/s): its plans not tried" in proc.stdout + proc.stderr
    assert "2.00 °/s" in proc.stdout + proc.stderr


def test_a_state_a_little_off_the_flat_spin_family_is_planned_and_says_so(table):
    """An estimator's flat spin: 0.3° of tilt out of the orbital plane and 0.03 °/s of transverse body rate."""
    tilt = np.radians(0.3)
    attitude = ",".join(repr(float(v)) for v in (np.cos(tilt / 2), np.sin(tilt / 2), 0.0, 0.0))
    proc = _query(table, "--attitude", attitude, "--omega-deg-s", "0.03,0,3.75", "--budget-s", "1")
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "error:" not in proc.stderr
    assert "note: not a flat spin about the major principal axis" in proc.stdout
    assert "the table answers at the nearest state of its family" in proc.stdout


@pytest.mark.parametrize("option,value,words", [
    ("--omega-deg-s", "0,0,nan", ("finite",)),
    ("--omega-deg-s", "0,0,inf", ("finite",)),
    ("--attitude", "1,0.2,0,0", ("unit", "norm")),
    ("--attitude", "1,0,0", ("--attitude", "4")),
])
def test_bad_target_state_is_refused(table, option, value, words):
    args = {"--attitude": ON_GRID_ATTITUDE, "--omega-deg-s": ON_GRID_OMEGA, option: value}
    proc = _query(table, *[x for kv in args.items() for x in kv])
    assert_one_line_error(proc, *words)


def test_table_built_for_another_model_is_refused(tmp_path):
    path = tmp_path / "other.h5"
    write_fake_table(path, model_hash="0" * 64)
    proc = _query(path, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA)
    assert_one_line_error(proc, "another robot/target/scenario", "000000000000")


def test_a_scenario_other_than_the_tables_is_refused(table):
    proc = _query(table, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA,
                  "--scenario", str(ROOT / "configs" / "scenarios" / "scenario_I.toml"))
    assert_one_line_error(proc, "another robot/target/scenario")


def test_truncated_table_is_refused(table, tmp_path):
    data = table.read_bytes()
    cut = tmp_path / "cut.h5"
    cut.write_bytes(data[: len(data) // 2])
    proc = _query(cut, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA)
    assert_one_line_error(proc, str(cut), "corrupt")


def test_garbage_file_is_refused(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"this is not an HDF5 file\n" * 100)
    proc = _query(bad, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA)
    assert_one_line_error(proc, str(bad))


def test_unknown_schema_version_is_refused(table, tmp_path):
    newer = tmp_path / "newer.h5"
    newer.write_bytes(table.read_bytes())
    with h5py.File(newer, "r+") as f:
        f.attrs["schema_version"] = 99
    proc = _query(newer, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA)
    assert_one_line_error(proc, "schema version 99")


def test_missing_table_is_refused(tmp_path):
    proc = _query(tmp_path / "nope.h5", "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA)
    assert_one_line_error(proc, "no such table")


def test_non_positive_budget_is_refused(table):
    proc = _query(table, "--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA, "--budget-s", "0")
    assert_one_line_error(proc, "--budget-s")
