"""One-line user errors: a :class:`LutgenError` becomes ``error: …`` on stderr and exit code 1, never a traceback;
stdout's reader gone (``| head``) ends the command quietly, exit code 141; any other exception is lutgen's own failure,
exit code 70, never 1."""

from __future__ import annotations

import functools
import os
import select
import sys
import traceback
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
    """Turn :class:`LutgenError` into a one-line message and exit code :attr:`ExitCode.BAD_INPUT`, and any other
    exception into its traceback, a last line ``internal error: …`` and :attr:`ExitCode.INTERNAL`: a script must
    never read a defect as bad input (a valid state refused)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except LutgenError as exc:
            click.echo(f"error: {one_line(str(exc))}", err=True)
            sys.exit(ExitCode.BAD_INPUT)
        except click.ClickException:
            raise
        except BrokenPipeError as exc:
            if not stdout_reader_gone():
                report_internal_error(exc)
                sys.exit(ExitCode.INTERNAL)
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nothing more to say; none at exit
            sys.exit(ExitCode.READER_GONE)
        except Exception as exc:  # noqa: BLE001 - the last line of defence: every other failure is ours
            report_internal_error(exc)
            sys.exit(ExitCode.INTERNAL)

    return wrapper


def stdout_reader_gone() -> bool:
    """True when stdout is a pipe whose reader has closed it (a worker's broken pipe is a failure of lutgen)."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & select.POLLERR for _, events in poller.poll(0))
    except (OSError, ValueError, AttributeError):  # no stdout, or no poll on this platform
        return False


def report_internal_error(exc: Exception) -> None:
    """The traceback of ``exc`` on stderr (for whoever mends it), then one line that says what it means."""
    click.echo("".join(traceback.format_exception(exc)).rstrip(), err=True)
    click.echo(f"internal error: {one_line(f'{type(exc).__name__}: {exc}')} (a failure of lutgen or of this machine, "
               "not of the input; no plan is given: report it with the traceback above)", err=True)


def write_error(target: str, exc: OSError) -> LutgenError:
    """A one-line user error for an output path that cannot be written (read-only, a file for a folder, …)."""
    where = f": {exc.filename}" if exc.filename and str(exc.filename) != str(target) else ""
    return LutgenError(f"{target}: cannot write ({exc.strerror or exc}{where})")
