"""What the approach's scan of meeting times found: its NLP starts, the outcome at each meeting time, the verdict.

A state is out of reach when no meeting time gave a start: *proven* (:mod:`planner.phases.reach_proof`, no plan
exists), or as far as the scan's local IK can tell.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from planner.phases.reach_proof import ReachProof

Array = NDArray[np.float64]

DELAY_STEP_S = 2.0  # candidate meeting times are this far apart
SAME_TIME_S = 1e-9  # a step this close before the window's end is its end [s]


def scan_times_s(window_s: tuple[float, float]) -> list[float]:
    """The start delays [s] the scan tries over ``window_s`` = (earliest, latest): every :data:`DELAY_STEP_S` from
    the earliest, and the latest itself: a grasp reachable only at the end of a window whose length is no whole
    number of steps was otherwise never scanned."""
    earliest, latest = window_s
    return [float(t) for t in np.arange(earliest, latest - SAME_TIME_S, DELAY_STEP_S)] + [float(latest)]


@dataclass(frozen=True)
class ApproachGuess:
    """One NLP start: the approach's decision parameters, with the pose IK's answers it was fitted to."""

    params: Array  # (7·(N−5),) Eq. 23 free parameters, planner.nlp.phase_spline layout [rad, rad/s³]
    base_offset_m: Array  # (2,) θ_b(0): (x, z) [m]
    start_delay_s: float  # [s]
    q_pregrasp: Array  # (7,) [rad]
    q_tracking: Array  # (len(TRACKING_NODES), 7) [rad]
    clearance_m: float  # smallest distance of its configurations [m]
    free_axis_angle_rad: float | None = None  # the angle about a free grasp axis it holds the handle at [rad]


class MeetingOutcome(Enum):
    """What the scan found at one candidate meeting time."""

    REACHED = "reached"  # pre-grasp and tracking poses solved: a candidate NLP start
    BEYOND_REACH = "beyond reach"  # the pre-grasp is farther than the arm reaches from every admissible base offset
    IK_UNSOLVED = "IK unsolved"  # within that bound, but the bounded IK found no pre-grasp or tracking pose


@dataclass(frozen=True)
class ReachScan:
    """The scan of meeting times over the start-delay window: its NLP starts and what it found at each time.

    ``proof``: the reach proof made before the scan; when it proves the state out of reach no meeting time is
    scanned (``outcomes`` empty).
    """

    guesses: list[ApproachGuess]
    window_s: tuple[float, float]  # the start-delay window (earliest, latest) [s]
    outcomes: tuple[MeetingOutcome, ...]  # one per scanned meeting time, scan_times_s(window_s)
    proof: ReachProof | None = None

    @property
    def reachable(self) -> bool:
        """True when at least one meeting time gave an NLP start."""
        return MeetingOutcome.REACHED in self.outcomes

    def reached_start_delays_s(self) -> list[tuple[float, float]]:
        """The start delays [s] at which the scan reached the grasp, as intervals ``(first, last)``: meeting times one
        scan step apart share an interval."""
        intervals: list[tuple[float, float]] = []
        if not self.outcomes:  # nothing scanned (the reach proof held)
            return intervals
        for t, outcome in zip(scan_times_s(self.window_s), self.outcomes, strict=True):
            if outcome != MeetingOutcome.REACHED:
                continue
            if intervals and t - intervals[-1][1] <= DELAY_STEP_S + SAME_TIME_S:
                intervals[-1] = (intervals[-1][0], t)
            else:
                intervals.append((t, t))
        return intervals

    @property
    def proven_out_of_reach(self) -> bool:
        """True when no plan can reach the grasp (not only the scan's IK)."""
        return self.proof is not None and self.proof.proven

    def reason(self) -> str:
        """Why nothing was reachable, in one sentence (for an infeasible answer)."""
        if self.proven_out_of_reach:
            return self.proof.reason()
        beyond = self.outcomes.count(MeetingOutcome.BEYOND_REACH)
        unsolved = self.outcomes.count(MeetingOutcome.IK_UNSOLVED)
        return (f"out of reach: no meeting time within the start-delay window "
                f"[{self.window_s[0]:g}, {self.window_s[1]:g}] s is reachable "
                f"(of {len(self.outcomes)} scanned every {DELAY_STEP_S:g} s and at its end, the pre-grasp is beyond "
                f"the arm's reach at {beyond}; at {unsolved} the arm cannot take the pre-grasp and tracking poses; the "
                f"scan's verdict, not a proof)")
