"""The ``lutgen`` command line.

Errors a user can cause (bad config, option value, file, target state) are printed as one line
``error: …`` on stderr with exit code 1, never a traceback; a malformed command line (click's usage
errors) exits 64; plan and query exit 2 for an infeasible plan (:class:`lut.cli.exit_codes.ExitCode`).
Warnings (e.g. compiled Functions falling back to interpreted ones, :mod:`planner.nlp.compiled`) are one line
``warning: …`` too.
"""

from __future__ import annotations

import functools
import sys
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import click

from lut.cli.exit_codes import ExitCode
from planner.errors import LutgenError

if TYPE_CHECKING:  # imported lazily at run time: `lutgen --help` must not load the planner
    from planner.config.scenario import Scenario
    from planner.model.target import TargetState

MAX_MESSAGE_CHARS = 500  # an error quoting a huge value is cut here: one readable line


def one_line(text: str) -> str:
    """``text`` on one line (newlines become spaces), at most :data:`MAX_MESSAGE_CHARS` characters."""
    flat = " ".join(str(text).split())
    return flat if len(flat) <= MAX_MESSAGE_CHARS else flat[:MAX_MESSAGE_CHARS - 1] + "…"


def user_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn :class:`LutgenError` into a one-line message and exit code :attr:`ExitCode.BAD_INPUT`."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except LutgenError as exc:
            click.echo(f"error: {one_line(str(exc))}", err=True)
            sys.exit(ExitCode.BAD_INPUT)

    return wrapper


class LutgenGroup(click.Group):
    """The ``lutgen`` group: a malformed command line exits :attr:`ExitCode.USAGE`, never 2 (= infeasible)."""

    def make_context(self, *args: Any, **kwargs: Any) -> click.Context:
        try:
            return super().make_context(*args, **kwargs)
        except click.UsageError as exc:
            exc.exit_code = ExitCode.USAGE
            raise

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except click.UsageError as exc:
            exc.exit_code = ExitCode.USAGE
            raise


def _one_line_warning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                      line: str | None = None) -> str:
    return f"warning: {message}\n"


@click.group(cls=LutgenGroup)
@click.version_option(package_name="lutgen")
def main() -> None:
    """lutgen: plan grasps of a tumbling satellite with a free-floating 7-DOF arm.

    \b
    Workflows:
      lutgen validate SCENARIO.toml               check a scenario, its robot URDF and its target
      lutgen plan SCENARIO.toml --out plan.json   plan one grasp directly (no table)

    \b
    Exit codes: 0 done (plan/query: feasible), 1 bad input (one line "error: …"),
    2 infeasible (plan/query), 64 malformed command line.
    """
    warnings.formatwarning = _one_line_warning


@main.command()
@click.argument("scenario_path", type=click.Path(dir_okay=False))
@user_errors
def validate(scenario_path: str) -> None:
    """Load SCENARIO_PATH with its robot and target, check every field, print a summary."""
    from planner.collision.layout import scene_layout
    from planner.config.scenario import load_scenario

    sc = load_scenario(scenario_path)
    robot = sc.robot
    layout = scene_layout(robot, sc.target)
    click.echo(f"scenario   {sc.name}  ({sc.source})")
    click.echo(f"robot      {robot.urdf_path}: {len(robot.body_names)} bodies, {robot.n_joints} joints, "
               f"{robot.total_mass_kg:.1f} kg, ee frame {robot.ee_frame!r}")
    click.echo(f"target     {sc.target.name}: {sc.target.mass_kg:.1f} kg, {len(sc.target.shapes)} shapes")
    handle = "" if layout.gripper_handle is None else f"; {'-'.join(layout.gripper_handle)} may touch only at the grasp"
    click.echo(f"collision  {len(layout.pairs)} body pairs{handle}")
    click.echo("ok")


MAX_BUDGET_S = 86400.0  # a query's time budget beyond a day is a typo (s)
COST_NAMES = ("manipulability", "min_distance", "approach_energy", "attitude_disturbance", "peak_wrench")


def _floats(text: str, count: int, option: str) -> list[float]:
    from planner.errors import TargetStateError

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise TargetStateError(f"{option}: expected {count} comma-separated numbers, got {text!r}") from None
    if len(values) != count:
        raise TargetStateError(f"{option}: expected {count} comma-separated numbers, got {text!r}")
    return values


def _cost_weights(base, specs: tuple[str, ...]):  # noqa: ANN001, ANN202
    """Scenario cost weights with ``--cost name[=weight]`` overrides; ``--cost none`` = feasibility only."""
    from dataclasses import replace

    from planner.errors import ConfigError

    if not specs:
        return base
    weights = {name: 0.0 for name in COST_NAMES}
    overscale = base.overscale
    for spec in specs:
        if spec == "none":
            continue
        name, _, value = spec.partition("=")
        name = name.replace("-", "_")
        if name == "overscale":
            if not value:
                raise ConfigError("--cost", name, "needs a value: overscale=FACTOR")
            overscale = _cost_number(name, value)
            if overscale <= 0:
                raise ConfigError("--cost", name, f"must be > 0, got {value!r}")
            continue
        if name not in weights:
            raise ConfigError("--cost", name, f"unknown cost; choose from none, {', '.join(COST_NAMES)}, overscale")
        weights[name] = _cost_number(name, value) if value else 1.0
    return replace(base, **weights, overscale=overscale)


def _cost_number(name: str, text: str) -> float:
    """A finite, non-negative ``--cost`` value within the scenario file's sanity limit for ``costs.<name>``."""
    import math

    from planner.config.limits import violation
    from planner.errors import ConfigError

    try:
        value = float(text)
    except ValueError:
        raise ConfigError("--cost", name, f"must be a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise ConfigError("--cost", name, f"must be a finite number >= 0, got {text!r}")
    problem = violation(f"costs.{name}", value)
    if problem:
        raise ConfigError("--cost", name, problem)
    return value


def target_state_from_options(scenario: Scenario, attitude: str | None, omega_deg_s: str | None,
                              spin_rate_deg_s: float | None) -> TargetState:
    """The observed target state: the scenario's default, overridden by the CLI options."""
    import numpy as np

    from planner.errors import TargetStateError
    from planner.model.target import TargetState

    quat = np.asarray(scenario.target_state.attitude_wxyz)
    omega = np.asarray(scenario.target_state.omega_body_rad_s)
    if attitude is not None:
        quat = np.asarray(_floats(attitude, 4, "--attitude"))
    if omega_deg_s is not None:
        omega = np.radians(_floats(omega_deg_s, 3, "--omega-deg-s"))
    if spin_rate_deg_s is not None:
        if not np.isfinite(spin_rate_deg_s) or np.linalg.norm(omega) == 0:
            raise TargetStateError("--spin-rate-deg-s: needs a finite rate and a non-zero spin axis")
        omega = omega / np.linalg.norm(omega) * np.radians(spin_rate_deg_s)
    return TargetState(quat, omega)


@main.command()
@click.argument("scenario_path", type=click.Path(dir_okay=False))
@click.option("--spin-rate-deg-s", type=float, default=None,
              help="Spin rate (deg/s) about the scenario's (or --omega-deg-s's) spin axis.")
@click.option("--attitude", default=None, metavar="W,X,Y,Z", help="Observed target attitude (unit quaternion).")
@click.option("--omega-deg-s", default=None, metavar="X,Y,Z", help="Observed body rates (deg/s).")
@click.option("--cost", "costs", multiple=True, metavar="NAME[=WEIGHT]",
              help=f"Cost term (repeatable), overriding the scenario's: none, {', '.join(COST_NAMES)}, "
                   "overscale=FACTOR.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default=None,
              help="Write the plan JSON (lutgen.plan/1) here.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the samples as CSV.")
@click.option("--verify-step-s", type=float, default=0.02, show_default=True,
              help="Dense verification step (s).")
@user_errors
def plan(scenario_path: str, spin_rate_deg_s: float | None, attitude: str | None, omega_deg_s: str | None,
         costs: tuple[str, ...], out_path: str | None, csv_path: str | None, verify_step_s: float) -> None:
    """Plan one grasp for SCENARIO_PATH directly (no look-up table), verify it densely, export it.

    Exit code 0: feasible; 2: infeasible (the violated constraints are printed); 1: bad input.
    """
    from dataclasses import replace

    from lut.output.export import plan_document, write_csv, write_json
    from planner.config.scenario import load_scenario
    from planner.errors import LutgenError
    from planner.plan import OutOfReach, Planner
    from planner.verify.verifier import summary_lines, verify

    if not 0 < verify_step_s <= 0.02:
        raise LutgenError(f"--verify-step-s: must be in (0, 0.02], got {verify_step_s}")
    sc = load_scenario(scenario_path)
    check_plan_outputs([scenario_path, sc.robot.urdf_path, sc.target.source], out_path, csv_path)
    sc = replace(sc, costs=_cost_weights(sc.costs, costs))
    state = target_state_from_options(sc, attitude, omega_deg_s, spin_rate_deg_s)
    click.echo(f"planning {sc.name}: building the problems…", err=True)
    planner = Planner(sc)
    click.echo(f"  built in {planner.build_time_s:.1f} s; solving…", err=True)
    try:
        result = planner.plan(state)
    except OutOfReach as exc:  # proved infeasible before solving: no trajectory to verify or export
        click.echo(f"INFEASIBLE ({exc.elapsed_s:.1f} s): {exc}", err=True)
        if out_path or csv_path:
            click.echo("no plan written: there is no trajectory to export", err=True)
        sys.exit(ExitCode.INFEASIBLE)
    report = verify(result, step_s=verify_step_s)
    for line in _plan_table(result, report):
        click.echo(line)
    for note in result.notes:  # e.g. the approach re-solved, or the plan made from another grasp
        click.echo(f"note: {note}")
    for line in summary_lines(report):
        click.echo(line)
    if out_path:
        write_json(out_path, plan_document(result, report))
        click.echo(f"wrote {out_path}")
    if csv_path:
        write_csv(csv_path, result, report)
        click.echo(f"wrote {csv_path}")
    if not report.feasible:
        click.echo("INFEASIBLE: " + "; ".join(report.violations), err=True)
        sys.exit(ExitCode.INFEASIBLE)
    click.echo("FEASIBLE")


def check_plan_outputs(inputs: list, out_path: str | None, csv_path: str | None) -> None:
    """Refuse (before solving) a plan JSON or CSV path that is an input, a table, or in a missing folder."""
    from pathlib import Path

    from lut.output.paths import Output, check_outputs

    outputs = [Output(option, Path(path)) for option, path in (("--out", out_path), ("--csv", csv_path)) if path]
    check_outputs(inputs, outputs)


def _plan_table(result, report) -> list[str]:  # noqa: ANN001
    import numpy as np

    a, s = result.approach, result.stabilization
    lines = ["phase          start [s]   end [s]   solver                 iters   time [s]"]
    # phase times from the plan's timings where it has them: they include every grasp a plan tried
    t = result.timings_s
    solver = {"approach": (a.status, a.iterations, t.get("approach_s") or a.solve_time_s),
              "tracking": ("IK (Eq. 7)", "-", t.get("tracking_s", 0.0)),
              "stabilization": (s.status, s.iterations, t.get("stabilization_s") or s.solve_time_s + s.build_time_s)}
    for name, (t0, t1) in result.phases.items():
        st, it, tm = solver[name]
        lines.append(f"{name:<14} {t0:9.2f} {t1:9.2f}   {st:<22} {it!s:>5} {tm:9.2f}")
    lines.append(f"start delay {a.start_delay_s:.2f} s, base offset θ_b(0) = ({a.base_offset_m[0]:+.4f}, "
                 f"{a.base_offset_m[1]:+.4f}) m (x, z), total planning time {result.timings_s['total_s']:.1f} s")
    lines.append(f"min distance {np.min(report.min_distance_m):.4f} m over {report.pair_count} pairs; "
                 f"peak grasp torque {np.abs(report.grasp_wrench[:, 3:]).max():.3f} N·m")
    return lines


@main.command()
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
@user_errors
def build(grid_path: str, out_path: str, jobs: int, backend: str, scheduler: str | None, point_timeout_s: float,
          resume: bool, force: bool, no_progress: bool) -> None:
    """Solve every point of GRID_PATH and store the verified plans in an HDF5 look-up table.

    Every finished point goes to OUT.journal at once; after a crash or kill, rerun with --resume.
    An existing OUT is never overwritten without --force.
    """
    from lut.build.options import BuildOptions, BuildOutcome
    from lut.build.sweep import run_build

    options = BuildOptions(jobs=jobs, backend=backend, scheduler=scheduler, point_timeout_s=point_timeout_s,
                           resume=resume, force=force, progress=not no_progress)
    summary = run_build(grid_path, out_path, options)
    c = summary.counts
    if summary.outcome is BuildOutcome.ALREADY_COMPLETE:
        click.echo(f"{summary.table} is complete ({summary.n_points} points — {c['feasible']} feasible, "
                   f"{c['infeasible']} infeasible, {c['failed']} failed): nothing to resume, nothing changed")
        return
    click.echo(f"built {summary.table}: {summary.n_points} points — {c['feasible']} feasible, "
               f"{c['infeasible']} infeasible, {c['failed']} failed, {c['pending']} pending; "
               f"{summary.solved_now} solved in {summary.wall_time_s:.0f} s")
    for line in summary.failures[:10]:
        click.echo(f"  failed {line}")


@main.command()
@click.argument("table_path", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
@click.option("--plot", "plot_dir", type=click.Path(file_okay=False), default=None, metavar="DIR",
              help="Also write maps of feasibility, costs and solve time over the grid axes (PNG) to DIR.")
@user_errors
def inspect(table_path: str, as_json: bool, plot_dir: str | None) -> None:
    """Summarise a look-up table: grid, point counts, cost and solve-time statistics, model hash.

    With --plot DIR: heatmaps over two grid axes (small multiples over a third and beyond; a line plot
    for one axis) of feasibility, each cost and the solve time.
    """
    import json

    import numpy as np

    from lut.table.store import Table

    table = Table.open(table_path)
    feasible = table.status == 1

    def stats(values: np.ndarray) -> dict[str, float | None]:
        v = np.asarray(values, dtype=float)[feasible]
        v = v[np.isfinite(v)]
        if v.size == 0:
            return {"min": None, "median": None, "max": None}
        return {"min": float(v.min()), "median": float(np.median(v)), "max": float(v.max())}

    info = {
        "table": table_path, "schema_version": int(table.attrs["schema_version"]),
        "model_hash": table.model_hash, "grid_kind": table.attrs.get("grid_kind"),
        "axes": {name: [float(x) for x in values] for name, values in zip(table.axis_names, table.axis_values,
                                                                            strict=True)},
        "counts": table.counts(), "n_points": table.n_points,
        "solve_time_s": stats(table.field("solve_time_s")),
        "costs": {key: stats(table.field(f"costs/{key}")) for key in
                  ("min_distance_m", "approach_energy_m2", "peak_grasp_torque_nm")
                  if table.has_field(f"costs/{key}")},
    }
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
    for name, s in [("solve time [s]", info["solve_time_s"])] + [(k, v) for k, v in info["costs"].items()]:
        if s["min"] is not None:
            click.echo(f"{name:<22} min {s['min']:.4g}  median {s['median']:.4g}  max {s['max']:.4g}")


@main.command()
@click.argument("table_path", type=click.Path(dir_okay=False))
@click.option("--attitude", required=True, metavar="W,X,Y,Z", help="Observed target attitude (unit quaternion).")
@click.option("--omega-deg-s", required=True, metavar="X,Y,Z", help="Observed body rates (deg/s).")
@click.option("--refine", is_flag=True, help="Always run a warm-started solve after the interpolation.")
@click.option("--budget-s", type=float, default=100.0, show_default=True, help="Time budget of the query (s).")
@click.option("--scenario", "scenario_path", type=click.Path(dir_okay=False), default=None,
              help="Scenario file, if it moved since the build.")
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default=None, help="Write the plan JSON here.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), default=None, help="Also write the samples as CSV.")
@user_errors
def query(table_path: str, attitude: str, omega_deg_s: str, refine: bool, budget_s: float,
          scenario_path: str | None, out_path: str | None, csv_path: str | None) -> None:
    """Turn an observed target state into a verified plan from a look-up table.

    Exit code 0: feasible; 2: infeasible (violations printed); 1: bad input, table or state.
    """
    import numpy as np

    from lut.output.export import plan_document, write_csv, write_json
    from lut.query.table_query import TableQuery
    from planner.errors import LutgenError
    from planner.model.target import TargetState
    from planner.verify.verifier import summary_lines

    if not 0 < budget_s <= MAX_BUDGET_S:
        raise LutgenError(f"--budget-s: must be in (0, {MAX_BUDGET_S:g}] s, got {budget_s}")
    quat = _floats(attitude, 4, "--attitude")
    omega = np.radians(_floats(omega_deg_s, 3, "--omega-deg-s"))
    state = TargetState(np.asarray(quat), omega)
    check_plan_outputs([table_path, *([scenario_path] if scenario_path else [])], out_path, csv_path)
    tq = TableQuery(table_path, scenario_path)
    check_plan_outputs([table_path, tq.scenario_path, tq.scenario.robot.urdf_path, tq.scenario.target.source],
                       out_path, csv_path)
    result = tq.query(state, budget_s=budget_s, refine=refine)
    for line in _plan_table(result.plan, result.report):
        click.echo(line)
    for line in summary_lines(result.report):
        click.echo(line)
    lat = result.latency_s
    click.echo(f"source {result.source} (corners {result.corners_used}); table load {tq.load_time_s:.2f} s; "
               + ", ".join(f"{k[:-2]} {v * 1e3:.1f} ms" for k, v in lat.items()))
    if result.refine_failure:
        click.echo(f"refine did not finish: {result.refine_failure}", err=True)
    if out_path:
        write_json(out_path, plan_document(result.plan, result.report))
        click.echo(f"wrote {out_path}")
    if csv_path:
        write_csv(csv_path, result.plan, result.report)
        click.echo(f"wrote {csv_path}")
    if not result.report.feasible:
        click.echo("INFEASIBLE: " + "; ".join(result.report.violations), err=True)
        sys.exit(ExitCode.INFEASIBLE)
    click.echo("FEASIBLE")


if __name__ == "__main__":
    main()


# plot and preview live in their own module (matplotlib/plotly are imported only when they run)
from lut.cli.view import register  # noqa: E402

register(main)
