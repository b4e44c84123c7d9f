"""``build``: throughput of the table-build harness with the fake point solver (``-j 1``, ``-j 2``, Dask on
2 loopback workers), and what the golden table's real per-point solve times imply."""

from __future__ import annotations

import heapq
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from bench_sections.common import (
    FAKE_SOLVER,
    GOLDEN_TABLE,
    ROOT,
    SCENARIOS,
    Settings,
    environment,
    relative,
    skipped,
    stats,
    table_query,
)
from lut.build.options import BuildOptions
from lut.build.sweep import continuation_layers, prepare, run_build  # the builder's own layering

BACKEND_KEYS = ("wall_s", "points_per_hour", "feasible")


def _grid_file(directory: Path, shape: tuple[int, int]) -> Path:
    """A flat-spin grid of scenario II, ``shape`` = (rate count, phase count), rates up to the default 4 °/s."""
    n_rate, n_phase = shape
    path = directory / "bench_grid.toml"
    path.write_text(f'name = "bench"\nscenario = "{(SCENARIOS / "scenario_II.toml").as_posix()}"\n'
                    'kind = "flat_spin"\n'
                    f'[[axes]]\nname = "spin_rate_deg_s"\nmin = {4.0 - 0.25 * (n_rate - 1)}\nmax = 4.0\n'
                    f'count = {n_rate}\n'
                    f'[[axes]]\nname = "spin_phase_deg"\nmin = 0.0\nmax = {10.0 * max(n_phase - 1, 0)}\n'
                    f'count = {n_phase}\n')
    return path


def _layer_sizes(grid_path: Path) -> list[int]:
    """Points per continuation layer: a layer runs in parallel, the next waits for it."""
    _, _, grid = prepare(grid_path)
    return [len(layer) for layer in continuation_layers(grid.continuation_order())]


def _fresh_loky_workers() -> None:
    """loky keeps its workers between builds with the environment they started with; the fake solver's
    variables must reach the point processes, and no worker may outlive the benchmark."""
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True, kill_workers=True)


def _measure(grid: Path, out_dir: Path, options: BuildOptions, runs: int, n_points: int) -> dict[str, Any]:
    """``runs`` builds of ``grid``: wall time (s), points/hour from the median, feasible count."""
    walls, feasible = [], 0
    for k in range(runs):
        _fresh_loky_workers()
        summary = run_build(grid, out_dir / f"{options.backend}-{options.jobs}-{k}.h5", options)
        walls.append(summary.wall_time_s)
        feasible = summary.counts["feasible"]
    wall = stats(walls)
    return {"wall_s": wall, "points_per_hour": 3600.0 * n_points / wall["median"], "feasible": feasible}


def _dask(grid: Path, out_dir: Path, runs: int, n_points: int) -> dict[str, Any]:
    """The Dask backend on a LocalCluster of 2 single-threaded worker processes on loopback."""
    try:
        import distributed
    except ImportError:
        return skipped("distributed is not installed (pip install -e '.[dask]')", BACKEND_KEYS)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        options = BuildOptions(backend="dask", scheduler=cluster.scheduler_address, solver=FAKE_SOLVER,
                               progress=False)
        return _measure(grid, out_dir, options, runs, n_points)


def _two_core_makespan(point_s: list[float], layers: list[int]) -> float:
    """Wall time (s) of layered list scheduling on 2 workers: each layer's points go, in order, to the
    worker free first (how joblib dispatches), and the next layer waits for the slowest."""
    total, i = 0.0, 0
    for size in layers:
        free = [0.0, 0.0]
        for t in point_s[i:i + size]:
            heapq.heappush(free, heapq.heappop(free) + t)
        total += max(free)
        i += size
    return total


def estimated_real(overhead_per_point_s: float) -> dict[str, Any]:
    """Points/hour on 1 and 2 cores from the golden table's recorded per-point solve times (plus the
    harness overhead measured here), on the golden table's own grid and continuation layers."""
    tq = table_query(GOLDEN_TABLE)
    solve = tq.table.field("solve_time_s")
    order = tq.grid.continuation_order()
    point_s = [float(solve[p]) + overhead_per_point_s for p, _ in order]
    if not all(math.isfinite(t) for t in point_s):
        return skipped(f"{relative(GOLDEN_TABLE)} lacks a solve time for some point")
    layers = [len(layer) for layer in continuation_layers(order)]
    n = len(point_s)
    return {"source": f"{relative(GOLDEN_TABLE)} points/solve_time_s (planner total_s per point, as built)",
            "points": n, "solve_time_s": stats(solve), "harness_overhead_per_point_s": overhead_per_point_s,
            "points_per_hour_1_core": 3600.0 * n / sum(point_s),
            "points_per_hour_2_cores": 3600.0 * n / _two_core_makespan(point_s, layers),
            "points_per_hour_2_cores_unlayered": 2 * 3600.0 * n / sum(point_s),
            "notes": "2 cores: the recorded times list-scheduled layer by layer on 2 workers (the golden grid's "
                     "layers allow little parallelism); unlayered: a large grid, perfect scaling"}


def builds(settings: Settings) -> dict[str, Any]:
    """The whole section."""
    # the point processes import tests.support.fake_solver from the repository root
    pythonpath = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    with (tempfile.TemporaryDirectory(prefix="lutgen-bench-") as tmp,
          environment(PYTHONPATH=pythonpath, LUTGEN_FAKE_SLEEP_S=str(settings.fake_point_s))):
        out_dir = Path(tmp)
        grid = _grid_file(out_dir, settings.build_grid)
        layers = _layer_sizes(grid)
        n = sum(layers)
        shape = settings.build_grid
        res: dict[str, Any] = {
            "grid": f"flat spin of scenario II, {shape[0]} rates x {shape[1]} phases",
            "points": n, "layer_sizes": layers, "fake_point_s": settings.fake_point_s,
            "solver": FAKE_SOLVER, "runs": settings.build_runs}
        for jobs in (1, 2):
            options = BuildOptions(jobs=jobs, solver=FAKE_SOLVER, progress=False)
            res[f"loky_j{jobs}"] = _measure(grid, out_dir, options, settings.build_runs, n)
        res["dask_2_workers"] = _dask(grid, out_dir, settings.build_runs, n)
        _fresh_loky_workers()
    j1 = res["loky_j1"]["points_per_hour"]
    # the continuation layers cap the speed-up below 2 whatever the harness does
    res["ideal_speedup_j2"] = n / sum(math.ceil(size / 2) for size in layers)
    res["scaling_efficiency_j2"] = res["loky_j2"]["points_per_hour"] / (2 * j1)
    dask_pph = res["dask_2_workers"]["points_per_hour"]
    res["scaling_efficiency_dask"] = None if dask_pph is None else dask_pph / (2 * j1)
    res["harness_overhead_per_point_s"] = max(3600.0 / j1 - settings.fake_point_s, 0.0)
    res["estimated_real"] = estimated_real(res["harness_overhead_per_point_s"])
    return res
