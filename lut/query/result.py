"""What a query answers: the verified plan, where it came from, the corners it used, its latency, why a
refine gave nothing, and its cost terms next to those corners'."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING

from planner.plan_parameters import PlanParameters

if TYPE_CHECKING:
    from lut.table.plan_costs import CostBreakdown
    from planner.plan import GraspPlan
    from planner.verify.verifier import VerifyReport


class QuerySource(StrEnum):
    """Where a query's plan came from; the value is the text ``lutgen query`` prints."""

    INTERPOLATED = "interpolated"  # the consistent corners of the enclosing cell, averaged
    NEAREST = "nearest"  # the nearest feasible grid point (no feasible corner)
    CORNER = "corner"  # one corner's own plan carried to the state's phase (the interpolated one failed verify)
    REPAIRED = "repaired"  # the table's plan (interpolated or a corner's) with its stabilization re-solved warm
    REFINED = "refined"  # a solve warm-started from the table's answer
    SOLVED_COLD = "solved cold"  # a solve from scratch (with its retries over grasps)


@dataclass(frozen=True)
class TableAnswer:
    """The table's parameters for a state, before any re-simulation: interpolated or the nearest point's.

    ``parameters``' start delay is carried to the state's phase (not yet wrapped into the delay window).
    """

    parameters: PlanParameters
    corners: list[int]  # the grid points used (flat indices)
    source: QuerySource
    notes: tuple[str, ...] = ()  # how the state differs from where the table answered (off its family or grid)


@dataclass
class QueryResult:
    """A query's verified plan; ``refine_failure``: why the last refine gave no plan ("" when none failed);
    ``costs``: the plan's weighted cost terms first, then each used corner's (empty for a feasibility-only table)."""

    plan: GraspPlan
    report: VerifyReport
    source: QuerySource
    corners_used: list[int]
    latency_s: dict[str, float] = field(default_factory=dict)  # by step, e.g. "verify_s" [s]
    refine_failure: str = ""
    notes: tuple[str, ...] = ()  # how the state differs from where the table answered (off its family or grid)
    costs: tuple[CostBreakdown, ...] = ()  # the plan's weighted cost terms, then each used corner's (none: all 0)
    late: tuple[str, ...] = ()  # the table plans not tried: they would have started before the answer (which, when)
    solve_notes: tuple[str, ...] = ()  # a solved plan's (source refined or solved cold): what its solve noted
