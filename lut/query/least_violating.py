"""Which of two infeasible plans a query answers with: the one that violates least, so that an operator reading an
INFEASIBLE answer sees the closest attempt (e.g. a grasp torque 11 N·m against 10), not the first one made (an
interpolated plan can be absurd: a joint 190 rad past its limit)."""

from __future__ import annotations

from planner.excess import relative_excess_sum
from planner.verify.verifier import VerifyReport


def violation(report: VerifyReport) -> tuple[int, float]:
    """``(failed checks, sum of their excesses relative to their limits)``: fewer failed checks first, then the
    smaller relative excess (|margin| against |limit|, :func:`planner.excess.relative_excess_sum`: the margin alone
    where the limit is ~0; a NaN counts as infinite); ``(0, 0.0)`` if feasible."""
    failed = [c for c in report.checks.values() if not c.passed]
    return len(failed), relative_excess_sum([abs(c.margin) for c in failed], [c.limit for c in failed])


def violates_less(candidate: VerifyReport, current: VerifyReport) -> bool:
    """True when ``candidate`` is feasible and ``current`` is not, or both are infeasible and ``candidate``
    violates strictly less (:func:`violation`)."""
    if current.feasible:
        return False
    return candidate.feasible or violation(candidate) < violation(current)
