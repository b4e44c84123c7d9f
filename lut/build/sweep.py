"""``lutgen build``: solve every grid point, crash-safe, resumable, in parallel (docs/table.md, Build).

* **Order.** Points are solved in continuation layers: every point is warm-started from a solved
  neighbour (its parent in :meth:`Grid.continuation_order`), which keeps neighbours in the same local
  minimum and makes interpolation meaningful. A layer runs in parallel; the next waits for it. On a
  flat-spin grid the warm start's meeting time is shifted by the phase ↔ time symmetry.
* **Isolation.** Each point runs in its own child process (:mod:`lut.solve.point_process`) with a hard
  time limit: a point that times out or crashes its process is recorded as failed with the reason.
* **Crash safety.** Every finished point is appended to a checksummed journal beside the output at
  once; ``--resume`` skips what the journal holds. The HDF5 table is assembled at the end atomically;
  once it holds every point, the journal is removed.
* **Parallelism.** joblib: ``loky`` locally, or ``dask`` with a ``distributed`` scheduler address for
  a cluster (the workers need lutgen installed and the config files at the same paths).
* **Reuse.** ``--reuse TABLE`` (repeatable): the points the grid shares with tables already built take their
  feasible plans as they are (the cheapest where several hold one), and the warm-start tree grows from them
  (:mod:`lut.build.reuse`).
* **Cold (``--cold``).** Every point not reused is planned cold, from no neighbour: one layer, all in parallel; a
  further start whose table merges with others by ``--reuse``.
* **Polish (``--polish``).** Once every point is solved, a point dearer than an adjacent one by a factor (or without
  a feasible plan) is solved again warm from its cheaper neighbours (``--polish-cold``: then cold) and keeps a cheaper
  feasible plan (:mod:`lut.build.polish`).
* **Determinism.** Same config (and reused tables) ⇒ same warm-start tree ⇒ same table (up to points that hit
  the time limit, which depends on the machine).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from lut.build.backends import parallel_backend
from lut.build.existing_work import complete_summary, existing_work, journal_path
from lut.build.options import BuildOptions, BuildSummary, check_options
from lut.build.polish import PolishOutcome, PolishTask, polish, polish_tasks
from lut.build.progress import Progress
from lut.build.reuse import Continuation, CostOf, ReusedPlans, cheapest_reused, reuse_continuation, weighted_cost
from lut.output.paths import Output, check_outputs
from lut.solve.point_process import run_point
from lut.solve.point_server import stop_all
from lut.table.grid import Grid
from lut.table.grid_config import GridConfig, load_grid
from lut.table.journal import Journal
from lut.table.model_identity import table_hash
from lut.table.point_result import PointResult, PointStatus
from lut.table.records import from_record, to_record
from lut.table.table_writer import write_table
from planner.config.scenario import Scenario, load_scenario

if TYPE_CHECKING:
    from joblib import Parallel

OnResult = Callable[[PointResult], None]


def prepare(grid_path: str | Path) -> tuple[GridConfig, Scenario, Grid]:
    """Load and validate the grid config, its scenario, and the grid over target states."""
    config = load_grid(grid_path)
    scenario = load_scenario(config.scenario_path)
    return config, scenario, Grid(config, scenario.target.inertia_body_kg_m2, scenario.target_state.as_state())


def _build_order(grid: Grid, reused: dict[int, PointResult], cost_of: CostOf | None, cold: bool) -> Continuation:
    """Every point once with its warm-start parent: none under ``--cold`` (one layer), else grown from the reused
    points (:func:`reuse_continuation`) or from the seed point (:meth:`Grid.continuation_order`)."""
    if cold:
        return [(p, None) for p in range(grid.n_points)]
    return reuse_continuation(grid, reused, cost_of) if cost_of else grid.continuation_order()


def continuation_layers(order: Continuation) -> list[Continuation]:
    """``order`` cut into layers by depth in the warm-start tree: a layer's parents are all in earlier layers."""
    depth: dict[int, int] = {}
    layers: list[Continuation] = []
    for point, parent in order:
        d = 0 if parent is None else depth[parent] + 1
        depth[point] = d
        while len(layers) <= d:
            layers.append([])
        layers[d].append((point, parent))
    return layers


def run_build(grid_path: str | Path, table_path: str | Path, options: BuildOptions,
              on_result: OnResult | None = None) -> BuildSummary:
    """Build (or resume) the table of ``grid_path`` into ``table_path``; ``on_result`` sees every point solved.

    Everything that can refuse the build (options, configs, output paths, an existing table or journal)
    is checked before a file is created; a build that stops before its first record leaves no journal.
    """
    t_start = time.perf_counter()
    table_path = Path(table_path)
    check_options(options)
    config, scenario, grid = prepare(grid_path)
    jpath = journal_path(table_path)
    inputs = [grid_path, config.scenario_path, *scenario.input_files, *options.reuse]
    check_outputs(inputs, [Output("--out", table_path), Output("--out (its journal)", jpath)], tables_allowed=True)
    mhash = table_hash(scenario)
    cost_of = weighted_cost(scenario) if options.reuse or options.polish else None
    reused = cheapest_reused(options.reuse, grid, config.kind, mhash, cost_of) if cost_of else ReusedPlans()
    complete = existing_work(table_path, jpath, options, mhash, config)
    if complete is not None:
        return complete_summary(complete, t_start)
    order = _build_order(grid, reused.results, cost_of if options.reuse else None, options.cold)
    done, did = _journaled_sweep(grid, config, options, jpath, mhash, Sweep(order, reused.results, on_result, cost_of))
    reused = reused.kept_in(done)
    write_table(table_path, grid_axes=list(zip(grid.axis_names, grid.axis_values, strict=True)),
                grid_kind=config.kind, config_text=config.text, scenario_text=scenario.text, model_hash=mhash,
                records={p: to_record(r) for p, r in done.items()}, n_points=grid.n_points,
                scenario_path=os.path.relpath(config.scenario_path, table_path.absolute().parent),
                reused_from=reused.provenance(table_path.parent) if reused.tables else None)
    counts = {status.value: sum(1 for r in done.values() if r.status is status) for status in PointStatus}
    counts["pending"] = grid.n_points - len(done)
    if counts["pending"] == 0:
        # the table now holds every point durably; a leftover journal would only block the next build
        jpath.unlink(missing_ok=True)
    failures = [f"point {p}: {r.failure_reason}" for p, r in sorted(done.items()) if r.status is PointStatus.FAILED]
    return BuildSummary(table_path, grid.n_points, counts, did.solved, time.perf_counter() - t_start, failures,
                        reused_now=did.reused, polish=did.polish)


@dataclass(frozen=True)
class Sweep:
    """What a build solves: every point in ``order`` (with its warm-start parent), less the ``reused`` results
    taken as they are; ``on_result`` sees every point solved (and polished); ``cost_of`` scores a plan (``--reuse``,
    ``--polish``)."""

    order: Continuation
    reused: dict[int, PointResult]
    on_result: OnResult | None = None
    cost_of: CostOf | None = None


@dataclass(frozen=True)
class SweepCounts:
    """What one run of a build did: points solved, reused, and what ``--polish`` did."""

    solved: int
    reused: int
    polish: PolishOutcome


def _journaled_sweep(grid: Grid, config: GridConfig, options: BuildOptions, jpath: Path, mhash: str,
                     sweep: Sweep) -> tuple[dict[int, PointResult], SweepCounts]:
    """Open (or continue) the journal and solve what it lacks, then polish (``--polish``); a sweep that solved
    nothing leaves no journal. The results of all points, and what this run did."""
    parallel, client = parallel_backend(options)
    header = {"model_hash": mhash, "grid_text": config.text}
    if options.polish:  # a polished point's second record must not be resumed into an unpolished build
        header["polish"] = str(options.polish_tries) + ("+cold" if options.polish_cold else "")
    try:
        journal = Journal(jpath, header)
    except BaseException:
        if client is not None:
            client.close()
        raise
    try:
        done = {p: from_record(rec) for p, rec in journal.records().items()}
        reused_now = _journal_reused(journal, sweep.reused, done)
        done, solved_now = _solve_layers(grid, config, options, journal, parallel, sweep, done)
        polished = _polish(grid, config, options, journal, parallel, sweep, done) if options.polish else PolishOutcome()
        return done, SweepCounts(solved_now, reused_now, polished)
    except BaseException:
        if journal.started and not journal.records():
            journal.discard()  # nothing was solved: leave no journal that would ask for --resume
        raise
    finally:
        journal.close()
        stop_all()  # the solver processes this process kept (-j 1); a worker's end with its worker
        if client is not None:
            client.close()


def _journal_reused(journal: Journal, reused: dict[int, PointResult], done: dict[int, PointResult]) -> int:
    """Append the reused results the journal lacks (a resumed build finds them there); how many were appended."""
    new = [p for p in sorted(reused) if p not in done]
    for p in new:
        journal.append(to_record(reused[p]))
        done[p] = reused[p]
    return len(new)


def _solve_layers(grid: Grid, config: GridConfig, options: BuildOptions, journal: Journal, parallel: Parallel,
                  sweep: Sweep, done: dict[int, PointResult]) -> tuple[dict[int, PointResult], int]:
    """Solve every point ``done`` does not hold yet, layer by layer; the results of all points, and how many
    were solved now."""
    bar = Progress(len(sweep.order), sum(1 for p, _ in sweep.order if p in done), options.progress)
    solved_now = 0
    try:
        for layer in continuation_layers(sweep.order):
            for result in _solve_layer(grid, config, options, layer, done, parallel):
                journal.append(to_record(result))
                done[result.point] = result
                solved_now += 1
                if sweep.on_result is not None:
                    sweep.on_result(result)
                bar.update(result)
    finally:
        bar.close()
    return done, solved_now


def _solve_layer(grid: Grid, config: GridConfig, options: BuildOptions, layer: Continuation,
                 done: dict[int, PointResult], parallel: Parallel) -> Iterable[PointResult]:
    """The results of ``layer``'s points not ``done`` yet, as they finish; each warm-started from its parent's
    plan when that is feasible, and planned cold after a warm plan verify refuses."""
    tasks = [_point_task(grid, config, options, point, parent, done.get(parent) if parent is not None else None,
                         cold_fallback=True)
             for point, parent in layer if point not in done]
    return parallel(tasks) if tasks else ()


def _point_task(grid: Grid, config: GridConfig, options: BuildOptions, point: int, parent: int | None,
                warm: PointResult | None, cold_fallback: bool) -> object:
    """The joblib task solving ``point`` warm from ``parent``'s result ``warm`` when it is feasible (else cold)."""
    import joblib

    if warm is not None and warm.status is not PointStatus.FEASIBLE:
        warm = None
    shift = 0.0
    if warm is not None and config.kind == "flat_spin":
        # the child reaches the parent's configuration Δφ/rate earlier
        shift = grid.start_delay_shift_s(grid.coordinates(parent), grid.coordinates(point), forward_turn=True)
    # a point's plan ends before its timeout (its best plan kept, not killed), and a worker's points share one solver
    # process (its planner built once)
    return joblib.delayed(run_point)(options.solver, str(config.scenario_path), point, grid.state(point),
                                     None if warm is None else warm.parameters, shift, options.point_timeout_s,
                                     plan_budget_s=options.point_timeout_s, cold_fallback=cold_fallback,
                                     solver_kwargs=options.solver_kwargs(), keep_process=True)


def _polish(grid: Grid, config: GridConfig, options: BuildOptions, journal: Journal, parallel: Parallel,
            sweep: Sweep, done: dict[int, PointResult]) -> PolishOutcome:
    """``--polish`` (:mod:`lut.build.polish`): the candidates read from the sweep's results (each point's first
    record), less those a resumed build already polished; ``done`` gets each point's outcome."""
    assert sweep.cost_of is not None, "a polishing build scores its plans"
    swept = {p: from_record(rec) for p, rec in journal.first_records().items()}
    polished = journal.journaled_again()
    tasks: list[PolishTask] = [t for t in polish_tasks(grid, swept, sweep.cost_of, options.polish_tries,
                                                        options.polish_cold) if t.point not in polished]
    bar = Progress(len(tasks), 0, options.progress, desc="polish")

    def solve_from(pairs: list[tuple[int, int | None]]) -> Iterable[PointResult]:
        jobs = [_point_task(grid, config, options, p, nb, None if nb is None else swept[nb], cold_fallback=False)
                for p, nb in pairs]
        return parallel(jobs) if jobs else ()

    def keep(result: PointResult) -> None:
        journal.append(to_record(result))
        done[result.point] = result
        bar.update(result)
        if sweep.on_result is not None:
            sweep.on_result(result)

    try:
        return polish(tasks, swept, sweep.cost_of, solve_from, keep)
    finally:
        bar.close()
