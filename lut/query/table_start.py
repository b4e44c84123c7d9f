"""When a table's plan starts at the observed state: whole spin periods into the window, and after the answer.

A spin about a principal axis repeats itself every spin period 2π/|ω| (:mod:`planner.model.spin_period`): a plan
carried to the state's phase may start any whole number of periods later and meet the same grasp. A tumble does not
repeat (its attitude is not periodic, whatever its rate), so a tumble table's plan keeps the start it has. A live
query's plan must also start after its answer can come (:mod:`lut.cli.answer_time`): a table plan that would start
before it is moved a period later where the window holds it, else not tried at all (verified, it could only be refused
as late).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from planner.model.spin_period import repeat_period_s
from planner.model.target_state import TargetState
from planner.plan_parameters import wrap_start_delay


def placed_start_s(start_delay_s: float, period_s: float, window_s: tuple[float, float],
                   earliest_s: float = -math.inf) -> float | None:
    """The start delay [s after the observation] a table plan carried to ``start_delay_s`` takes: moved by whole
    periods ``period_s`` into ``window_s`` (earliest, latest) [s] as :func:`~planner.plan_parameters.wrap_start_delay`
    does (no move for an infinite period); if that comes before ``earliest_s`` (when the answer can come), the first
    whole period after it within the window; None when no such start lies in the window (the plan would be late)."""
    finite = math.isfinite(period_s) and period_s > 0
    tau = wrap_start_delay(start_delay_s, period_s, window_s) if finite else start_delay_s
    if tau >= earliest_s:
        return tau
    if not finite:
        return None
    later = tau + math.ceil((earliest_s - tau) / period_s) * period_s
    return later if later <= window_s[1] else None


def table_period_s(state: TargetState, inertia_body_kg_m2: ArrayLike, flat_spin_table: bool) -> float:
    """The period [s] by which a table's plan may be moved at ``state``: a flat-spin table answers the state as a flat
    spin (an estimator's is a little off it), 2π/|ω|; another table, the motion's own repeat period (none for a
    tumble)."""
    rate = float(np.linalg.norm(state.omega_body_rad_s))
    if flat_spin_table and rate > 0:
        return 2 * math.pi / rate
    return repeat_period_s(state, inertia_body_kg_m2)
