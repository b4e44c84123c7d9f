"""A query's corner stage: the interpolated plan repaired, else the cheapest of the cell's corners' own plans that
verifies at the state (docs/table.md, Query step 4).

Each corner's plan is an optimum at a nearby state and consistent in itself, where an average of corners in different
families of solutions may collide or miss the grasp. A plan whose failure has one cause
(:func:`~lut.query.stabilization_repair.single_cause`) is repaired at once; one whose braking is too harsh while its
arm also hits a limit or a body only once every corner has been verified as it is, fewest failed checks first: those
repairs mostly fail, at the full ``REPAIR_ITERATIONS`` (seconds each).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol

from lut.query.interpolation import SAME_COST_ABS, Candidate, cost_bands
from lut.query.least_violating import violates_less, violation
from lut.query.result import QuerySource, TableAnswer
from lut.query.stabilization_repair import single_cause, stabilization_only
from planner.deadline import Deadline
from planner.model.target import TargetState
from planner.plan import GraspPlan
from planner.plan_parameters import PlanParameters
from planner.verify.verifier import VerifyReport

# corners whose own plans are tried (by band of cost, each band heaviest first) when the interpolated plan fails
# verification, before any solve: each costs one re-simulation and verification and perhaps a repair (1-4 s), a refine
# tens of seconds; a flat-spin cell has 8 corners (docs/measurements.md, "Optimal tables")
CORNER_TRIES = 8
CORNER_STAGE_S = 20.0  # no corner is started once the corners took this long [s]: the solves keep the rest
FINISH_RESERVE_S = 5.0  # kept back from the budget to re-simulate, verify and export a refined plan [s]
MIN_REFINE_S = 5.0  # a refine with less time than this cannot finish a solve: not started [s]
# a plan the query made: the plan, its verification, the corners it came from and its source
Attempt = tuple[GraspPlan, VerifyReport, list[int], QuerySource]


class TablePlans(Protocol):
    """What the corner stage asks of a table opened for queries (:class:`lut.query.table_query.TableQuery`)."""

    def corner_candidates(self, state: TargetState) -> list[Candidate]: ...

    def verified(self, state: TargetState, parameters: PlanParameters, corners: list[int], source: QuerySource,
                 latency: dict[str, float]) -> Attempt | None: ...

    def repaired(self, plan: GraspPlan, report: VerifyReport,
                 deadline: Deadline) -> tuple[GraspPlan, VerifyReport] | None: ...


def corner_order(corners: list[Candidate]) -> list[Candidate]:
    """The corners the corner stage tries, in order: by band of cost (:func:`cost_bands`: those at the cell's lowest
    cost, then bands a factor :data:`~lut.query.interpolation.COST_BAND_RATIO` apart), each band heaviest first, at most
    :data:`CORNER_TRIES`."""
    bands = dict(zip((c.corner for c in corners), cost_bands(corners), strict=True))
    return sorted(corners, key=lambda c: (bands[c.corner], -c.weight))[:CORNER_TRIES]


def cheaper(cost: float, than: float) -> bool:
    """True when a corner of weighted cost ``cost`` is worth trying after a feasible plan of cost ``than`` was found:
    lower by more than :data:`~lut.query.interpolation.SAME_COST_ABS` (a cost the query would not tell apart from it,
    Eq. 16 for a 1 cm base offset); never for an unknown (NaN) cost or in a feasibility-only table (costs 0)."""
    return bool(cost < than - SAME_COST_ABS)


@dataclass
class CornerStage:
    """One query's corner stage at ``state``: the table's answer ``found`` and the query's ``deadline``; the time its
    repairs take is added to ``latency["repair_s"]``."""

    query: TablePlans
    state: TargetState
    found: TableAnswer
    deadline: Deadline
    latency: dict[str, float]
    later: list[Attempt] = field(default_factory=list)  # the both-cause plans, repaired last
    stage: Deadline = field(default_factory=lambda: Deadline.after(CORNER_STAGE_S))

    def run(self, first: Attempt | None) -> Attempt | None:
        """The interpolated plan (``first``, verified; None when late) repaired, or the cheapest feasible plan of the
        cell's corners (at most :data:`CORNER_TRIES`, for at most :data:`CORNER_STAGE_S`, in :func:`corner_order`; the
        interpolation's own corner when it is one corner's plan is not tried twice; none that would start before the
        answer), each carried to the state's phase and verified there, as it is (source ``corner``) or with its
        stabilization repaired (``repaired``): once one is feasible only the corners cheaper than it
        (:func:`cheaper`) are tried, each as it is or repaired from one cause. If none is feasible in time, the least
        violating of those made (:mod:`lut.query.least_violating`); None when none was made."""
        fixed = None if first is None else self._repair_now_or_later(first)
        if fixed is not None:
            return fixed
        best, found, found_cost = first, None, float("nan")
        candidates = [c for c in self.query.corner_candidates(self.state) if [c.corner] != self.found.corners]
        for candidate in corner_order(candidates):
            if self.out_of_time():
                break
            if found is not None and not cheaper(candidate.cost, found_cost):
                continue
            made = self.query.verified(self.state, candidate.parameters, [candidate.corner], QuerySource.CORNER, {})
            if made is None:
                continue
            fixed = made if made[1].feasible else self._repair_now_or_later(made, defer=found is None)
            if fixed is not None:
                found, found_cost = fixed, candidate.cost
            elif found is None and (best is None or violates_less(made[1], best[1])):
                best = made
        return found or self._repair_the_rest() or best

    def _repair_the_rest(self) -> Attempt | None:
        """The both-cause plans repaired, fewest failed checks first (the count alone, so that ties keep the order
        they were tried in), while the stage has time: the first that verifies feasible, else None."""
        for made in sorted(self.later, key=lambda attempt: violation(attempt[1])[0]):
            if self.out_of_time():
                break
            fixed = self.timed_repair(made)
            if fixed is not None:
                return fixed
        return None

    def _repair_now_or_later(self, made: Attempt, defer: bool = True) -> Attempt | None:
        """``made`` (a failed plan) repaired now when it fails from one cause: the repaired attempt, or None; kept for
        :meth:`_repair_the_rest` when it fails from both after its grasp and ``defer``; else left alone (it fails
        before its grasp)."""
        if single_cause(made[1]):
            return self.timed_repair(made)
        if defer and stabilization_only(made[1]):
            self.later.append(made)
        return None

    def out_of_time(self) -> bool:
        """True when no more corner may be tried: the corner stage is over, or the solves need what is left."""
        return self.stage.passed or self.deadline.remaining_s() < FINISH_RESERVE_S + MIN_REFINE_S

    def timed_repair(self, made: Attempt) -> Attempt | None:
        """``made`` repaired (:meth:`TableQuery.repaired`) as ``(plan, report, its corners, "repaired")``, or None; the
        time it took added to ``latency["repair_s"]``."""
        t0 = time.perf_counter()
        fixed = self.query.repaired(made[0], made[1], self.deadline)
        self.latency["repair_s"] += time.perf_counter() - t0
        return None if fixed is None else (*fixed, made[2], QuerySource.REPAIRED)
