"""A live plan's meeting times still in time: the rule for a scanned guess, and a scan of the window left.

A live plan's approach cannot start before its answer can come (:meth:`planner.deadline.Deadline.earliest_start_s`).
The scan of meeting times is made at the plan's start over the whole start-delay window; a stage that comes later (a
costed plan's feasibility stage after the costed optimum's share of the budget, an approach from another base offset
after the retries) may find every guess of it already too early, and then scans the window from the earliest start on.
"""

from __future__ import annotations

import math

from planner.config.scenario import Scenario
from planner.deadline import Deadline
from planner.phases.approach_guess import ScanOnDemand
from planner.phases.reach_scan_result import DELAY_STEP_S


def meets_in_time(start_delay_s: float, deadline: Deadline) -> bool:
    """Whether a scanned guess starting at ``start_delay_s`` [s] is worth a start under ``deadline``: it meets no more
    than one scan step before the earliest start (the NLP's bound raises it that little); any, without an
    observation."""
    return start_delay_s + DELAY_STEP_S >= deadline.earliest_start_s()


def window_in_time(scenario: Scenario, deadline: Deadline) -> Scenario:
    """``scenario`` whose start-delay window begins no earlier than one scan step after ``deadline``'s earliest start
    (the scan's own time: its guesses are still in time when it ends), on the whole window's grid of meeting times (a
    scan of it tries the times a scan of the whole window tried), unchanged without an observation or when that would
    close the window."""
    phases = scenario.phases
    after_s = deadline.earliest_start_s() + DELAY_STEP_S - phases.min_start_delay_s
    if not after_s > 0:
        return scenario
    earliest_s = phases.min_start_delay_s + math.ceil(after_s / DELAY_STEP_S) * DELAY_STEP_S
    if earliest_s > phases.max_start_delay_s:
        return scenario
    return scenario.starting_from(earliest_s)


def scan_in_time(scan: ScanOnDemand, deadline: Deadline) -> ScanOnDemand:
    """``scan``, or, when it was made, has guesses and none of them meets in time under ``deadline`` any more, a scan
    of the same state over :func:`window_in_time` (made when first asked for; a scan that reached nothing is kept)."""
    guesses = scan.result.guesses if scan.made else []
    if not guesses or any(meets_in_time(g.start_delay_s, deadline) for g in guesses):
        return scan
    later = window_in_time(scan.scenario, deadline)
    return scan if later is scan.scenario else ScanOnDemand(later, scan.spline, scan.state, scan.count,
                                                            scan.held_angles)
