"""The decision parameters a plan is re-simulated from (paper Eq. 23-24), and the table's operations on them.

A plan is fully determined by its target state and these parameters: the approach spline's free parameters,
the base offset and start delay, the arm configurations at the tracking nodes (which steer the tracking IK's
null space) and the stabilization spline's free parameters. A table stores them per grid point; a query
shifts them in time (flat-spin symmetry) and averages them over a cell's corners.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ApproachParameters:
    """The approach's decision parameters (paper Eq. 23, plus the base offset and the meeting time)."""

    params: Array  # (7·(N−5),) free spline parameters, :mod:`planner.nlp.bspline` layout [rad, rad/s³]
    base_offset_m: Array  # (2,) θ_b(0) in the orbital plane: (x, z) [m]
    start_delay_s: float  # observation → approach start [s]
    q_tracking: Array  # (n_nodes, 7) arm configurations at the tracking nodes [rad]


@dataclass(frozen=True)
class PlanParameters:
    """Everything a plan is re-simulated from, besides the target state."""

    approach: ApproachParameters
    stabilization_params: Array | None  # Eq. 24 free parameters; None: the stabilization's own initial guess

    def with_start_delay(self, start_delay_s: float) -> PlanParameters:
        """The same parameters with another start delay [s]."""
        return replace(self, approach=replace(self.approach, start_delay_s=float(start_delay_s)))

    def shifted_in_time(self, shift_s: float, period_s: float | None = None,
                        window_s: tuple[float, float] | None = None) -> PlanParameters:
        """The flat-spin phase ↔ time symmetry: a target whose spin phase is ahead by Δφ reaches the same
        configuration Δφ/rate earlier, so ``shift_s`` = −Δφ/rate [s].

        With a spin period and the start-delay window (earliest, latest) [s], the delay is moved by whole periods
        into the window, or clamped to its nearer end when no such delay lies in it (:func:`wrap_start_delay`).
        """
        tau = self.approach.start_delay_s + shift_s
        if period_s is not None and window_s is not None and np.isfinite(period_s) and period_s > 0:
            tau = wrap_start_delay(tau, period_s, window_s)
        return self.with_start_delay(tau)

    @staticmethod
    def weighted_mean(members: Sequence[PlanParameters], weights: Array, period_s: float) -> PlanParameters:
        """Weighted mean of a cell's corner parameters; ``weights`` sum to one.

        Start delays are averaged on the circle of the spin period [s] around the heaviest member's delay,
        so two corners 0.1 s either side of a period's end average to its end, not to half a period.
        """
        w = np.asarray(weights, dtype=float)
        ref_tau = members[int(np.argmax(w))].approach.start_delay_s
        taus = np.array([ref_tau + signed_gap(m.approach.start_delay_s, ref_tau, period_s) for m in members])

        def mean(get: Callable[[PlanParameters], Array | None]) -> Array:
            return sum(wi * np.asarray(get(m), dtype=float) for wi, m in zip(w, members, strict=True))

        approach = ApproachParameters(params=mean(lambda m: m.approach.params),
                                      base_offset_m=mean(lambda m: m.approach.base_offset_m),
                                      start_delay_s=float(w @ taus),
                                      q_tracking=mean(lambda m: m.approach.q_tracking))
        return PlanParameters(approach, mean(lambda m: m.stabilization_params))


def wrap_start_delay(tau_s: float, period_s: float, window_s: tuple[float, float]) -> float:
    """The earliest delay whole spin periods from ``tau_s`` inside ``window_s`` (earliest, latest) [s]. Where none
    lies in it: ``tau_s`` modulo the period beyond the latest is clamped to the latest; one before the earliest whose
    next equivalent is beyond the latest, to the nearer of the two ends."""
    earliest, latest = window_s
    tau = tau_s % period_s
    tau = 0.0 if tau >= period_s else tau  # a tiny negative tau_s modulo the period rounds to the period
    if tau < earliest:
        tau += np.ceil((earliest - tau) / period_s) * period_s
        if tau > latest:  # past the window: nearer its start (that far back) or its end
            return earliest if earliest - (tau - period_s) <= tau - latest else latest
    return min(tau, latest)


def circular_gap(a: float, b: float, period_s: float) -> float:
    """|a − b| on the circle of ``period_s`` (plain |a − b| for an infinite period) [s]."""
    return abs(signed_gap(a, b, period_s))


def signed_gap(a: float, b: float, period_s: float) -> float:
    """a − b wrapped into [−period/2, period/2) (plain a − b for an infinite period) [s]."""
    d = a - b
    if np.isfinite(period_s):
        d = (d + period_s / 2) % period_s - period_s / 2
    return d
