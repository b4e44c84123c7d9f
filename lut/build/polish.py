"""``lutgen build --polish``: once every point is solved, a point whose plan costs a factor more than an adjacent
point's (or that has no feasible plan) is solved again warm from its cheaper feasible neighbours (with
``--polish-cold``, then cold), and keeps the plan only if it is feasible and cheaper.

Why: a warm-started point stays in its parent's local minimum, and a point whose warm start verify refused is planned
cold and may fall into a far costlier one than both its neighbours hold (docs/measurements.md, "Optimal tables"); the
query then answers near it at that cost. Where no neighbour's warm start leaves that minimum, a cold plan (its own grasp
guesses) may find a cheaper one. The candidates and their starts are read from the plans as the sweep left them (the
journal's first record of each point), so the result does not depend on the order the tries finish in, and each
candidate's outcome (its better plan, or its plan as it was) is journaled once: ``--resume`` skips it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from lut.build.reuse import CostOf, cost_or_inf
from lut.table.grid import Grid
from lut.table.plan_costs import cost_ratio
from lut.table.point_result import PointResult, PointStatus

POLISH_RATIO = 1.25  # a point this factor dearer than a neighbour is polished from it (the query's bands of cost)
POLISH_COST_FLOOR = 2e-3  # costs below this are alike (the query's floor: Eq. 16 of a 4.5 cm base offset) [cost]


@dataclass(frozen=True)
class PolishTask:
    """A point to solve again: the feasible neighbours to warm-start it from, cheapest first, then perhaps cold."""

    point: int
    neighbours: tuple[int, ...]
    cold: bool = False  # planned cold too, once no neighbour's warm start gave a cheaper plan

    @property
    def starts(self) -> tuple[int | None, ...]:
        """The starts tried in order: each neighbour's plan, then None (a cold plan) when :attr:`cold`."""
        return self.neighbours + ((None,) if self.cold else ())


def polish_tasks(grid: Grid, results: dict[int, PointResult], cost_of: CostOf, tries: int, cold: bool = False,
                 ratio: float = POLISH_RATIO) -> list[PolishTask]:
    """The points of ``results`` with an adjacent feasible point whose cost ``cost_of`` is lower by more than
    ``ratio`` (:func:`cost_ratio`; a point without a feasible plan, or with a NaN cost, is dearer than any), each
    with up to ``tries`` such neighbours, cheapest first (a tie: the lower index), and a cold plan after them when
    ``cold``, in point order."""
    costs = {p: cost_or_inf(r, cost_of) for p, r in results.items()}
    tasks = []
    for point in sorted(results):
        cheaper = sorted((costs[nb], nb) for nb in grid.neighbours(point)
                         if nb in costs and np.isfinite(costs[nb])
                         and float(cost_ratio(costs[point], costs[nb], POLISH_COST_FLOOR)) > ratio)
        if cheaper:
            tasks.append(PolishTask(point, tuple(nb for _, nb in cheaper[:tries]), cold))
    return tasks


def better(tried: PointResult, kept: PointResult, cost_of: CostOf) -> bool:
    """Whether ``tried`` replaces ``kept``: feasible, and cheaper (any feasible plan replaces one that is not)."""
    return tried.status is PointStatus.FEASIBLE and cost_or_inf(tried, cost_of) < cost_or_inf(kept, cost_of)


@dataclass(frozen=True)
class PolishOutcome:
    """What a polish did: how many points it tried, and how many of them got a cheaper plan."""

    tried: int = 0
    improved: int = 0


# (point, start) pairs → their tries; a start is a neighbour's index, or None for a cold plan
SolveFrom = Callable[[list[tuple[int, int | None]]], Iterable[PointResult]]


def polish(tasks: list[PolishTask], results: dict[int, PointResult], cost_of: CostOf, solve_from: SolveFrom,
           keep: Callable[[PointResult], None]) -> PolishOutcome:
    """Try every task's starts in rounds (round k: each task not yet improved, from its k-th start, all in parallel
    through ``solve_from``); ``keep`` gets each task's outcome once: its better plan as soon as a try finds it, else
    its plan of ``results`` after its last try."""
    open_tasks = {t.point: t for t in tasks}
    improved = 0
    for k in range(max((len(t.starts) for t in tasks), default=0)):
        pairs = [(t.point, t.starts[k]) for t in open_tasks.values() if k < len(t.starts)]
        for tried in solve_from(pairs):
            if tried.point in open_tasks and better(tried, results[tried.point], cost_of):
                keep(tried)
                improved += 1
                del open_tasks[tried.point]
        for point in [p for p, t in open_tasks.items() if len(t.starts) <= k + 1]:
            keep(results[point])
            del open_tasks[point]
    return PolishOutcome(len(tasks), improved)
