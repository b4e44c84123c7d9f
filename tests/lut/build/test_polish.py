"""``lutgen build --polish``: a point dearer than a neighbour by the polish ratio (or without a feasible plan) is solved
again warm from its cheaper neighbours and keeps a cheaper feasible plan; with the stand-in solver whose warm plans
stay in their warm start's minimum (its base offset, so its Eq. 16 cost ‖θ_b(0)‖²)."""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from lut.build.existing_work import journal_path
from lut.build.options import BuildOptions
from lut.build.polish import POLISH_COST_FLOOR, POLISH_RATIO, PolishTask, polish_tasks
from lut.build.sweep import prepare, run_build
from lut.table.journal import Journal
from lut.table.point_result import PointResult, PointStatus
from lut.table.store import Table
from planner.errors import LutgenError
from tests.lut.build.test_reuse import OFFSETS, _grid_file, _rate_phase, _write_coarse
from tests.support.cli import assert_one_line_error, lutgen_in_process
from tests.support.fake_build import assert_same, fake_solver_env, snapshot
from tests.support.fake_solver import solve as fake_solve

SOLVER = "tests.support.fake_solver:solve_in_warm_minimum"


@pytest.fixture(autouse=True)
def _fake_solver(monkeypatch):
    fake_solver_env(monkeypatch)


def _costs_by_point(grid, offsets=OFFSETS) -> dict[int, float]:
    return {p: float(np.sum(np.square(offsets[_rate_phase(grid, p)]))) for p in range(grid.n_points)}


def _expected_tasks(grid, costs: dict[int, float], feasible: set[int]) -> dict[int, tuple[int, ...]]:
    """Brute force, written out apart from lut.build.polish: every pair of adjacent grid points (indices one step apart
    on one axis of the 3 × 1 × 3 grid) whose cost ratio exceeds the polish ratio."""
    shape = [len(v) for v in grid.axis_values]
    out: dict[int, tuple[int, ...]] = {}
    for p in range(grid.n_points):
        ip = np.array(np.unravel_index(p, shape))
        cost_p = costs[p] if p in feasible else math.inf
        cheaper = []
        for q in sorted(feasible):
            iq = np.array(np.unravel_index(q, shape))
            if np.abs(ip - iq).sum() != 1:
                continue
            if cost_p == math.inf or 1 + (cost_p - costs[q]) / max(abs(costs[q]), POLISH_COST_FLOOR) > POLISH_RATIO:
                cheaper.append((costs[q], q))
        if cheaper:
            out[p] = tuple(q for _, q in sorted(cheaper)[:2])
    return out


def _result(point: int, status: PointStatus = PointStatus.FEASIBLE) -> PointResult:
    return PointResult(point, status)


def test_the_candidates_are_the_points_a_ratio_dearer_than_a_neighbour_cheapest_neighbours_first(tmp_path):
    _, _, grid = prepare(_grid_file(tmp_path, "g", rates=3))
    costs = _costs_by_point(grid)
    results = {p: _result(p) for p in range(grid.n_points)}
    tasks = polish_tasks(grid, results, lambda r: costs[r.point], 2)
    assert {t.point: t.neighbours for t in tasks} == _expected_tasks(grid, costs, set(range(grid.n_points)))
    # 3.5 °/s at 0° (0.09 m²): from 3.0 °/s at 0° (0.01), then the lower index of the two at 0.04 m² (3.5 °/s at 15°)
    by_point = {t.point: t for t in tasks}
    assert by_point[3] == PolishTask(3, (0, 4))
    assert 0 not in by_point  # the cheapest point of its neighbourhood


def test_a_point_without_a_feasible_plan_or_a_cost_is_dearer_than_any_and_never_a_start(tmp_path):
    _, _, grid = prepare(_grid_file(tmp_path, "g", rates=3))
    costs = _costs_by_point(grid)
    results = {p: _result(p) for p in range(grid.n_points)}
    results[4] = _result(4, PointStatus.INFEASIBLE)
    results[1] = _result(1, PointStatus.FAILED)
    costs[5] = math.nan
    tasks = {t.point: t.neighbours for t in polish_tasks(grid, results, lambda r: costs[r.point], 2)}
    assert tasks == _expected_tasks(grid, costs, set(range(grid.n_points)) - {1, 4, 5})
    assert all(1 not in nbs and 4 not in nbs and 5 not in nbs for nbs in tasks.values())
    assert {1, 4, 5} <= set(tasks)


@pytest.mark.parametrize(("cost", "neighbour", "candidate"), [
    (1.25, 1.0, False),  # exactly the ratio: kept
    (1.25 + 1e-9, 1.0, True),  # just past it
    (4e-4, 1e-9, False),  # within a quarter of the floor above a near-zero cost: alike (scenario I's ~1e-9 m²)
    (POLISH_COST_FLOOR * 0.25 + 1e-9 + 1e-6, 1e-9, True),  # just past it
    (-0.75, -1.0, False),  # Eq. 14-15 maximised: an excess of a quarter of the lowest's size
    (-0.7, -1.0, True),
])
def test_the_ratio_at_and_past_its_edge_for_positive_negative_and_near_zero_costs(tmp_path, cost, neighbour,
                                                                                 candidate):
    _, _, grid = prepare(_grid_file(tmp_path, "g", rates=2, rate_max=3.5))
    pair = {0: neighbour, 3: cost}  # 3.0 and 3.5 °/s at phase 0°: adjacent; every other point far costlier
    costs = {p: pair.get(p, 1e3) for p in range(grid.n_points)}
    tasks = {t.point: t.neighbours for t in polish_tasks(grid, {p: _result(p) for p in costs},
                                                          lambda r: costs[r.point], 2)}
    assert (tasks.get(3) == (0,)) is candidate


def _cold_offset(grid_file: Path, point: int) -> np.ndarray:
    """The stand-in solver's cold plan's base offset at ``point`` (a function of the state alone) [m]."""
    config, _, grid = prepare(grid_file)
    state = grid.state(point)
    return fake_solve(str(config.scenario_path), point, state.attitude_wxyz, state.omega_body_rad_s, None,
                      0.0)["base_offset_m"]


def _polished_build(tmp_path: Path, name: str, **options) -> tuple[Path, object]:
    coarse_grid = _grid_file(tmp_path, "coarse", rates=3)
    if not (tmp_path / "coarse.h5").exists():
        _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    out = tmp_path / f"{name}.h5"
    summary = run_build(coarse_grid, out, BuildOptions(jobs=2, solver=SOLVER, progress=False,
                                                       reuse=(str(tmp_path / "coarse.h5"),), polish=True, **options))
    return out, summary


def test_a_dearer_point_takes_its_cheaper_neighbours_plan_family_and_leaves_the_reused_sources(tmp_path):
    out, summary = _polished_build(tmp_path, "polished")
    _, _, grid = prepare(tmp_path / "coarse.toml")
    costs = _costs_by_point(grid)
    expected = _expected_tasks(grid, costs, set(range(grid.n_points)))
    table = Table.open(out)
    offsets = table.field("base_offset_m")
    assert summary.solved_now == 0 and summary.polish.improved == summary.polish.tried == len(expected) > 0
    for p in range(grid.n_points):
        # the stand-in's warm plan keeps its start's offset: a polished point holds its cheapest neighbour's
        want = OFFSETS[_rate_phase(grid, expected[p][0])] if p in expected else OFFSETS[_rate_phase(grid, p)]
        np.testing.assert_array_equal(offsets[p], want, err_msg=f"point {p}")
    (source,) = table.reused_from
    assert set(source.points) == set(range(grid.n_points)) - set(expected)


def test_a_polish_that_finds_nothing_cheaper_keeps_the_plan_and_tries_the_next_neighbour(tmp_path, monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_INFEASIBLE", "3")  # 3.5 °/s at 0°: both warm tries infeasible
    out, summary = _polished_build(tmp_path, "kept")
    table = Table.open(out)
    np.testing.assert_array_equal(table.field("base_offset_m")[3], OFFSETS[(3.5, 0.0)])
    assert table.status[3] == PointStatus.FEASIBLE.code
    assert 3 in table.reused_from[0].points
    assert summary.polish.improved == summary.polish.tried - 1


def test_an_interrupted_polish_resumes_to_the_same_table_without_polishing_a_point_twice(tmp_path):
    reference, _ = _polished_build(tmp_path, "reference")
    out = tmp_path / "interrupted.h5"
    seen: list[int] = []

    def interrupt(result: PointResult) -> None:
        seen.append(result.point)
        if len(seen) == 2:
            raise KeyboardInterrupt

    coarse = (str(tmp_path / "coarse.h5"),)
    with pytest.raises(KeyboardInterrupt):
        run_build(tmp_path / "coarse.toml", out, BuildOptions(jobs=1, solver=SOLVER, progress=False, reuse=coarse,
                                                              polish=True), interrupt)
    with Journal(journal_path(out), {"model_hash": Table.open(reference).model_hash,
                                     "grid_text": (tmp_path / "coarse.toml").read_text(), "polish": "2"}) as j:
        assert j.journaled_again() == set(seen)
    summary = run_build(tmp_path / "coarse.toml", out, BuildOptions(jobs=1, solver=SOLVER, progress=False,
                                                                    reuse=coarse, polish=True, resume=True))
    assert_same(snapshot(reference), snapshot(out))
    grid = prepare(tmp_path / "coarse.toml")[2]
    improved_before = sum(1 for p in seen if not np.array_equal(Table.open(out).field("base_offset_m")[p],
                                                                 OFFSETS[_rate_phase(grid, p)]))
    assert summary.polish.improved + improved_before == len(_expected_tasks(grid, _costs_by_point(grid),
                                                                         set(range(grid.n_points))))


@pytest.mark.parametrize("resumed", [{}, {"polish": True, "polish_cold": True}],
                         ids=["without polish", "with cold tries"])
def test_a_polishing_journal_is_resumed_only_with_the_same_polish(tmp_path, resumed):
    out = tmp_path / "p.h5"
    coarse_grid = _grid_file(tmp_path, "coarse", rates=3)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    coarse = (str(tmp_path / "coarse.h5"),)

    def interrupt(_: PointResult) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_build(coarse_grid, out, BuildOptions(jobs=1, solver=SOLVER, progress=False, reuse=coarse, polish=True),
                  interrupt)
    with pytest.raises(LutgenError, match="polish"):
        run_build(coarse_grid, out, BuildOptions(jobs=1, solver=SOLVER, progress=False, reuse=coarse, resume=True,
                                                 **resumed))


def test_the_cli_says_how_many_points_polish_improved(tmp_path, monkeypatch):
    import lut.build.options

    monkeypatch.setattr(lut.build.options, "BuildOptions", partial(BuildOptions, solver=SOLVER))
    coarse_grid = _grid_file(tmp_path, "coarse", rates=3)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    res = lutgen_in_process("build", coarse_grid, "--out", tmp_path / "cli.h5", "--reuse", tmp_path / "coarse.h5",
                            "--polish", "--no-progress")
    assert res.returncode == 0, res.stderr
    _, _, grid = prepare(coarse_grid)
    n = len(_expected_tasks(grid, _costs_by_point(grid), set(range(grid.n_points))))
    assert f"--polish: {n} of {n} points tried given a cheaper plan" in res.stdout


@pytest.mark.parametrize("tries", ["0", "-1"])
def test_fewer_than_one_try_is_refused_in_one_line_before_any_file(tmp_path, tries):
    grid = _grid_file(tmp_path, "g", rates=3)
    out = tmp_path / "t.h5"
    assert_one_line_error(lutgen_in_process("build", grid, "--out", out, "--polish", "--polish-tries", tries),
                          "--polish-tries", tries)
    assert list(tmp_path.iterdir()) == [grid]


def test_equal_costs_and_a_grid_without_a_feasible_point_give_nothing_to_polish(tmp_path):
    _, _, grid = prepare(_grid_file(tmp_path, "g", rates=3))
    alike = {p: _result(p) for p in range(grid.n_points)}
    assert polish_tasks(grid, alike, lambda r: 0.7, 2) == []
    none_feasible = {p: _result(p, PointStatus.INFEASIBLE) for p in range(grid.n_points)}
    assert polish_tasks(grid, none_feasible, lambda r: 0.7, 2) == []


def test_with_cold_each_task_tries_a_cold_plan_after_its_neighbours_and_zero_tries_leave_only_that(tmp_path):
    _, _, grid = prepare(_grid_file(tmp_path, "g", rates=3))
    costs = _costs_by_point(grid)
    results = {p: _result(p) for p in range(grid.n_points)}
    warm_only = polish_tasks(grid, results, lambda r: costs[r.point], 2)
    with_cold = polish_tasks(grid, results, lambda r: costs[r.point], 2, cold=True)
    assert [t.point for t in with_cold] == [t.point for t in warm_only]
    assert all(c.starts == w.neighbours + (None,) and w.starts == w.neighbours
               for c, w in zip(with_cold, warm_only, strict=True))
    assert [t.starts for t in polish_tasks(grid, results, lambda r: costs[r.point], 0, cold=True)] \
        == [(None,)] * len(warm_only)


def test_a_point_no_neighbour_improved_takes_its_cold_plan_when_that_is_cheaper(tmp_path, monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_INFEASIBLE", "3")  # 3.5 °/s at 0°: both warm tries infeasible
    out, summary = _polished_build(tmp_path, "cold", polish_cold=True)
    cold = _cold_offset(tmp_path / "coarse.toml", 3)
    assert np.sum(np.square(cold)) < np.sum(np.square(OFFSETS[(3.5, 0.0)]))  # the premise: the cold plan is cheaper
    table = Table.open(out)
    np.testing.assert_array_equal(table.field("base_offset_m")[3], cold)
    assert 3 not in table.reused_from[0].points
    assert summary.polish.improved == summary.polish.tried  # without --polish-cold: one fewer (the test above)


def test_zero_tries_with_cold_plans_every_candidate_cold_and_keeps_the_cheaper_plan(tmp_path):
    out, summary = _polished_build(tmp_path, "cold_only", polish_cold=True, polish_tries=0)
    grid_file = tmp_path / "coarse.toml"
    _, _, grid = prepare(grid_file)
    costs = _costs_by_point(grid)
    candidates = _expected_tasks(grid, costs, set(range(grid.n_points)))
    offsets = Table.open(out).field("base_offset_m")
    for p in range(grid.n_points):
        cold = _cold_offset(grid_file, p)
        want = cold if p in candidates and np.sum(np.square(cold)) < costs[p] else OFFSETS[_rate_phase(grid, p)]
        np.testing.assert_array_equal(offsets[p], want, err_msg=f"point {p}")
    assert summary.polish.tried == len(candidates) and 0 < summary.polish.improved


def test_the_cli_takes_zero_tries_with_polish_cold(tmp_path, monkeypatch):
    import lut.build.options

    monkeypatch.setattr(lut.build.options, "BuildOptions", partial(BuildOptions, solver=SOLVER))
    coarse_grid = _grid_file(tmp_path, "coarse", rates=3)
    _write_coarse(tmp_path / "coarse.h5", coarse_grid)
    res = lutgen_in_process("build", coarse_grid, "--out", tmp_path / "cli.h5", "--reuse", tmp_path / "coarse.h5",
                            "--polish", "--polish-tries", "0", "--polish-cold", "--no-progress")
    assert res.returncode == 0, res.stderr
    _, _, grid = prepare(coarse_grid)
    costs = _costs_by_point(grid)
    candidates = _expected_tasks(grid, costs, set(range(grid.n_points)))
    cheaper = [p for p in candidates if np.sum(np.square(_cold_offset(coarse_grid, p))) < costs[p]]
    assert f"--polish: {len(cheaper)} of {len(candidates)} points tried given a cheaper plan" in res.stdout
    assert_one_line_error(lutgen_in_process("build", coarse_grid, "--out", tmp_path / "neg.h5", "--polish",
                                            "--polish-tries", "-1", "--polish-cold"), "--polish-tries", "-1")
