"""Running the ``lutgen`` CLI in a subprocess, and the checks every bad-input test makes of its answer."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py

from lut.build.sweep import prepare
from lut.table.model_identity import table_hash
from lut.table.table_writer import write_table
from tests.support.fake_solver import solve as fake_solve

ROOT = Path(__file__).resolve().parents[2]
CI_GRID = ROOT / "configs" / "grids" / "ci.toml"
LUTGEN = str(Path(sys.executable).parent / "lutgen")
ON_GRID_ATTITUDE = "1,0,0,0"  # scenario II's default: flat spin about body z = orbital z, phase 0
ON_GRID_OMEGA = "0,0,3.75"
ON_GRID_STATE = ("--attitude", ON_GRID_ATTITUDE, "--omega-deg-s", ON_GRID_OMEGA)


def lutgen(*args: str | Path, timeout_s: float = 300.0, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``lutgen ARGS…`` with its output captured."""
    return subprocess.run([LUTGEN, *map(str, args)], capture_output=True, text=True, timeout=timeout_s, cwd=cwd)


def lutgen_in_process(*args: str | Path) -> subprocess.CompletedProcess:
    """``lutgen ARGS…`` run by click in this process (no interpreter start-up: ~20× faster than :func:`lutgen`),
    its answer in the shape of a finished subprocess; an exception that escaped the CLI appears in ``stderr``
    as the traceback it would have printed."""
    import traceback

    from click.testing import CliRunner

    from lut.cli.main import main

    result = CliRunner().invoke(main, [str(a) for a in args], prog_name="lutgen")
    stderr = result.stderr
    if result.exc_info is not None and not isinstance(result.exception, SystemExit):
        stderr += "Traceback (most recent call last):\n" + "".join(traceback.format_exception(*result.exc_info))
    return subprocess.CompletedProcess([LUTGEN, *map(str, args)], result.exit_code, result.stdout, stderr)


def assert_one_line_error(proc: subprocess.CompletedProcess, *words: str) -> str:
    """Exit 1, no traceback, exactly one stderr line ``error: …`` holding every word; returns that line."""
    assert proc.returncode == 1, (proc.returncode, proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), proc.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def write_fake_table(path: Path, *, model_hash: str | None = None) -> None:
    """A table of ``configs/grids/ci.toml`` with the real grid, schema and model hash, its records from the
    fast stand-in solver (no NLP): good for every check made before anything is interpolated or solved."""
    config, scenario, grid = prepare(CI_GRID)
    records = {}
    for p in range(grid.n_points):
        state = grid.state(p)
        records[p] = fake_solve(str(config.scenario_path), p, state.attitude_wxyz, state.omega_body_rad_s, None, 0.0)
    write_table(path, grid_axes=list(zip(grid.axis_names, grid.axis_values, strict=True)), grid_kind=config.kind,
                config_text=config.text, scenario_text=scenario.text,
                model_hash=model_hash or table_hash(scenario), records=records, n_points=grid.n_points,
                scenario_path=os.path.relpath(config.scenario_path, path.parent))


def write_golden_for_current_model(path: Path) -> None:
    """The golden CI table's real plans, labelled with today's configs (texts and model hash), so that a query
    re-simulates and verifies them even after a deliberate config change made the golden table stale."""
    config, scenario, _ = prepare(CI_GRID)
    shutil.copy(ROOT / "tests" / "data" / "ci_golden.h5", path)
    with h5py.File(path, "r+") as f:
        f.attrs["model_hash"] = table_hash(scenario)
        f.attrs["config_text"] = config.text
        f.attrs["scenario_text"] = scenario.text
        f.attrs["scenario_path"] = os.path.relpath(config.scenario_path, path.parent)


REPLAY_PLAN = ROOT / "tests" / "data" / "plan_II_replay.json.gz"  # scenario II's default plan, with its parameters


def replay_plan_for_current_model() -> dict:
    """The stored scenario II plan (with its parameters) labelled with today's model hash, so that a deliberate
    config change does not make every re-execution test refuse it."""
    from lut.output.plan_file import load_plan
    from lut.output.plan_replay import replay_inputs
    from planner.config.scenario import load_scenario

    doc = load_plan(REPLAY_PLAN)
    doc["model_hash"] = table_hash(load_scenario(ROOT / replay_inputs(doc, "plan").scenario_file))
    return doc


def write_replay_plan_for_current_model(path: Path) -> Path:
    """:func:`replay_plan_for_current_model` written as a plan JSON file at ``path``."""
    import json

    path.write_text(json.dumps(replay_plan_for_current_model()), encoding="utf-8")
    return path
