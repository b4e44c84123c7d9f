"""``lutgen build``, ``lutgen inspect`` and ``lutgen query``: the look-up table's commands."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import click

from lut.cli import process_end
from lut.cli.options import check_budget, check_plan_outputs, parse_floats, with_earliest_start
from lut.cli.plan_output import (
    SOLVE_NOTE_PREFIX,
    cost_table,
    export_and_verdict,
    plan_lines,
    query_block,
    refuse_without_plan,
)
from lut.cli.user_errors import user_errors
from planner.errors import LutgenError

if TYPE_CHECKING:  # imported lazily at run time: `lutgen --help` must not load h5py
    from lut.query.robust_choice import RobustRequest
    from lut.query.table_query import TableQuery
    from lut.table.store import Table
    from planner.model.target import TargetState


@click.command()
@click.argument("grid_path", type=click.Path(dir_okay=False))
@click.option("--out", "out_path", type=click.Path(dir_okay=False), required=True, help="The HDF5 table to write.")
@click.option("-j", "--jobs", type=int, default=1, show_default=True, help="Points solved in parallel (loky).")
@click.option("--backend", type=click.Choice(["loky", "dask"]), default="loky", show_default=True,
              help="joblib backend; dask needs --scheduler and the 'dask' extra.")
@click.option("--scheduler", default=None, metavar="tcp://HOST:PORT", help="Dask distributed scheduler address.")
@click.option("--point-timeout", "point_timeout_s", type=float, default=900.0, show_default=True,
              help="Wall-time limit per grid point (s); a point past it is recorded as failed.")
@click.option("--resume", is_flag=True,
              help="Continue an interrupted build from its journal; a complete table is left as it is.")
@click.option("--force", is_flag=True,
              help="Build again although OUT (or an interrupted build's journal) exists; OUT is replaced only "
                   "when the new table is complete.")
@click.option("--no-progress", is_flag=True, help="No progress bar (logs, CI).")
@click.option("--robust", "robust_sigmas", default=None, metavar="ATT_DEG,RATE_DEG_S",
              help="Also record each feasible point's success probability at this 1-σ attitude (deg) and body-rate "
                   "(deg/s) error (robustness/* fields; inspect --plot maps it).")
@click.option("--robust-samples", type=int, default=20, show_default=True,
              help="With --robust: drawn true states per feasible point.")
@click.option("--cold", is_flag=True,
              help="Plan every point cold, none warm-started from a neighbour (all points independent, in parallel): "
                   "another start for a table of the cheapest plans, merged with others by --reuse.")
@click.option("--reuse", "reuse_paths", type=click.Path(dir_okay=False), multiple=True, metavar="TABLE",
              help="A table built for the same scenario (repeatable): its feasible plans at the points this grid "
                   "shares with it are taken as they are (the cheapest where several tables hold a point), and every "
                   "other point starts from the cheapest adjacent one (a finer grid grown from a coarser table).")
@click.option("--polish", is_flag=True,
              help="Once every point is solved, solve again each point whose plan costs over 1.25x an adjacent "
                   "point's (or has no feasible plan) warm from its cheapest such neighbours (--polish-tries), each "
                   "try up to --point-timeout; a cheaper feasible plan replaces it.")
@click.option("--polish-tries", type=int, default=2, show_default=True,
              help="With --polish: the cheaper neighbours tried per point, cheapest first, until one gives a cheaper "
                   "feasible plan (0: none, with --polish-cold).")
@click.option("--polish-cold", is_flag=True,
              help="With --polish: a point none of whose neighbours gave a cheaper plan is then planned cold (its own "
                   "grasp guesses, up to --point-timeout): a minimum no neighbour's warm start reaches.")
@user_errors
def build(grid_path: str, out_path: str, jobs: int, backend: str, scheduler: str | None, point_timeout_s: float,
          resume: bool, force: bool, no_progress: bool, robust_sigmas: str | None, robust_samples: int,
          cold: bool, reuse_paths: tuple[str, ...], polish: bool, polish_tries: int, polish_cold: bool) -> None:
    """Solve every point of GRID_PATH and store the verified plans in an HDF5 look-up table.

    Every finished point goes to OUT.journal at once; after a crash or kill, rerun with --resume.
    An existing OUT is never overwritten without --force.
    """
    from lut.build.options import BuildOptions, BuildOutcome
    from lut.build.sweep import run_build

    sigmas = None
    if robust_sigmas is not None:
        att_deg, rate_deg_s = parse_floats(robust_sigmas, 2, "--robust")
        sigmas = (att_deg, rate_deg_s)
    options = BuildOptions(jobs=jobs, backend=backend, scheduler=scheduler, point_timeout_s=point_timeout_s,
                           resume=resume, force=force, progress=not no_progress,
                           robust_sigmas=sigmas, robust_samples=robust_samples, cold=cold, reuse=reuse_paths,
                           polish=polish, polish_tries=polish_tries, polish_cold=polish_cold)
    summary = run_build(grid_path, out_path, options)
    c = summary.counts
    if summary.outcome is BuildOutcome.ALREADY_COMPLETE:
        click.echo(f"{summary.table} is complete ({summary.n_points} points — {c['feasible']} feasible, "
                   f"{c['infeasible']} infeasible, {c['failed']} failed): nothing to resume, nothing changed")
        return
    click.echo(f"built {summary.table}: {summary.n_points} points — {c['feasible']} feasible, "
               f"{c['infeasible']} infeasible, {c['failed']} failed, {c['pending']} pending; "
               f"{summary.solved_now} solved in {summary.wall_time_s:.0f} s"
               + (f", {summary.reused_now} reused from {', '.join(reuse_paths)}" if summary.reused_now else "")
               + (f"; --polish: {summary.polish.improved} of {summary.polish.tried} points tried given a cheaper plan"
                  if polish else ""))
    for line in summary.failures[:10]:
        click.echo(f"  failed {line}")


@click.command()
@click.argument("table_path", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Also write maps of feasibility, costs and solve time over the grid axes (PNG) to DIR.")
@user_errors
def inspect(table_path: str, as_json: bool, plot_dir: str | None) -> None:
    """Summarise a look-up table: grid, point counts, the tables a --reuse build took plans from, cost and
    solve-time statistics, model hash.

    With --plot DIR: heatmaps over two grid axes (small multiples over a third and beyond; a line plot
    for one axis) of feasibility, each cost and the solve time.
    """
    import json

    from lut.table.store import Table

    table = Table.open(table_path)
    info = _table_info(table, table_path)
    if plot_dir is not None:
        from lut.output.coverage_plots import write_coverage_maps

        try:
            info["plots"] = [str(p) for p in write_coverage_maps(table, plot_dir)]
        except OSError as exc:
            raise LutgenError(f"{plot_dir}: cannot write ({exc.strerror or exc})") from None
    if as_json:
        click.echo(json.dumps(info, indent=1))
        return
    for path in info.get("plots", []):
        click.echo(f"wrote {path}")
    click.echo(f"table      {table_path} (schema {info['schema_version']}, model {info['model_hash'][:12]}…)")
    for name, values in info["axes"].items():
        click.echo(f"axis       {name}: {len(values)} values in [{min(values):g}, {max(values):g}]")
    click.echo("points     " + ", ".join(f"{k} {v}" for k, v in info["counts"].items()) + f" (of {table.n_points})")
    for source in table.reused_from:
        click.echo(f"reused     {len(source.points)} points from {source.table} (built {source.created_utc})")
    for name, s in [("solve time [s]", info["solve_time_s"]), ("start delay [s]", info["start_delay_s"])]:
        _echo_stats(name, s)
    early = info["starting_too_soon"]
    if early is not None and early["plans"]:
        click.echo(f"too soon   {early['plans']} of {info['counts']['feasible']} feasible plans start within "
                   f"{early['within_s']:g} s of the observation: no query answers that soon, and a tumble table's "
                   "plans keep their start")
    for name, s in info["costs"].items():
        _echo_stats(name, s)


def _echo_stats(name: str, s: dict[str, float | None]) -> None:
    """One line of ``lutgen inspect``: the min, median and max of a field over the feasible points (none: no line)."""
    if s["min"] is not None:
        click.echo(f"{name:<22} min {s['min']:.4g}  median {s['median']:.4g}  max {s['max']:.4g}")


def _table_info(table: Table, table_path: str) -> dict[str, Any]:
    """What ``lutgen inspect`` reports of ``table`` (its ``--json`` document, before any plots)."""
    import numpy as np

    from lut.table.point_result import PointStatus
    from planner.deadline import QUERY_EARLIEST_START_S

    feasible = table.status == PointStatus.FEASIBLE.code
    grid_kind = table.attrs.get("grid_kind")
    start_delay_s = np.asarray(table.field("start_delay_s"), dtype=float)

    def stats(values: np.ndarray) -> dict[str, float | None]:
        v = np.asarray(values, dtype=float)[feasible]
        v = v[np.isfinite(v)]
        if v.size == 0:
            return {"min": None, "median": None, "max": None}
        return {"min": float(v.min()), "median": float(np.median(v)), "max": float(v.max())}

    return {
        "table": table_path, "schema_version": int(table.attrs["schema_version"]),
        "model_hash": table.model_hash, "grid_kind": grid_kind,
        "axes": {name: [float(x) for x in values] for name, values in zip(table.axis_names, table.axis_values,
                                                                            strict=True)},
        "counts": table.counts(), "n_points": table.n_points,
        "reused_from": [source.as_json() for source in table.reused_from],
        "solve_time_s": stats(table.field("solve_time_s")),
        "start_delay_s": stats(start_delay_s),
        # a flat-spin plan is carried to the state's phase: later for a state whose phase lags its point's
        "starting_too_soon": None if grid_kind != "tumble" else {
            "within_s": QUERY_EARLIEST_START_S,
            "plans": int(np.count_nonzero(feasible & (start_delay_s < QUERY_EARLIEST_START_S)))},
        "costs": {key: stats(table.field(f"costs/{key}")) for key in
                  ("min_distance_m", "approach_energy_m2", "peak_grasp_torque_nm")
                  if table.has_field(f"costs/{key}")},
    }


@click.command()
@click.argument("table_path", type=click.Path(dir_okay=False))
@click.option("--attitude", required=True, metavar="W,X,Y,Z", help="Observed target attitude (unit quaternion).")
@click.option("--omega-deg-s", required=True, metavar="X,Y,Z", help="Observed body rates (deg/s).")
@click.option("--refine", is_flag=True, help="Always run a warm-started solve after the interpolation.")
@click.option("--budget-s", type=float, default=100.0, show_default=True,
              help="Time budget of the whole query (s), from the command's start: table load, interpolation, "
                   "verification and every solve; a solve still running at it ends with its best plan.")
@click.option("--earliest-start-s", type=float, default=None,
              help="The approach starts no earlier than this (s) after the observation (default: the scenario's "
                   "phases.min_start_delay_s): room to look at the plan and move the chaser to its base offset. A "
                   "table plan that would start sooner starts a spin period later or is not tried; a solve's "
                   "approach starts no sooner.")
@click.option("--scenario", "scenario_path", type=click.Path(dir_okay=False), default=None,
              help="Scenario file, if it moved since the build.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default=None, help="Write the plan JSON here.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), default=None, help="Also write the samples as CSV.")
@click.option("--robust", "robust_sigmas", default=None, metavar="ATT_DEG,RATE_DEG_S",
              help="Choose, among the interpolated plan, each feasible corner's and a refined one (as the budget "
                   "allows), the plan with the best success probability at this 1-σ attitude (deg, per body axis) "
                   "and body-rate (deg/s) error.")
@click.option("--robust-samples", type=int, default=20, show_default=True,
              help="With --robust: drawn true states each candidate is executed against (the same for all).")
@click.option("--seed", type=int, default=0, show_default=True, help="With --robust: seed of the draws.")
@click.option("-j", "--jobs", type=int, default=1, show_default=True, help="With --robust: worker processes.")
@user_errors
def query(table_path: str, attitude: str, omega_deg_s: str, refine: bool, budget_s: float,
          earliest_start_s: float | None, scenario_path: str | None, out_path: str | None, csv_path: str | None,
          robust_sigmas: str | None, robust_samples: int, seed: int, jobs: int) -> None:
    """Turn an observed target state into a verified plan from a look-up table.

    With --robust, the most robust of the plans the query can produce is returned, with its success
    probability (lutgen robustness' figure). Times count from the observation, taken to be the command's start.
    Exit code 0: feasible and on time; 2: infeasible (violations printed), or late (the approach was to start
    before the answer came); 1: bad input, table or state.
    """
    import numpy as np

    from lut.query.table_query import TableQuery
    from planner.model.target import TargetState
    from planner.plan import NoPlan, OutOfReach

    started_s = time.monotonic()  # the budget counts from here: loading the table is part of the query
    check_budget(budget_s)
    quat = parse_floats(attitude, 4, "--attitude")
    omega = np.radians(parse_floats(omega_deg_s, 3, "--omega-deg-s"))
    state = TargetState(np.asarray(quat), omega)
    check_plan_outputs([table_path, *([scenario_path] if scenario_path else [])], out_path, csv_path)
    robust = _robust_request(robust_sigmas, robust_samples, seed, jobs) if robust_sigmas is not None else None
    tq = TableQuery(table_path, scenario_path)
    check_plan_outputs([table_path, tq.scenario_path, *tq.scenario.input_files],
                       out_path, csv_path)
    with_earliest_start(tq.scenario, earliest_start_s)  # checked against the table's scenario's window
    tq.earliest_start_s = earliest_start_s
    try:
        if robust is not None:
            _robust_query(tq, state, robust, budget_s, out_path, csv_path, started_s)
            return
        result = tq.query(state, budget_s=budget_s, refine=refine, since_s=started_s)
    except (OutOfReach, NoPlan) as exc:  # no table plan near it and no solve gave one: nothing to verify or export
        refuse_without_plan(exc, time.monotonic() - started_s, out_path, csv_path)
    for note in result.notes:
        click.echo(f"note: {note}; planned and verified at the observed state")
    if result.late:
        click.echo(f"note: not tried, starting too soon (before this answer could come, or --earliest-start-s): "
                   f"{'; '.join(result.late)}")
    # the solve's notes: e.g. the approach re-solved, the braking cut short, the budget ran out
    for line in plan_lines(result.plan, result.report, result.solve_notes, SOLVE_NOTE_PREFIX):
        click.echo(line)
    lat = result.latency_s
    click.echo(f"source {result.source} (corners {result.corners_used}); table load {tq.load_time_s:.2f} s; "
               + ", ".join(f"{k[:-2]} {v * 1e3:.1f} ms" for k, v in lat.items()))
    for line in cost_table(result.costs, tq.scorer, str(result.source)):
        click.echo(line)
    if result.refine_failure:
        click.echo(f"refine did not finish: {result.refine_failure}", err=True)
    export_and_verdict(result.plan, result.report, out_path, csv_path, started_s,
                       {"query": query_block(result.costs, tq.scorer, str(result.source), result.corners_used)})


def _robust_request(sigmas: str, samples: int, seed: int, jobs: int) -> RobustRequest:
    """``--robust ATT_DEG,RATE_DEG_S`` and its companions, checked."""
    import math

    from lut.query.robust_choice import RobustRequest
    from lut.robustness.error_model import ErrorModel

    att_deg, rate_deg_s = parse_floats(sigmas, 2, "--robust")
    if not all(math.isfinite(v) and v >= 0 for v in (att_deg, rate_deg_s)):
        raise LutgenError(f"--robust: both σ's must be finite numbers >= 0, got {sigmas!r}")
    for option, value in (("--robust-samples", samples), ("--jobs", jobs)):
        if value < 1:
            raise LutgenError(f"{option}: must be >= 1, got {value}")
    return RobustRequest(ErrorModel.from_sigmas(math.radians(att_deg), math.radians(rate_deg_s)), samples, seed, jobs)


def _robust_query(tq: TableQuery, state: TargetState, robust: RobustRequest, budget_s: float, out_path: str | None,
                  csv_path: str | None, started_s: float) -> None:
    """``query --robust``: every candidate judged, the chosen one printed, exported and given its verdict
    (``started_s``: the command's start, on ``time.monotonic()``'s clock)."""
    from lut.query.robust_choice import candidate_lines, robust_query

    if robust.jobs > 1:  # joblib's loky workers outlive a process that ends at once: the interpreter must end them
        process_end.END_AT_ONCE = False
    choice = robust_query(tq, state, robust, budget_s)
    chosen = choice.chosen
    for line in plan_lines(chosen.plan, chosen.report):
        click.echo(line)
    sig = robust.model.sigmas()
    click.echo(f"robust choice at 1-σ {math.degrees(sig[0]):g}° attitude, {math.degrees(sig[3]):g} °/s rate, "
               f"{robust.samples} drawn states (seed {robust.seed}); corners {choice.corners}; "
               f"{choice.elapsed_s:.1f} s")
    for line in candidate_lines(choice):
        click.echo(line)
    click.echo(f"source {chosen.source} ({chosen.label})")
    export_and_verdict(chosen.plan, chosen.report, out_path, csv_path, started_s)


COMMANDS = (build, inspect, query)
