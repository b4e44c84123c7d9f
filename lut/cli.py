"""The ``lutgen`` command line.

Errors a user can cause (bad config, argument, file, target state) are printed as one line
``error: …`` on stderr with exit code 1, never a traceback.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any

import click

from planner.errors import LutgenError


def user_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn :class:`LutgenError` into a one-line message and exit code 1."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except LutgenError as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(1)

    return wrapper


@click.group()
@click.version_option(package_name="lutgen")
def main() -> None:
    """lutgen: plan grasps of a tumbling satellite with a free-floating 7-DOF arm.

    \b
    Workflows:
      lutgen validate SCENARIO.toml               check a scenario, its robot URDF and its target
      lutgen plan SCENARIO.toml --out plan.json   plan one grasp directly (no table)
    """


@main.command()
@click.argument("scenario_path", type=click.Path(dir_okay=False))
@user_errors
def validate(scenario_path: str) -> None:
    """Load SCENARIO_PATH with its robot and target, check every field, print a summary."""
    from planner.collision import default_pairs
    from planner.scenario import load_scenario

    sc = load_scenario(scenario_path)
    robot = sc.robot
    adjacent = list(zip(robot.body_names[:-1], robot.body_names[1:], strict=True))
    pairs = default_pairs(robot.body_names, adjacent, ["target"])
    click.echo(f"scenario   {sc.name}  ({sc.source})")
    click.echo(f"robot      {robot.urdf_path}: {len(robot.body_names)} bodies, {robot.n_joints} joints, "
               f"{robot.total_mass_kg:.1f} kg, ee frame {robot.ee_frame!r}")
    click.echo(f"target     {sc.target.name}: {sc.target.mass_kg:.1f} kg, {len(sc.target.shapes)} shapes")
    click.echo(f"collision  {len(pairs)} body pairs")
    click.echo("ok")


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
            overscale = float(value)
            continue
        if name not in weights:
            raise ConfigError("--cost", name, f"unknown cost; choose from none, {', '.join(COST_NAMES)}, overscale")
        try:
            weights[name] = float(value) if value else 1.0
        except ValueError:
            raise ConfigError("--cost", name, f"weight must be a number, got {value!r}") from None
    return replace(base, **weights, overscale=overscale)


def target_state_from_options(scenario, attitude: str | None, omega_deg_s: str | None,  # noqa: ANN001
                              spin_rate_deg_s: float | None):  # noqa: ANN201
    """The observed target state: the scenario's default, overridden by the CLI options."""
    import numpy as np

    from planner.errors import TargetStateError
    from planner.target import TargetState

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

    from planner.verify import summary_lines, verify

    from lut.export import plan_document, write_csv, write_json
    from planner.errors import LutgenError
    from planner.plan import Planner
    from planner.scenario import load_scenario

    if not 0 < verify_step_s <= 0.02:
        raise LutgenError(f"--verify-step-s: must be in (0, 0.02], got {verify_step_s}")
    sc = load_scenario(scenario_path)
    sc = replace(sc, costs=_cost_weights(sc.costs, costs))
    state = target_state_from_options(sc, attitude, omega_deg_s, spin_rate_deg_s)
    click.echo(f"planning {sc.name}: building the problems…", err=True)
    planner = Planner(sc)
    click.echo(f"  built in {planner.build_time_s:.1f} s; solving…", err=True)
    result = planner.plan(state)
    report = verify(result, step_s=verify_step_s)
    for line in _plan_table(result, report):
        click.echo(line)
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
        sys.exit(2)
    click.echo("FEASIBLE")


def _plan_table(result, report) -> list[str]:  # noqa: ANN001
    import numpy as np

    a, s = result.approach, result.stabilization
    lines = ["phase          start [s]   end [s]   solver                 iters   time [s]"]
    solver = {"approach": (a.status, a.iterations, a.solve_time_s),
              "tracking": ("IK (Eq. 7)", "-", result.timings_s.get("tracking_s", 0.0)),
              "stabilization": (s.status, s.iterations, s.solve_time_s + s.build_time_s)}
    for name, (t0, t1) in result.phases.items():
        st, it, tm = solver[name]
        lines.append(f"{name:<14} {t0:9.2f} {t1:9.2f}   {st:<22} {it!s:>5} {tm:9.2f}")
    lines.append(f"start delay {a.start_delay_s:.2f} s, base offset θ_b(0) = ({a.base_offset_m[0]:+.4f}, "
                 f"{a.base_offset_m[1]:+.4f}) m (x, z), total planning time {result.timings_s['total_s']:.1f} s")
    lines.append(f"min distance {np.min(report.min_distance_m):.4f} m over {report.pair_count} pairs; "
                 f"peak grasp torque {np.abs(report.grasp_wrench[:, 3:]).max():.3f} N·m")
    return lines
