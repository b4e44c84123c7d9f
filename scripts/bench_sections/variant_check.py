"""Whether a failed live plan's state has a plan where the chaser may wait farther: the same ``lutgen plan`` command
with the scenario's variant (``--coverage-variant-check wide``: θ_b(0) within ±2 m instead of the bundled ±1 m; the
same budget, one core, live), beside the live run. A feasible plan there says the failure is the box's: the grasp lies
beyond where the bundled scenario lets the chaser wait, not beyond what the planner finds."""

from __future__ import annotations

from typing import Any

from bench_sections.common import Settings
from bench_sections.failure_kinds import FailureKind
from bench_sections.recheck import Recheck, rechecked

KEY = "variant_plan"  # the record's key for the variant's run
# every failure a state's geometry or timing can explain; a bug, a run over its budget, a late answer and a query's
# missing plan are not the box's
CHECKED = frozenset(FailureKind) - {FailureKind.BUG, FailureKind.OVER_BUDGET, FailureKind.NO_PLAN,
                                    FailureKind.LATE_START}


def variant_arguments(args: list[str], variant: str) -> list[str]:
    """A ``plan configs/scenarios/NAME.toml …`` command's arguments with the scenario's ``NAME_variant.toml``."""
    scenario = args[1]
    if args[0] != "plan" or not scenario.endswith(".toml"):
        raise ValueError(f"not a plan command of a scenario file: {args[:2]}")
    return [args[0], scenario.removesuffix(".toml") + f"_{variant}.toml", *args[2:]]


def with_variant(records: list[dict[str, Any]], jobs: list[list[str]], settings: Settings) -> list[dict[str, Any]]:
    """``records`` (one per plan command of ``jobs``, in order), each failure of a :data:`CHECKED` kind with its state
    planned with the scenario's ``settings.coverage.variant_check`` variant (under :data:`KEY`: exit code, wall time
    [s], start delay [s] and θ_b(0) [m] when it wrote a plan)."""
    variant = settings.coverage.variant_check
    return rechecked(records, jobs, settings, Recheck(KEY, CHECKED, lambda args: variant_arguments(args, variant)))
