"""``lutgen plot`` and ``lutgen preview``: look at a plan JSON before it runs (figures, 3D page).

Errors a user causes (missing file, not JSON, another schema, a robot URDF that cannot be found) print one
line and exit 1 (:mod:`lut.cli.user_errors`). matplotlib, plotly and pinocchio are imported only when a
command runs.
"""

from __future__ import annotations

import click

from lut.cli.user_errors import user_errors, write_error


@click.command()
@click.argument("plan_path", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_dir", type=click.Path(file_okay=False), default="plots", show_default=True,
              help="Folder for the PNG files (created if missing).")
@user_errors
def plot(plan_path: str, out_dir: str) -> None:
    """Write the figures of the plan PLAN_PATH (lutgen.plan/1 JSON) as PNG files.

    Base attitude, grasp wrench vs limits, joints vs limits, minimum collision distance vs margin, and
    gripper-vs-grasp errors during tracking; phase boundaries marked on every time axis.
    """
    from lut.output.plan_file import load_plan

    doc = load_plan(plan_path)  # before importing matplotlib: a bad path fails fast
    from lut.output.plots import write_plots

    try:
        paths = write_plots(doc, out_dir)
    except OSError as exc:
        raise write_error(out_dir, exc) from None
    for path in paths:
        click.echo(f"wrote {path}")


@click.command()
@click.argument("plan_path", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_html", type=click.Path(dir_okay=False), default="preview.html",
              show_default=True, help="The HTML file to write (self-contained, works offline).")
@click.option("--max-frames", type=click.IntRange(min=2), default=300, show_default=True,
              help="Frames of the animation (the plan's samples are thinned to this many).")
@user_errors
def preview(plan_path: str, out_html: str, max_frames: int) -> None:
    """Write a 3D animation of the plan PLAN_PATH as one self-contained HTML page.

    Open it in a browser: play/pause, time slider, speed; OUT.html?t=20 opens at t = 20 s.
    """
    from pathlib import Path

    from lut.output.paths import Output, check_outputs
    from lut.output.plan_file import load_plan

    doc = load_plan(plan_path)  # before importing plotly and pinocchio: a bad path fails fast
    check_outputs([plan_path], [Output("-o/--out", Path(out_html))], creates_folders=True)
    from lut.output.preview import write_preview

    try:
        path = write_preview(doc, out_html, max_frames=max_frames)
    except OSError as exc:
        raise write_error(out_html, exc) from None
    click.echo(f"wrote {path}")


COMMANDS = (plot, preview)
