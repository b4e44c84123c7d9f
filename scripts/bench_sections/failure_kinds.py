"""What kind of failure a coverage run is (issue 20: every failure explained by kind, not by a timeout), from the
reasons its record names (:func:`bench_sections.coverage_runs.failure_reasons`) and, for a cold plan, when its state's
grasp is within reach (:mod:`bench_sections.reach_windows`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from enum import StrEnum
from typing import Any

from bench_sections.coverage_runs import BUDGET_RAN_OUT, EXIT_MEANINGS, LATE_START, OVER_BUDGET
from planner.deadline import FLOOR_STEP_S, START_LEAD_S
from planner.out_of_reach import REACHABLE_ONLY_TOO_EARLY

OUT_OF_REACH = "out of reach"
OUT_OF_REACH_PROVEN = "out of reach (proven)"
NO_PLAN = "no plan"
# a run's reasons that say the bench or the planner is wrong (an infeasible exit is the state's, not a bug)
BUGS = frozenset(meaning for code, meaning in EXIT_MEANINGS.items() if code != 2)
# the phases of a failed check (failed_checks) that lie before the braking: what no braking can change
BEFORE_THE_GRASP = frozenset({"approach", "tracking", "grasp"})
# the earliest approach start [s after the observation] a cold live plan can take: its problems' build (1.3 s, the wall
# time of an out-of-reach answer) plus START_LEAD_S (5 s), rounded up to a whole FLOOR_STEP_S (planner.deadline)
PROBLEM_BUILD_S = 1.3
EARLIEST_COLD_START_S = math.ceil((PROBLEM_BUILD_S + START_LEAD_S) / FLOOR_STEP_S) * FLOOR_STEP_S


class FailureKind(StrEnum):
    """Why a state got no verified plan on time, in the order a run is matched against them."""

    BUG = "bug"  # bad input, a usage error, a crash: the bench or the planner is wrong, not the state
    OVER_BUDGET = "over budget"  # late or killed: the product's promise broken, whatever else failed
    # no plan can bring the grasp within the arm's reach at any meeting time (planner.phases.reach_proof)
    OUT_OF_REACH_PROVEN = "out of reach (proven)"
    OUT_OF_REACH = "out of reach"  # the scan of meeting times reached none: refused before solving
    NO_PLAN = "no plan"  # a query whose solves gave no plan and whose table had none near the state
    # within reach only at start delays before a cold plan can start: the plan's own answer (planner.out_of_reach), or
    # its state's reach windows all before EARLIEST_COLD_START_S
    ONLY_TOO_EARLY = REACHABLE_ONLY_TOO_EARLY
    # its state planned offline (bench_sections.offline_check) is feasible, its approach starting before a cold live
    # plan can (EARLIEST_COLD_START_S): the grasps that hold come only too early
    HELD_ONLY_TOO_EARLY = "held only too early"
    # planned offline, feasible, starting after that: a live search that found that grasp first could have flown it
    MISSED_LIVE = "missed live"
    NO_GRASP_HELD = "no grasp held"  # verify refuses the plan before its grasp: the approach, the tracking, the grasp
    BRAKING = "braking"  # the grasp held; every failed check lies in the braking, from the grasp on
    LATE_START = "late start"  # verified feasible, but its approach was to start before its answer came
    UNEXPLAINED = "unexplained"  # infeasible, and no failed check says where


def failure_kind(reasons: Sequence[dict[str, Any]], refine_failure: str | None = None,
                 reach_windows_s: Sequence[Sequence[float]] | None = None,
                 offline: Mapping[str, Any] | None = None) -> FailureKind | None:
    """The kind of a run's failure from its ``reasons`` (None: no reason, the run gave a verified plan on time); for a
    query, why its solve did not finish (a query answers a state out of reach with its table's plan, whose failed
    checks are the table's, not the state's); for a cold plan, its state's ``reach_windows_s`` (the start delays [s]
    the scan reached, as intervals; None: not known), all before a cold plan can start (:data:`EARLIEST_COLD_START_S`)
    being the failure's kind whatever the plan then failed; and the same state's ``offline`` plan (its exit code and
    start delay [s], :mod:`bench_sections.offline_check`; None: not planned), which, feasible, tells when a plan
    exists."""
    if not reasons:
        return None
    names = {r["reason"] for r in reasons}
    phases = {r.get("phase") for r in reasons if r["reason"] not in (BUDGET_RAN_OUT, OVER_BUDGET, LATE_START)}
    if names & BUGS or any(n.startswith("exit ") for n in names):
        return FailureKind.BUG
    if OVER_BUDGET in names:
        return FailureKind.OVER_BUDGET
    if OUT_OF_REACH_PROVEN in names or (refine_failure or "").startswith(OUT_OF_REACH_PROVEN):
        return FailureKind.OUT_OF_REACH_PROVEN
    if OUT_OF_REACH in names or (refine_failure or "").startswith(OUT_OF_REACH):
        return FailureKind.OUT_OF_REACH
    if NO_PLAN in names:
        return FailureKind.NO_PLAN
    too_early = REACHABLE_ONLY_TOO_EARLY in names or (refine_failure or "").startswith(REACHABLE_ONLY_TOO_EARLY)
    if too_early or (reach_windows_s and max(last for _, last in reach_windows_s) < EARLIEST_COLD_START_S):
        return FailureKind.ONLY_TOO_EARLY
    offline_start = offline_start_s(offline)
    if offline_start is not None:
        return FailureKind.HELD_ONLY_TOO_EARLY if offline_start < EARLIEST_COLD_START_S else FailureKind.MISSED_LIVE
    if phases & BEFORE_THE_GRASP:
        return FailureKind.NO_GRASP_HELD
    if phases == {"stabilization"}:
        return FailureKind.BRAKING
    if names == {LATE_START} or names == {LATE_START, BUDGET_RAN_OUT}:
        return FailureKind.LATE_START
    return FailureKind.UNEXPLAINED


def offline_start_s(offline: Mapping[str, Any] | None) -> float | None:
    """When the approach of a feasible offline plan (a record's ``offline``, :mod:`bench_sections.offline_check`)
    starts [s after the observation]; None without one (not planned, infeasible, killed)."""
    return offline["start_delay_s"] if offline is not None and offline["exit_code"] == 0 else None


def record_failure_kind(record: Mapping[str, Any]) -> FailureKind | None:
    """:func:`failure_kind` of a coverage run's record (its reasons, a query's refine failure, a plan's reach
    windows, its offline plan)."""
    return failure_kind(record["reasons"], record.get("refine_failure"), record.get("reach_windows_s"),
                        record.get("offline"))


def cut_by_the_budget(reasons: Sequence[dict[str, Any]]) -> bool:
    """True when the plan's own deadline ended a solve: its failed checks are where that solve stood."""
    return any(r["reason"] == BUDGET_RAN_OUT for r in reasons)
