"""Success probability with a Wilson score confidence interval, and the tally of the checks that fail.

The Wilson interval (95 %, z = 1.96) stays inside [0, 1] and is not degenerate at 0 or n successes: 200
successes of 200 give [0.981, 1], where the normal approximation would claim [1, 1].
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

from lut.robustness.execution import RunOutcome

CONFIDENCE = 0.95
Z_95 = 1.959963984540054  # standard normal quantile of 0.975


@dataclass(frozen=True)
class SuccessEstimate:
    """``successes`` of ``runs`` feasible: the point estimate and its Wilson 95 % interval."""

    successes: int
    runs: int
    low: float
    high: float

    @property
    def probability(self) -> float:
        """Fraction of runs that were feasible."""
        return self.successes / self.runs if self.runs else float("nan")


def wilson_interval(successes: int, runs: int, z: float = Z_95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (``runs`` ≥ 1)."""
    p = successes / runs
    denom = 1.0 + z * z / runs
    centre = (p + z * z / (2 * runs)) / denom
    half = z / denom * math.sqrt(p * (1 - p) / runs + z * z / (4 * runs * runs))
    return max(0.0, centre - half), min(1.0, centre + half)


def success_estimate(outcomes: Sequence[RunOutcome]) -> SuccessEstimate:
    """The success probability of ``outcomes`` (at least one) with its interval."""
    k = sum(1 for o in outcomes if o.feasible)
    low, high = wilson_interval(k, len(outcomes))
    return SuccessEstimate(k, len(outcomes), low, high)


@dataclass(frozen=True)
class CheckTally:
    """How often a check failed (``failed``) and how often it was the run's first failure (``first``)."""

    check: str
    failed: int
    first: int


def failure_tally(outcomes: Sequence[RunOutcome]) -> list[CheckTally]:
    """Every check that failed in some run, most often first-failing first."""
    failed = Counter(name for o in outcomes for name in o.failed)
    first = Counter(o.first_failed for o in outcomes if o.failed)
    return sorted((CheckTally(name, failed[name], first.get(name, 0)) for name in failed),
                  key=lambda t: (-t.first, -t.failed, t.check))
