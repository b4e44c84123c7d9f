"""``lutgen plot`` and ``lutgen preview``: look at a plan JSON before it runs (figures, 3D page).

Wired into the main group by :func:`register` (``lut/cli.py``: ``register(main)``). Errors a user causes
(missing file, not JSON, another schema, a robot URDF that cannot be found) print one line and exit 1,
through :func:`lut.cli.main.user_errors`, imported when a command runs so that ``lut.cli.main`` may import this
module at any point of its own import.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import click


def _user_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """:func:`lut.cli.main.user_errors`, looked up at call time (no circular import with ``lut.cli.main``)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        from lut.cli.main import user_errors

        return user_errors(func)(*args, **kwargs)

    return wrapper


def _write_error(target: str, exc: OSError) -> Exception:
    """A one-line user error for an output path that cannot be written (read-only, a file for a folder, …)."""
    from planner.errors import LutgenError

    where = f": {exc.filename}" if exc.filename and str(exc.filename) != str(target) else ""
    return LutgenError(f"{target}: cannot write ({exc.strerror or exc}{where})")


@click.command()
@click.argument("plan_path", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_dir", type=click.Path(file_okay=False), default="plots", show_default=True,
              help="Folder for the PNG files (created if missing).")
@_user_errors
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
        raise _write_error(out_dir, exc) from None
    for path in paths:
        click.echo(f"wrote {path}")


@click.command()
@click.argument("plan_path", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "out_html", type=click.Path(dir_okay=False), default="preview.html",
              show_default=True, help="The HTML file to write (self-contained, works offline).")
@click.option("--max-frames", type=click.IntRange(min=2), default=300, show_default=True,
              help="Frames of the animation (the plan's samples are thinned to this many).")
@_user_errors
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
        raise _write_error(out_html, exc) from None
    click.echo(f"wrote {path}")


def register(group: click.Group) -> None:
    """Add ``plot`` and ``preview`` to the click ``group`` (the ``lutgen`` main group)."""
    group.add_command(plot)
    group.add_command(preview)
