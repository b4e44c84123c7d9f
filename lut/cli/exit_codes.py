"""Process exit codes of ``lutgen``: each outcome has its own, so a script can tell them apart."""

from __future__ import annotations

from enum import IntEnum


class ExitCode(IntEnum):
    """What a ``lutgen`` run ended with."""

    OK = 0  # done; for plan and query: the plan is feasible
    BAD_INPUT = 1  # a config, file, table, option value or target state was refused (one line ``error: …``)
    INFEASIBLE = 2  # plan/query: a plan was made but verification failed (do not run it)
    USAGE = 64  # the command line itself is malformed (unknown option, missing argument); BSD EX_USAGE
    INTERNAL = 70  # an unexpected exception: a defect of lutgen or the machine, never the input; BSD EX_SOFTWARE
    READER_GONE = 141  # stdout's reader closed it (``| head``): the output cut by its reader; 128 + SIGPIPE
