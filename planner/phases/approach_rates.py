"""The approach's joint rates between the instants its NLP bounds them (paper Eq. 18), and the bounds that hold them.

The approach NLP bounds each joint's rate at :data:`~planner.nlp.constraint_backoff.JOINT_VELOCITY_FRACTION` of its
limit at its via points (at every RK4 node where a cost shapes the arm's motion: ``ApproachProblem._rate_nodes``).
The spline's rates are a quadratic between its knots and can peak above the limit between two bounded instants (the
seed point of scenario II's coarse flat-spin grid: 1.023× joint 1's limit between two via points 0.5 s apart), and
verify refuses the plan. This reads the densely sampled approach (its rates are the spline's own) and, where a joint's
rate comes within :data:`RATE_TRIGGER` of its limit between two bounded instants, lowers that joint's bound at those two
instants below the rate it has there by how far the peak exceeds the NLP's bound: the same peak from the lowered
instants ends at it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.nlp import constraint_backoff as backoff
from planner.phases.approach import ApproachProblem
from planner.phases.approach_bounds import ApproachBounds
from planner.plan_samples import PhaseSamples

Array = NDArray[np.float64]

# a rate this close to its limit counts as over: verify samples other instants than the dense samples, and between
# two 0.01 s apart a rate rises by at most jerk·h²/8 above them (1e-4 of a limit at 3 rad/s³)
RATE_TRIGGER = 0.999


@dataclass(frozen=True)
class RatePeak:
    """One joint's largest rate between two bounded instants of the approach."""

    joint: int  # 0-based
    stretch: int  # between the NLP's bounded instants stretch − 1 and stretch (0: before the first)
    t_s: float  # since the approach's start [s]
    rate_rad_s: float  # signed [rad/s]
    ratio: float  # |rate| over the joint's limit


def rate_peaks(problem: ApproachProblem, samples: PhaseSamples, above: float = RATE_TRIGGER) -> list[RatePeak]:
    """Each joint's largest rate in each stretch between the NLP's bounded instants of ``problem`` where it exceeds
    ``above`` × its limit, along the approach sampled as ``samples``; the highest ratio first."""
    stretch = np.searchsorted(problem.rate_times_s, samples.t, side="left")
    qd_max = problem.robot.qd_max
    peaks = []
    for s in np.unique(stretch):
        inside = np.flatnonzero(stretch == s)
        worst = inside[np.abs(samples.qd[inside]).argmax(axis=0)]
        for j, i in enumerate(worst):
            rate = float(samples.qd[i, j])
            if abs(rate) > above * qd_max[j]:
                peaks.append(RatePeak(j, int(s), float(samples.t[i]), rate, abs(rate) / qd_max[j]))
    return sorted(peaks, key=lambda p: -p.ratio)


def lowered_rates(problem: ApproachProblem, samples: PhaseSamples,
                  bounds: ApproachBounds) -> tuple[ApproachBounds | None, list[RatePeak]]:
    """The joint-velocity rows' bounds of a re-solve, ``bounds``' own tightened where the approach sampled as
    ``samples`` peaks above :data:`RATE_TRIGGER` of a limit between two bounded instants, and the peaks (None and
    [] when none does)."""
    peaks = rate_peaks(problem, samples)
    if not peaks:
        return None, []
    times, n = problem.rate_times_s, problem.robot.n_joints
    lower, upper = (b.reshape(len(times), n) for b in bounds.rates(problem))
    at_rows = np.column_stack([np.interp(times, samples.t, samples.qd[:, j]) for j in range(n)])
    bound = backoff.JOINT_VELOCITY_FRACTION * problem.robot.qd_max
    for p in peaks:
        excess = abs(p.rate_rad_s) - bound[p.joint]
        for row in (r for r in (p.stretch - 1, p.stretch) if 0 <= r < len(times)):
            if p.rate_rad_s > 0:  # the box keeps 0: the row's rate may fall to rest, never be pushed across
                upper[row, p.joint] = min(upper[row, p.joint], max(at_rows[row, p.joint] - excess, 0.0))
            else:
                lower[row, p.joint] = max(lower[row, p.joint], min(at_rows[row, p.joint] + excess, 0.0))
    return ApproachBounds(rate_lower_rad_s=lower.ravel(), rate_upper_rad_s=upper.ravel()), peaks
