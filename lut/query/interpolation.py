"""A cell's corners → one set of plan parameters: only corners that agree on the meeting time are averaged.

Corners in different local minima meet the target at different times; averaging them would give a plan
that meets it at neither. So the corners' start delays, carried to the query's phase by the flat-spin
symmetry and taken on the circle of the spin period, must agree within :data:`CONSISTENT_DELAY_S`; the
group of agreeing corners with the largest weight is averaged (docs/table.md, Query). In a table of optimal
plans only the corners at the cell's lowest cost take part (:func:`cheapest`): a corner left in a local minimum
would pull the average off the optimum its neighbours hold.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from lut.table.plan_costs import cost_ratio
from planner.plan_parameters import PlanParameters, circular_gap

CONSISTENT_DELAY_S = 3.0  # corners whose carried start delays differ more are not averaged [s]
# corners whose weighted cost (Eq. 14-16) is within the larger of these of the cell's lowest are at its optimum: 1e-4 in
# the cost's units is Eq. 16 for a base offset of 1 cm (below what relative navigation resolves), 5 % is issue 21's bar
SAME_COST_ABS = 1e-4
SAME_COST_REL = 0.05
# the corner stage's bands of cost, each this factor above the one before from the cell's lowest cost: a corner left in
# a far costlier minimum is tried after the nearer-optimal ones, however heavy (docs/measurements.md, "Optimal tables")
COST_BAND_RATIO = 1.25


@dataclass(frozen=True)
class Candidate:
    """A feasible corner of the cell: its flat index, interpolation weight, and parameters carried to the query."""

    corner: int
    weight: float
    parameters: PlanParameters
    cost: float = 0.0  # the scenario's weighted cost of the corner's plan (0: a feasibility-only table)

    @property
    def start_delay_s(self) -> float:
        return self.parameters.approach.start_delay_s


def consistent_group(candidates: Sequence[Candidate], period_s: float) -> list[Candidate]:
    """The largest-weight group of candidates whose start delays agree (on the circle of ``period_s`` [s])."""
    best: list[Candidate] = []
    for ref in candidates:
        group = [c for c in candidates if circular_gap(c.start_delay_s, ref.start_delay_s, period_s)
                 <= CONSISTENT_DELAY_S]
        if sum(c.weight for c in group) > sum(c.weight for c in best):
            best = group
    return best


def cheapest(candidates: Sequence[Candidate]) -> list[Candidate]:
    """The candidates whose cost is within :data:`SAME_COST_ABS` or :data:`SAME_COST_REL` of the lowest (all of
    them when a cost is unknown, NaN)."""
    costs = np.array([c.cost for c in candidates], dtype=float)
    if costs.size == 0 or not np.isfinite(costs).all():
        return list(candidates)
    best = float(costs.min())
    return [c for c in candidates if c.cost <= best + max(SAME_COST_ABS, SAME_COST_REL * abs(best))]


def mean_of_group(group: Sequence[Candidate], period_s: float) -> PlanParameters:
    """The group's parameters averaged with its normalised weights (start delays on the period's circle)."""
    w = np.array([c.weight for c in group])
    w = w / w.sum()
    return PlanParameters.weighted_mean([c.parameters for c in group], w, period_s)


def cost_bands(candidates: Sequence[Candidate]) -> list[int]:
    """Each candidate's band of cost: 0 for those :func:`cheapest` keeps, else 1 + the whole number of factors
    :data:`COST_BAND_RATIO` in 1 + its excess over the lowest cost relative to the lowest's size (at least
    ``SAME_COST_ABS / SAME_COST_REL``, so that costs near zero share a band; for a positive lowest cost the ratio of the
    two costs); all 0 when a cost is unknown (NaN)."""
    costs = np.array([c.cost for c in candidates], dtype=float)
    if costs.size == 0 or not np.isfinite(costs).all():
        return [0] * len(candidates)
    cheap = {c.corner for c in cheapest(candidates)}
    best = float(costs.min())
    ratios = cost_ratio(costs, best, SAME_COST_ABS / SAME_COST_REL)
    return [0 if c.corner in cheap else 1 + int(np.floor(np.log(r) / np.log(COST_BAND_RATIO)))
            for c, r in zip(candidates, ratios, strict=True)]
