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
      lutgen validate SCENARIO.toml     check a scenario, its robot URDF and its target
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
