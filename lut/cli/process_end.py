"""How a command that has given its answer ends: output flushed, then, in the console script, the process at once.

A plan's objects (CasADi Functions, IPOPT instances, compiled libraries, pinocchio models) take a noticeable part of a
cold plan's wall time to free (README "Measured performance"); a process that has written and flushed its answer has
nothing left to do with them, so the console script leaves them to the operating system. Called in-process (the tests'
click runner), the interpreter stays: a non-zero code is raised as ``SystemExit`` as before.
"""

from __future__ import annotations

import os
import sys
from typing import NoReturn

from lut.cli.exit_codes import ExitCode

END_AT_ONCE = False  # set by the console script (:func:`lut.cli.main.run`) only


def end_command(code: ExitCode) -> None:
    """Finish a command with ``code``: in the console script end the process now (:func:`exit_now`); elsewhere
    return for 0 (output flushed) and exit for any other code."""
    if END_AT_ONCE or code != ExitCode.OK:
        exit_now(code)
    sys.stdout.flush()
    sys.stderr.flush()


def exit_now(code: ExitCode) -> NoReturn:
    """Flush stdout and stderr, then end with ``code``: the process at once in the console script (``os._exit``: no
    teardown, no atexit handlers), ``sys.exit(code)`` elsewhere."""
    sys.stdout.flush()
    sys.stderr.flush()
    if END_AT_ONCE:
        os._exit(int(code))
    sys.exit(code)
