"""The bounds of an approach re-solve that are tighter than the NLP's own: raised clearances, lowered joint rates.

The approach NLP holds its distances and joint rates at its via points; between two of them a pair can dip below
its clearance (:mod:`planner.phases.approach_clearance`) or a joint's rate peak above its limit
(:mod:`planner.phases.approach_rates`). A warm re-solve holds those rows tighter, by what the solved approach shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.phases.approach import ApproachProblem

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ApproachBounds:
    """Tighter rows of :class:`~planner.phases.approach.ApproachProblem`, each block in the NLP's row order (None:
    that block as the NLP has it)."""

    collision_raise_m: Array | None = None  # added to the collision rows' lower bounds [m]
    rate_lower_rad_s: Array | None = None  # the joint-velocity rows' lower bounds [rad/s]
    rate_upper_rad_s: Array | None = None  # their upper bounds [rad/s]

    def applied(self, problem: ApproachProblem, lbg: Array, ubg: Array) -> None:
        """Tighten ``lbg`` and ``ubg`` (``problem``'s rows; its joint-velocity rows as the NLP has them) in place."""
        if self.collision_raise_m is not None:
            lbg[problem.constraints.slice("collision")] += self.collision_raise_m
        rates = problem.constraints.slice("joint_velocities")
        lbg[rates], ubg[rates] = self.rates(problem)

    def rates(self, problem: ApproachProblem) -> tuple[Array, Array]:
        """The joint-velocity rows' bounds ``(lower, upper)`` [rad/s] these hold (copies)."""
        rates = problem.constraints.slice("joint_velocities")
        lower, upper = problem.lbg[rates].copy(), problem.ubg[rates].copy()
        if self.rate_lower_rad_s is not None:
            lower = np.maximum(lower, self.rate_lower_rad_s)
        if self.rate_upper_rad_s is not None:
            upper = np.minimum(upper, self.rate_upper_rad_s)
        return lower, upper

    def and_(self, other: ApproachBounds) -> ApproachBounds:
        """Both tightenings: each row the tighter of the two."""
        raise_m = _either(self.collision_raise_m, other.collision_raise_m, np.maximum)
        return ApproachBounds(raise_m, _either(self.rate_lower_rad_s, other.rate_lower_rad_s, np.maximum),
                              _either(self.rate_upper_rad_s, other.rate_upper_rad_s, np.minimum))


AS_SOLVED = ApproachBounds()  # the NLP's own bounds


def _either(a: Array | None, b: Array | None, tighter: np.ufunc) -> Array | None:
    """``tighter(a, b)``, or the one given, or None."""
    if a is None or b is None:
        return b if a is None else a
    return tighter(a, b)
