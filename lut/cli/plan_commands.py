"""``lutgen validate`` and ``lutgen plan``: one scenario, one target state, no table."""

from __future__ import annotations

import click

from lut.cli.options import (
    COST_NAMES,
    check_budget,
    check_plan_outputs,
    cost_weights,
    target_state_from_options,
    with_earliest_start,
)
from lut.cli.plan_output import export_and_verdict, plan_lines, refuse_without_plan
from lut.cli.user_errors import user_errors


@click.command()
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
    weights = [f"{name} {getattr(sc.costs, name):g}" for name in COST_NAMES if getattr(sc.costs, name) > 0]
    click.echo(f"costs      {', '.join(weights) or 'none (feasible plans, no optimum)'}")
    click.echo("ok")


@click.command()
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
@click.option("--budget-s", type=float, default=100.0, show_default=True,
              help="Time budget of the whole plan (s), from the command's start, retries over grasps included: a "
                   "solve still running at it ends, and the plan found by then is verified and reported.")
@click.option("--earliest-start-s", type=float, default=None,
              help="The approach starts no earlier than this (s) after the observation (default: the scenario's "
                   "phases.min_start_delay_s, 0 in the bundled ones): room to answer, look at the plan and move the "
                   "chaser to its base offset. A plan whose approach starts before its answer is refused as late.")
@click.option("--offline", is_flag=True, default=False,
              help="The state is no live observation (a study, a table's reference): the approach may start anywhere "
                   "in the window and its start is not judged against the answer's time.")
@user_errors
def plan(scenario_path: str, spin_rate_deg_s: float | None, attitude: str | None, omega_deg_s: str | None,
         costs: tuple[str, ...], out_path: str | None, csv_path: str | None, verify_step_s: float,
         budget_s: float, earliest_start_s: float | None, offline: bool) -> None:
    """Plan one grasp for SCENARIO_PATH directly (no look-up table), verify it densely, export it.

    Times count from the observation, taken to be the command's start: an approach solved then starts at least
    5 s later (the rest of the plan), and a plan answered after its approach's start is refused as late (not with
    --offline). Exit code 0: feasible and on time; 2: infeasible (the violated constraints are printed), out of
    reach, no feasible plan within --budget-s, or late; 1: bad input.
    """
    import time

    started_s = time.monotonic()  # the budget counts from here: building the problems is part of the plan
    from dataclasses import replace

    from planner.config.scenario import load_scenario
    from planner.deadline import VERIFY_RESERVE_S, Deadline
    from planner.errors import LutgenError
    from planner.plan import NoPlan, OutOfReach, Planner
    from planner.verify.verifier import verify

    deadline = Deadline.after(check_budget(budget_s), started_s).earlier(VERIFY_RESERVE_S)
    if not offline:  # a live observation: an approach solved later may not start before the answer can come
        deadline = deadline.observed(started_s)
    if not 0 < verify_step_s <= 0.02:
        raise LutgenError(f"--verify-step-s: must be in (0, 0.02], got {verify_step_s}")
    sc = load_scenario(scenario_path)
    check_plan_outputs([scenario_path, *sc.input_files], out_path, csv_path)
    sc = with_earliest_start(replace(sc, costs=cost_weights(sc.costs, costs)), earliest_start_s)
    state = target_state_from_options(sc, attitude, omega_deg_s, spin_rate_deg_s)
    click.echo(f"planning {sc.name}: building the problems…", err=True)
    planner = Planner(sc)
    click.echo(f"  built in {planner.build_time_s:.1f} s; solving…", err=True)
    try:
        if deadline.passed:  # nothing was solved, so there is nothing to verify: say so at once
            raise NoPlan(f"the time budget of {budget_s:g} s ran out while the problems were built "
                         f"({time.monotonic() - started_s:.1f} s)")
        result = planner.plan(state, deadline=deadline)
    except (OutOfReach, NoPlan) as exc:  # no trajectory to verify or export
        refuse_without_plan(exc, time.monotonic() - started_s, out_path, csv_path)
    report = verify(result, step_s=verify_step_s)
    for line in plan_lines(result, report, result.notes):  # notes: e.g. the approach re-solved, another grasp
        click.echo(line)
    export_and_verdict(result, report, out_path, csv_path, None if offline else started_s)


COMMANDS = (validate, plan)
