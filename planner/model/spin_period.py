"""When a torque-free target's motion repeats: a spin about a principal axis of inertia, every 2π/|ω|.

Euler's equations keep ω constant in the body exactly when ω × (I ω) = 0, i.e. ω lies along a principal axis; the
attitude then turns about a fixed axis and returns to itself every 2π/|ω|, so a plan started one period later meets
the same grasp. Any other motion (a general tumble) never repeats its attitude: no time shift carries a plan.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from planner.model.target_state import TargetState

NO_REPEAT_S = math.inf  # the period of a motion that does not repeat (a tumble, or a target at rest) [s]
# the angle [rad] within which ω and I ω count as parallel (the grids' own flat-spin tolerance)
PRINCIPAL_TOL_RAD = 1e-6


def repeat_period_s(state: TargetState, inertia_body_kg_m2: ArrayLike) -> float:
    """The time [s] after which ``state``'s torque-free motion repeats: 2π/|ω| for a spin about a principal axis of
    ``inertia_body_kg_m2`` [kg·m², body frame] (within :data:`PRINCIPAL_TOL_RAD`), else :data:`NO_REPEAT_S`."""
    omega = np.asarray(state.omega_body_rad_s, dtype=float)
    rate = float(np.linalg.norm(omega))
    if rate == 0.0:
        return NO_REPEAT_S
    momentum = np.asarray(inertia_body_kg_m2, dtype=float) @ omega
    off = math.atan2(float(np.linalg.norm(np.cross(omega, momentum))), float(omega @ momentum))
    return 2 * math.pi / rate if off <= PRINCIPAL_TOL_RAD else NO_REPEAT_S
