"""A build's starts: ``--reuse`` (a finer grid takes a coarser table's feasible plans where its points coincide and
grows the rest from the cheapest adjacent one) and ``--cold`` (no warm start at all), with the fast stand-in solver,
whose plan records its warm start."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lut.build.existing_work import journal_path
from lut.build.options import BuildOptions
from lut.build.reuse import reuse_continuation
from lut.build.sweep import prepare, run_build
from lut.output.paths import OutputPathError
from lut.table.model_identity import table_hash
from lut.table.point_result import PointResult, PointStatus
from lut.table.provenance import ReusedSource
from lut.table.store import Table
from lut.table.table_writer import write_table
from planner.errors import LutgenError
from tests.support.cli import assert_one_line_error, lutgen_in_process
from tests.support.fake_build import FAKE_SOLVER as FAKE
from tests.support.fake_build import assert_same, fake_solver_env, snapshot
from tests.support.fake_solver import solve as fake_solve

ROOT = Path(__file__).resolve().parents[3]
ENERGY = ROOT / "configs/scenarios/scenario_II_energy.toml"  # Eq. 16 weighted 1: a plan's cost is ‖θ_b(0)‖²

GRID = """
name = "{name}"
scenario = "{scenario}"
kind = "flat_spin"

[[axes]]
name = "spin_rate_deg_s"
min = {rate_min}
max = {rate_max}
count = {rates}

[[axes]]
name = "spin_phase_deg"
min = 0.0
max = 30.0
count = 3
"""
# the coarse table's base offsets [m] by (rate, phase): at phase 0° the 3.0 °/s plan is the cheaper neighbour of
# 3.25 °/s, at 15° the 3.5 °/s one; at 30° the two cost the same (the lower index wins)
OFFSETS = {(3.0, 0.0): (0.1, 0.0), (3.5, 0.0): (0.3, 0.0), (4.0, 0.0): (0.2, 0.0),
           (3.0, 15.0): (0.4, 0.1), (3.5, 15.0): (0.0, 0.2), (4.0, 15.0): (0.5, 0.0),
           (3.0, 30.0): (0.3, 0.0), (3.5, 30.0): (0.0, 0.3), (4.0, 30.0): (0.1, 0.1)}


@pytest.fixture(autouse=True)
def _fake_solver(monkeypatch):
    fake_solver_env(monkeypatch)


def _grid_file(tmp_path: Path, name: str, rates: int, scenario: Path = ENERGY, rate_min: float = 3.0,
               rate_max: float = 4.0) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(GRID.format(name=name, scenario=scenario.as_posix(), rates=rates, rate_min=rate_min,
                                rate_max=rate_max))
    return path


def _write_coarse(path: Path, grid_file: Path, infeasible: tuple[float, float] | None = None,
                  offsets: dict[tuple[float, float], tuple[float, float]] = OFFSETS) -> None:
    """The coarse grid's table: the stand-in solver's cold plans with the base offsets ``offsets`` [m]."""
    config, scenario, grid = prepare(grid_file)
    records = {}
    for p in range(grid.n_points):
        state = grid.state(p)
        rec = fake_solve(str(config.scenario_path), p, state.attitude_wxyz, state.omega_body_rad_s, None, 0.0)
        rate, phase = _rate_phase(grid, p)
        rec["base_offset_m"] = np.array(offsets.get((rate, phase), (0.0, 0.0)))
        if (rate, phase) == infeasible:
            rec["status"], rec["failure_reason"] = "infeasible", "stand-in: joint 3 past its limit"
        records[p] = rec
    write_table(path, grid_axes=list(zip(grid.axis_names, grid.axis_values, strict=True)), grid_kind=config.kind,
                config_text=config.text, scenario_text=scenario.text, model_hash=table_hash(scenario),
                records=records, n_points=grid.n_points)


def _rate_phase(grid, point: int) -> tuple[float, float]:
    """The grid point's rate [°/s] and phase [°] (the spin axis is fixed at the scenario's)."""
    rate, _, phase = (float(c) for c in grid.coordinates(point))
    return rate, phase


def _coarse_point(coarse: Table, rate: float, phase: float) -> int:
    values = [coarse.axis_values[0], coarse.axis_values[2]]
    i, j = (int(np.flatnonzero(np.isclose(v, x))[0]) for v, x in zip(values, (rate, phase), strict=True))
    return int(np.ravel_multi_index((i, 0, j), [len(v) for v in coarse.axis_values]))


def _warm_parent_params(grid_file: Path, table: Table, point: int) -> np.ndarray:
    """The approach parameters the stand-in solver was warm-started from at ``point`` (it adds 1e-3 × them)."""
    config, _, grid = prepare(grid_file)
    state = grid.state(point)
    cold = fake_solve(str(config.scenario_path), point, state.attitude_wxyz, state.omega_body_rad_s, None, 0.0)
    return (table.field("approach_params")[point] - cold["approach_params"]) / 1e-3


def test_shared_points_are_taken_and_the_rest_start_from_the_cheapest_adjacent_one(tmp_path):
    coarse_grid, fine_grid = _grid_file(tmp_path, "coarse", 3), _grid_file(tmp_path, "fine", 5)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    out = tmp_path / "fine.h5"
    summary = run_build(fine_grid, out, BuildOptions(jobs=2, solver=FAKE, progress=False,
                                                     reuse=(str(tmp_path / "coarse.h5"),)))
    assert (summary.reused_now, summary.solved_now, summary.counts["feasible"]) == (9, 6, 15)
    coarse, fine = Table.open(tmp_path / "coarse.h5"), Table.open(out)
    _, _, grid = prepare(fine_grid)
    for p in range(grid.n_points):
        rate, phase = _rate_phase(grid, p)
        if rate in (3.0, 3.5, 4.0):  # shared: the coarse record bit for bit
            c = _coarse_point(coarse, rate, phase)
            for key in coarse.field_names:
                np.testing.assert_array_equal(fine.field(key)[p], coarse.field(key)[c], err_msg=f"{key} at {p}")
            continue
        below, above = rate - 0.25, rate + 0.25
        costs = {r: float(np.sum(np.square(OFFSETS[(r, phase)]))) for r in (below, above)}  # Eq. 16 by hand
        parent_rate = below if costs[below] <= costs[above] else above
        parent = coarse.field("approach_params")[_coarse_point(coarse, parent_rate, phase)]
        np.testing.assert_allclose(_warm_parent_params(fine_grid, fine, p), parent, atol=1e-9,
                                   err_msg=f"point {p} ({rate} °/s, {phase}°) not started from {parent_rate} °/s")


def test_an_infeasible_point_of_the_reused_table_is_solved_again(tmp_path):
    coarse_grid, fine_grid = _grid_file(tmp_path, "coarse", 3), _grid_file(tmp_path, "fine", 5)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid, infeasible=(3.5, 15.0))
    summary = run_build(fine_grid, tmp_path / "fine.h5", BuildOptions(jobs=1, solver=FAKE, progress=False,
                                                                      reuse=(str(tmp_path / "coarse.h5"),)))
    assert (summary.reused_now, summary.solved_now, summary.counts["feasible"]) == (8, 7, 15)


def test_of_several_tables_holding_a_point_the_cheapest_plan_is_taken(tmp_path):
    coarse_grid = _grid_file(tmp_path, "coarse", 3)
    _write_coarse(tmp_path / "a.h5", coarse_grid)
    other = {key: (0.0, 0.0) if key[1] == 15.0 else (1.0, 1.0) for key in OFFSETS}  # cheaper at 15° only
    _write_coarse(tmp_path / "b.h5", coarse_grid, offsets=other, infeasible=(4.0, 15.0))
    out = tmp_path / "merged.h5"
    summary = run_build(coarse_grid, out, BuildOptions(jobs=1, solver=FAKE, progress=False,
                                                       reuse=(str(tmp_path / "a.h5"), str(tmp_path / "b.h5"))))
    assert (summary.reused_now, summary.solved_now) == (9, 0)  # every point held: nothing solved
    merged, (_, _, grid) = Table.open(out), prepare(coarse_grid)
    for p in range(grid.n_points):
        rate, phase = _rate_phase(grid, p)
        cheaper_in_b = phase == 15.0 and rate != 4.0  # b's 4 °/s, 15° plan is infeasible: a's is taken
        expected = other[(rate, phase)] if cheaper_in_b else OFFSETS[(rate, phase)]
        np.testing.assert_array_equal(merged.field("base_offset_m")[p], expected, err_msg=f"point {p}")
    from_b = tuple(p for p in range(grid.n_points) if _rate_phase(grid, p)[1] == 15.0 and _rate_phase(grid, p)[0] < 4)
    assert merged.reused_from == (
        ReusedSource("a.h5", Table.open(tmp_path / "a.h5").attrs["created_utc"],
                     tuple(p for p in range(grid.n_points) if p not in from_b)),
        ReusedSource("b.h5", Table.open(tmp_path / "b.h5").attrs["created_utc"], from_b))


def test_inspect_names_the_reused_table_relative_to_the_new_one_and_what_was_taken(tmp_path):
    coarse_grid, fine_grid = _grid_file(tmp_path, "coarse", 3), _grid_file(tmp_path, "fine", 5)
    (tmp_path / "old").mkdir()
    _write_coarse(tmp_path / "old/coarse.h5", coarse_grid, infeasible=(3.5, 15.0))
    (tmp_path / "new").mkdir()
    out = tmp_path / "new/fine.h5"
    run_build(fine_grid, out, BuildOptions(jobs=1, solver=FAKE, progress=False,
                                           reuse=(str(tmp_path / "old/coarse.h5"),)))
    _, _, grid = prepare(fine_grid)
    taken = tuple(p for p in range(grid.n_points) if _rate_phase(grid, p)[0] in (3.0, 3.5, 4.0)
                  and _rate_phase(grid, p) != (3.5, 15.0))
    built = Table.open(tmp_path / "old/coarse.h5").attrs["created_utc"]
    assert Table.open(out).reused_from == (ReusedSource("../old/coarse.h5", built, taken),)
    result = lutgen_in_process("inspect", out)
    assert result.returncode == 0, result.stderr
    assert f"reused     8 points from ../old/coarse.h5 (built {built})" in result.stdout
    info = json.loads(lutgen_in_process("inspect", out, "--json").stdout)
    assert info["reused_from"] == [{"table": "../old/coarse.h5", "created_utc": built, "points": list(taken)}]
    plain = json.loads(lutgen_in_process("inspect", tmp_path / "old/coarse.h5", "--json").stdout)
    assert plain["reused_from"] == [] and Table.open(tmp_path / "old/coarse.h5").reused_from == ()


def test_a_reused_table_removed_during_the_build_loses_nothing(tmp_path):
    coarse_grid, fine_grid = _grid_file(tmp_path, "coarse", 3), _grid_file(tmp_path, "fine", 5)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    built = Table.open(tmp_path / "coarse.h5").attrs["created_utc"]
    summary = run_build(fine_grid, tmp_path / "fine.h5",
                        BuildOptions(jobs=1, solver=FAKE, progress=False, reuse=(str(tmp_path / "coarse.h5"),)),
                        lambda _: (tmp_path / "coarse.h5").unlink(missing_ok=True))
    assert summary.counts["feasible"] == 15 and not (tmp_path / "coarse.h5").exists()
    assert Table.open(tmp_path / "fine.h5").reused_from[0].created_utc == built


def test_an_interrupted_reusing_build_resumes_to_the_same_table(tmp_path):
    coarse_grid, fine_grid = _grid_file(tmp_path, "coarse", 3), _grid_file(tmp_path, "fine", 5)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    reuse = (str(tmp_path / "coarse.h5"),)
    reference = tmp_path / "ref.h5"
    run_build(fine_grid, reference, BuildOptions(jobs=1, solver=FAKE, progress=False, reuse=reuse))

    def interrupt(_: PointResult) -> None:
        raise KeyboardInterrupt

    out = tmp_path / "fine.h5"
    with pytest.raises(KeyboardInterrupt):
        run_build(fine_grid, out, BuildOptions(jobs=1, solver=FAKE, progress=False, reuse=reuse), interrupt)
    assert journal_path(out).exists() and not out.exists()
    summary = run_build(fine_grid, out, BuildOptions(jobs=1, solver=FAKE, progress=False, reuse=reuse, resume=True))
    assert (summary.reused_now, summary.solved_now) == (0, 5)  # the reused points and the first solved were journaled
    assert_same(snapshot(reference), snapshot(out))
    assert Table.open(out).reused_from == Table.open(reference).reused_from


def test_a_table_of_another_scenario_or_without_shared_points_is_refused_before_any_file(tmp_path):
    fine_grid = _grid_file(tmp_path, "fine", 5)
    _write_coarse(tmp_path / "other_scenario.h5", _grid_file(tmp_path, "fs", 3, scenario=ROOT /
                                                             "configs/scenarios/scenario_II.toml"))
    _write_coarse(tmp_path / "elsewhere.h5", _grid_file(tmp_path, "far", 3, rate_min=5.0, rate_max=6.0))
    cases = {"other_scenario.h5": "another robot, target or scenario", "elsewhere.h5": "none of its feasible points",
             "missing.h5": "no such table file"}
    out = tmp_path / "fine.h5"
    for name, words in cases.items():
        with pytest.raises(LutgenError, match=f"--reuse.*{words}"):
            run_build(fine_grid, out, BuildOptions(jobs=1, solver=FAKE, progress=False, reuse=(str(tmp_path / name),)))
        assert not out.exists() and not journal_path(out).exists()
    with pytest.raises(OutputPathError, match="is an input"):
        run_build(fine_grid, out, BuildOptions(jobs=1, solver=FAKE, progress=False, reuse=(str(out),)))


def test_the_cli_names_a_bad_reuse_table_in_one_line(tmp_path):
    proc = lutgen_in_process("build", _grid_file(tmp_path, "fine", 5), "--out", tmp_path / "t.h5",
                             "--reuse", tmp_path / "missing.h5", "--no-progress")
    assert_one_line_error(proc, "--reuse", "missing.h5")


def test_the_tree_grows_breadth_first_from_every_reused_point_across_the_phase_wrap(tmp_path):
    grid_file = tmp_path / "wrap.toml"
    grid_file.write_text(GRID.format(name="wrap", scenario=ENERGY.as_posix(), rates=2, rate_min=3.0, rate_max=4.0)
                         .replace("max = 30.0\ncount = 3", "max = 330.0\ncount = 12"))
    _, _, grid = prepare(grid_file)
    reused = {grid.flat_of((0, 0, 0)): PointResult(0, PointStatus.FEASIBLE)}  # 3 °/s at phase 0°, alone
    order = reuse_continuation(grid, reused, lambda _: 0.0)
    assert sorted(p for p, _ in order) == list(range(grid.n_points)) and order[0] == (grid.flat_of((0, 0, 0)), None)
    depth = {order[0][0]: 0}
    for point, parent in order[1:]:
        assert parent in depth and point in grid.neighbours(parent), (point, parent)
        depth[point] = depth[parent] + 1
    rate_i, _, phase_i = np.unravel_index(np.arange(grid.n_points), grid.shape)
    steps_round = np.minimum(phase_i, 12 - phase_i) + rate_i  # grid steps from (3 °/s, 0°), across the wrap
    assert [depth[p] for p in range(grid.n_points)] == steps_round.tolist()
    assert (grid.flat_of((0, 0, 11)), grid.flat_of((0, 0, 0))) in order  # 330° grows from 0° across the wrap


def test_the_cheapest_reused_neighbour_is_the_parent_and_a_cost_that_is_not_a_number_loses_to_any_number(tmp_path):
    _, _, grid = prepare(_grid_file(tmp_path, "fine", 5))
    a, b, c = grid.flat_of((0, 0, 1)), grid.flat_of((2, 0, 1)), grid.flat_of((1, 0, 0))  # around (3.25 °/s, 15°)
    costs = {a: float("nan"), b: 2.0, c: 1.0}
    reused = {p: PointResult(p, PointStatus.FEASIBLE) for p in costs}
    parents = dict(reuse_continuation(grid, reused, lambda r: costs[r.point]))
    assert parents[grid.flat_of((1, 0, 1))] == c  # adjacent to all three: the cheapest
    assert parents[grid.flat_of((0, 0, 0))] == c  # adjacent to a (NaN) and c
    assert parents[grid.flat_of((0, 0, 2))] == a  # adjacent to a alone: NaN is still a parent where it is the only one
    costs[c] = 2.0
    parents = dict(reuse_continuation(grid, reused, lambda r: costs[r.point]))
    assert parents[grid.flat_of((1, 0, 1))] == min(b, c)  # a tie: the lower index


def test_a_cold_build_warm_starts_no_point_and_keeps_what_it_reuses(tmp_path):
    coarse_grid, fine_grid = _grid_file(tmp_path, "coarse", 3), _grid_file(tmp_path, "fine", 5)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    cold = tmp_path / "cold.h5"
    summary = run_build(fine_grid, cold, BuildOptions(jobs=2, solver=FAKE, progress=False, cold=True))
    assert (summary.reused_now, summary.solved_now) == (0, 15)
    both = tmp_path / "both.h5"
    run_build(fine_grid, both, BuildOptions(jobs=2, solver=FAKE, progress=False, cold=True,
                                            reuse=(str(tmp_path / "coarse.h5"),)))
    cold_table, both_table, coarse = Table.open(cold), Table.open(both), Table.open(tmp_path / "coarse.h5")
    _, _, grid = prepare(fine_grid)
    for p in range(grid.n_points):
        np.testing.assert_array_equal(_warm_parent_params(fine_grid, cold_table, p), 0.0, err_msg=f"point {p}")
        rate, phase = _rate_phase(grid, p)
        if rate in (3.0, 3.5, 4.0):
            expected = coarse.field("approach_params")[_coarse_point(coarse, rate, phase)]
            np.testing.assert_array_equal(both_table.field("approach_params")[p], expected)
        else:
            np.testing.assert_array_equal(_warm_parent_params(fine_grid, both_table, p), 0.0, err_msg=f"point {p}")
