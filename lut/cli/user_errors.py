"""One-line user errors: a :class:`LutgenError` becomes ``error: …`` on stderr and exit code 1, never a traceback."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import Any

import click

from lut.cli.exit_codes import ExitCode
from planner.errors import LutgenError

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


def write_error(target: str, exc: OSError) -> LutgenError:
    """A one-line user error for an output path that cannot be written (read-only, a file for a folder, …)."""
    where = f": {exc.filename}" if exc.filename and str(exc.filename) != str(target) else ""
    return LutgenError(f"{target}: cannot write ({exc.strerror or exc}{where})")
