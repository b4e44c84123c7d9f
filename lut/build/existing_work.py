"""What a build finds at its ``--out``: nothing, a journal (running or interrupted), or a table; and what it may do.

The overwrite and resume rules of ``lutgen build`` (README, workflow 1; docs/table.md, Build), decided
before anything is solved.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lut.build.options import BuildOptions, BuildOutcome, BuildSummary
from lut.table.grid_config import GridConfig
from lut.table.journal import JournalStatus, journal_status
from lut.table.point_result import PointStatus
from lut.table.store import Table
from planner.errors import LutgenError


def journal_path(table_path: Path) -> Path:
    """The build journal beside ``table_path`` (``t.h5`` → ``t.h5.journal``)."""
    return table_path.with_name(table_path.name + ".journal")


def existing_work(table_path: Path, jpath: Path, options: BuildOptions, mhash: str,
                  config: GridConfig) -> Table | None:
    """Apply the overwrite and resume rules to what is at ``table_path``: raise :class:`LutgenError` where the
    build must not start, delete an interrupted journal under ``--force``, and return the table (as read) when it
    is complete and ``--resume`` leaves it as it is, else ``None``."""
    status = journal_status(jpath)
    if status is JournalStatus.IN_USE:
        raise LutgenError(f"{jpath}: another build of {table_path} is running (its journal is locked); "
                          "wait for it, or stop it first")
    if status is JournalStatus.INTERRUPTED:
        if options.force:
            jpath.unlink()
        elif not options.resume:
            raise LutgenError(f"{jpath} exists: an earlier build of {table_path} was interrupted; rerun with "
                              "--resume to continue it, or --force to start over")
        return None
    if not table_path.exists() or options.force:
        return None
    if not options.resume:
        raise LutgenError(f"{table_path} exists: --force to build it again (the old table stays until the new "
                          "one is complete), or another --out")
    table = Table.open(table_path)
    if table.model_hash != mhash or table.attrs.get("config_text") != config.text:
        raise LutgenError(f"{table_path} was built from another grid config, robot, target or scenario: nothing "
                          "to resume; --force to build it again")
    if table.counts()["pending"]:
        raise LutgenError(f"{table_path} has pending points but no journal to resume; --force to build it again")
    return table


def complete_summary(table: Table, t_start: float) -> BuildSummary:
    """The summary of a complete table that ``--resume`` leaves as it is (``t_start``: ``perf_counter`` [s])."""
    reasons = table.field("failure_reason")
    failures = [f"point {p}: {reasons[p]}" for p in np.flatnonzero(table.status == PointStatus.FAILED.code)]
    return BuildSummary(table.path, table.n_points, table.counts(), 0, time.perf_counter() - t_start, failures,
                        BuildOutcome.ALREADY_COMPLETE)
