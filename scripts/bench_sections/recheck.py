"""A failed coverage run's state planned again another way, beside the live run: the same ``lutgen plan`` command
changed by one rule (``--offline``, or the scenario's variant), the same budget, one core; the record keeps what that
run gave (exit code, wall time, the approach's start delay and θ_b(0) when it wrote a plan)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Collection
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

from bench_sections.common import Settings
from bench_sections.coverage_runs import CliRun, run_cli
from bench_sections.failure_kinds import FailureKind, record_failure_kind


@dataclass(frozen=True)
class Recheck:
    """One other way to plan a failure's state: the record key it is kept under, the failure kinds it can explain,
    and how a plan command's arguments become its own."""

    key: str
    kinds: Collection[FailureKind]
    arguments: Callable[[list[str]], list[str]]


def rerun_summary(run: CliRun) -> dict[str, Any]:
    """Exit code, wall time [s], and, when it wrote a plan, its approach's start delay [s] and θ_b(0) [m] (x, z)."""
    m = run.metrics or {}
    offset = m.get("base_offset_m")
    return {"exit_code": run.exit_code, "wall_s": run.wall_s, "start_delay_s": m.get("start_delay_s"),
            "base_offset_m": None if offset is None else [offset["x"], offset["z"]]}


def rechecked(records: list[dict[str, Any]], jobs: list[list[str]], settings: Settings,
              how: Recheck) -> list[dict[str, Any]]:
    """``records`` (one per plan command of ``jobs``, in order), each failure of one of ``how``'s kinds with its state
    planned again ``how``'s way (under ``how.key``: :func:`rerun_summary`)."""
    c = settings.coverage
    todo = [i for i, r in enumerate(records) if record_failure_kind(r) in how.kinds]

    def one(i: int) -> dict[str, Any]:
        out = rerun_summary(run_cli(how.arguments(jobs[i]), c.budget_s + c.kill_margin_s))
        start = out["start_delay_s"]
        print(f"coverage {how.key}: {jobs[i][1]} state {i} exit {out['exit_code']} {out['wall_s']:.1f} s, start "
              f"{'-' if start is None else format(start, '.2f')} s", file=sys.stderr, flush=True)
        return out

    with ThreadPoolExecutor(max(1, c.jobs)) as pool:
        again = dict(zip(todo, pool.map(one, todo), strict=True))
    return [{**r, how.key: again[i]} if i in again else r for i, r in enumerate(records)]
