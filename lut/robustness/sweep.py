"""The error-scale sweep: the success probability as both σ's are multiplied by a factor, and the largest
factor at which at least 95 % of runs succeed.

Every scale reuses the same standard normal draws (:mod:`lut.robustness.error_model`), so the curve's
steps come from the error growing, not from new draws. The largest 95 % scale is the largest tested scale
at and below which every tested scale had a point estimate ≥ :data:`SUCCESS_TARGET`; it is only as fine as
the scales tested.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from lut.robustness.statistics import SuccessEstimate

SUCCESS_TARGET = 0.95


@dataclass(frozen=True)
class ScalePoint:
    """The success estimate at one error scale (a factor on both σ's)."""

    scale: float
    estimate: SuccessEstimate


@dataclass(frozen=True)
class LargestScale:
    """The largest tested scale meeting :data:`SUCCESS_TARGET` (None: not even the smallest);
    ``beyond_tested``: every tested scale met it, so the true limit is larger."""

    scale: float | None
    beyond_tested: bool


def largest_scale(points: Sequence[ScalePoint], target: float = SUCCESS_TARGET) -> LargestScale:
    """The module docstring's largest scale over ``points`` (any order)."""
    best = None
    ordered = sorted(points, key=lambda p: p.scale)
    for p in ordered:
        if p.estimate.probability < target:
            return LargestScale(best, False)
        best = p.scale
    return LargestScale(best, bool(ordered))


def parse_scales(text: str) -> list[float]:
    """Comma-separated error scales, each finite and ≥ 0, sorted and without repeats; 1 is always included."""
    from planner.errors import LutgenError

    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise LutgenError(f"--scales: expected comma-separated numbers, got {text!r}") from None
    if any(not (v >= 0 and v < float("inf")) for v in values):
        raise LutgenError(f"--scales: every scale must be a finite number >= 0, got {text!r}")
    return sorted({*values, 1.0})
