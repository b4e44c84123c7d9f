"""Whether a failed live plan's state has a plan at all: the same ``lutgen plan`` command with ``--offline`` (the
whole start-delay window, no timing verdict; the same budget, one core), beside the live run. A live plan must start
after its own answer; where the offline plan is feasible and starts before a cold live plan can, the state's grasps
hold only too early (the failure is its timing); where it starts later, the live search missed a grasp an offline one
found (the failure is the search's, not the state's; the offline search may have reached it only after its start
too: its wall time is kept beside the start delay)."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from bench_sections.common import Settings
from bench_sections.coverage_runs import run_cli
from bench_sections.failure_kinds import FailureKind, record_failure_kind

# the failures an offline plan can explain: the state is within reach after the answer and the live plan was refused
CHECKED = (FailureKind.NO_GRASP_HELD, FailureKind.BRAKING, FailureKind.UNEXPLAINED)


def with_offline(records: list[dict[str, Any]], jobs: list[list[str]], settings: Settings) -> list[dict[str, Any]]:
    """``records`` (one per plan command of ``jobs``, in order), each failure of a :data:`CHECKED` kind with its state
    planned offline (``offline``: exit code, wall time [s], the approach's start delay [s] when a plan was written)."""
    c = settings.coverage
    todo = [i for i, r in enumerate(records) if record_failure_kind(r) in CHECKED]

    def one(i: int) -> dict[str, Any]:
        run = run_cli([*jobs[i], "--offline"], c.budget_s + c.kill_margin_s)
        start = None if run.metrics is None else run.metrics.get("start_delay_s")
        offline = {"exit_code": run.exit_code, "wall_s": run.wall_s, "start_delay_s": start}
        print(f"coverage offline: {jobs[i][1]} state {i} exit {run.exit_code} {run.wall_s:.1f} s, start "
              f"{'-' if start is None else format(start, '.2f')} s", file=sys.stderr, flush=True)
        return offline

    with ThreadPoolExecutor(max(1, c.jobs)) as pool:
        offline = dict(zip(todo, pool.map(one, todo), strict=True))
    return [{**r, "offline": offline[i]} if i in offline else r for i, r in enumerate(records)]
