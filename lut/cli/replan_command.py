"""``lutgen replan``: a newer estimate of the target's state, the previous plan as the warm start → a plan
continuous with the one already started (docs/table.md, Re-plan)."""

from __future__ import annotations

import click

from lut.cli.options import MAX_BUDGET_S, check_plan_outputs, parse_floats
from lut.cli.plan_output import SOLVE_NOTE_PREFIX, export_and_verdict, plan_lines
from lut.cli.user_errors import user_errors
from planner.errors import LutgenError


@click.command()
@click.argument("plan_path", type=click.Path(dir_okay=False))
@click.option("--attitude", required=True, metavar="W,X,Y,Z",
              help="The new estimate's target attitude (unit quaternion).")
@click.option("--omega-deg-s", required=True, metavar="X,Y,Z", help="The new estimate's body rates (deg/s).")
@click.option("--since-s", type=float, required=True,
              help="When the new estimate's state holds: seconds after the previous plan's observation; must be "
                   "before the previous approach starts.")
@click.option("--budget-s", type=float, default=100.0, show_default=True, help="Time budget of the re-plan (s).")
@click.option("--scenario", "scenario_path", type=click.Path(dir_okay=False), default=None,
              help="Scenario file, if it moved since the plan was made (its model must be the plan's).")
@click.option("--out", "out_path", type=click.Path(dir_okay=False), default=None, help="Write the new plan JSON here.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False), default=None, help="Also write the samples as CSV.")
@user_errors
def replan(plan_path: str, attitude: str, omega_deg_s: str, since_s: float, budget_s: float,
           scenario_path: str | None, out_path: str | None, csv_path: str | None) -> None:
    """Re-plan PLAN_PATH's grasp for a newer estimate of the target's state that arrived while the chaser
    waits: warm-started from the previous plan, with the base offset it already holds pinned. The new plan's
    times count from the new estimate.

    Exit code 0: feasible; 2: infeasible (violations printed), or late (its approach starts before this
    answer, counted from the command's start); 1: bad input, or the approach has begun.
    """
    import time

    import numpy as np

    started_s = time.monotonic()  # the new estimate's instant: the new plan's times count from here
    from lut.output.plan_file import load_plan
    from lut.output.plan_replay import replay_inputs, resolve_scenario
    from lut.query.replan import replan as run_replan
    from planner.model.target import TargetState

    if not 0 < budget_s <= MAX_BUDGET_S:
        raise LutgenError(f"--budget-s: must be in (0, {MAX_BUDGET_S:g}] s, got {budget_s}")
    state = TargetState(np.asarray(parse_floats(attitude, 4, "--attitude")),
                        np.radians(parse_floats(omega_deg_s, 3, "--omega-deg-s")))
    inputs = replay_inputs(load_plan(plan_path), plan_path)
    scenario = resolve_scenario(inputs, plan_path, scenario_path)
    check_plan_outputs([plan_path, scenario.source, scenario.robot.urdf_path, scenario.target.source], out_path,
                       csv_path)
    result = run_replan(scenario, inputs.parameters, state, since_s, budget_s, started_s)
    for line in plan_lines(result.plan, result.report, result.solve_notes, SOLVE_NOTE_PREFIX):
        click.echo(line)
    x, z = result.plan.approach.base_offset_m
    click.echo(f"re-planned from {plan_path} ({result.source}): base offset kept at ({x:+.4f}, {z:+.4f}) m; the "
               f"approach starts {result.start_shift_s:+.3f} s from the previous schedule ({result.solve_s:.1f} s)")
    if result.solve_failure:
        click.echo(f"re-solve gave no feasible plan: {result.solve_failure}", err=True)
    export_and_verdict(result.plan, result.report, out_path, csv_path, started_s)


COMMANDS = (replan,)
