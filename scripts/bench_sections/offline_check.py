"""Whether a failed live plan's state has a plan at all: the same ``lutgen plan`` command with ``--offline`` (the
whole start-delay window, no timing verdict; the same budget, one core), beside the live run. A live plan must start
after its own answer; where the offline plan is feasible and starts before a cold live plan can, the state's grasps
hold only too early (the failure is its timing); where it starts later, the live search missed a grasp an offline one
found (the failure is the search's, not the state's; the offline search may have reached it only after its start
too: its wall time is kept beside the start delay)."""

from __future__ import annotations

from typing import Any

from bench_sections.common import Settings
from bench_sections.failure_kinds import FailureKind
from bench_sections.recheck import Recheck, rechecked

# the failures an offline plan can explain: the state is within reach after the answer and the live plan was refused
CHECKED = (FailureKind.NO_GRASP_HELD, FailureKind.BRAKING, FailureKind.UNEXPLAINED)
OFFLINE = Recheck("offline", CHECKED, lambda args: [*args, "--offline"])


def with_offline(records: list[dict[str, Any]], jobs: list[list[str]], settings: Settings) -> list[dict[str, Any]]:
    """``records`` (one per plan command of ``jobs``, in order), each failure of a :data:`CHECKED` kind with its state
    planned offline (``offline``: exit code, wall time [s], the approach's start delay [s] and θ_b(0) [m] when a plan
    was written)."""
    return rechecked(records, jobs, settings, OFFLINE)
