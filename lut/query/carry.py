"""How far a tumble table's plan carries: from a grid point farther than a measured attitude or body rate, no plan
verifies, so the query solves at the observed state at once (README "How far a plan carries").

A flat-spin table is not judged so: its phase is an exact time shift, and its plans carry across its coarse cells
(README "Envelope tables": a corner's plan 30° and 0.5 °/s away answers some states).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planner.model.rotation import quat_to_matrix, rotation_log
from planner.model.target_state import TargetState

# the carry bench (10 seeded tumbles a scenario, their plans re-verified at displaced states, repaired as the query
# repairs): none verified 20° of attitude or 1 °/s of body rate away (README "How far a plan carries")
CARRY_ATTITUDE_DEG = 20.0
CARRY_RATE_DEG_S = 1.0


@dataclass(frozen=True)
class Displacement:
    """How far an observed state is from a grid point's: the rotation between their attitudes [deg] and the norm of
    the difference of their body rates [deg/s] (each in its own body frame, as a tumble grid's axes are)."""

    point: int
    attitude_deg: float
    rate_deg_s: float

    @property
    def beyond_carry(self) -> bool:
        """True when no tumble plan is known to verify this far (:data:`CARRY_ATTITUDE_DEG`,
        :data:`CARRY_RATE_DEG_S`)."""
        return self.attitude_deg >= CARRY_ATTITUDE_DEG or self.rate_deg_s >= CARRY_RATE_DEG_S

    def note(self) -> str:
        """The answer's note: the query solved at the state, and why."""
        return (f"the table's nearest plan (point {self.point}) is {self.attitude_deg:.1f}° and {self.rate_deg_s:.2f} "
                f"°/s from this state, beyond what a tumble plan carries ({CARRY_ATTITUDE_DEG:g}°, "
                f"{CARRY_RATE_DEG_S:g} °/s): its plans not tried")


def displacement(point: int, state: TargetState, point_state: TargetState) -> Displacement:
    """``state``'s displacement from grid point ``point`` (whose state is ``point_state``); q and −q alike."""
    turn = quat_to_matrix(point_state.attitude_wxyz).T @ quat_to_matrix(state.attitude_wxyz)
    angle = float(np.linalg.norm(rotation_log(turn)))
    rate = float(np.linalg.norm(np.asarray(state.omega_body_rad_s) - np.asarray(point_state.omega_body_rad_s)))
    return Displacement(point, math.degrees(angle), math.degrees(rate))


def nearest_displacement(corners: list[int], state: TargetState,
                         point_state: Callable[[int], TargetState]) -> Displacement | None:
    """The displacement of ``state`` from the nearest of ``corners`` (the larger of attitude and rate, each in units
    of its carry; ``point_state``: a grid point's state); None without corners."""
    moves = [displacement(c, state, point_state(c)) for c in corners]
    return min(moves, key=_relative_to_carry, default=None)


def _relative_to_carry(move: Displacement) -> float:
    """The larger of ``move``'s attitude and rate, each in units of its carry."""
    return max(move.attitude_deg / CARRY_ATTITUDE_DEG, move.rate_deg_s / CARRY_RATE_DEG_S)
