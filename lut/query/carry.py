"""How far a table's plans carry: a state farther from them than that is solved at once, none of them tried (none is
known to verify that far).

A tumble plan (README "How far a plan carries"): a measured attitude or body rate from the nearest grid point. A flat
spin's phase is an exact time shift, so only its rate and the direction of its spin axis count; inside its grid's box
its corners are tried as they are (the coarse envelope grid's corners, 60° and 1 °/s apart, answer some states), and
outside it by more than half that cell they are not: at 20 seeded states that far outside the CI table none of its
plans verified, and the query lost to the cold plan it ends with (README "A flat-spin table far from the state"). A
state far from every flat spin (a tumble given to a flat-spin table) is judged first, as a tumble plan carries.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from planner.model.rotation import quat_to_matrix, rotation_log
from planner.model.target_state import TargetState

# the carry bench (10 seeded tumbles a scenario, their plans re-verified at displaced states, repaired as the query
# repairs): none verified 20° of attitude or 1 °/s of body rate away (README "How far a plan carries")
CARRY_ATTITUDE_DEG = 20.0
CARRY_RATE_DEG_S = 1.0
# a flat spin outside its table's grid: as far as half the coarse envelope grid's cell (60° of spin axis, 1 °/s) from
# the grid's box its plans are still tried, beyond that not; the carry bench found 1 plan of 35 verifying 30° of spin
# axis away and none at 45°, and a 1 °/s rate limit gained 1 query of 16 for a slower tail (README "How far a
# flat-spin plan carries")
FLAT_SPIN_AXIS_DEG = 30.0
FLAT_SPIN_RATE_DEG_S = 0.5


@dataclass(frozen=True)
class CarryLimits:
    """How far a plan of one kind of table carries: its attitude (a tumble: the rotation between two attitudes; a flat
    spin: the angle between two spin axes) [deg] and body rate [deg/s]; ``at_limit``: whether a state exactly that far
    is already beyond."""

    kind: str
    attitude_deg: float
    rate_deg_s: float
    at_limit: bool

    def beyond(self, attitude_deg: float, rate_deg_s: float) -> bool:
        """True when a plan this far in attitude or rate is not known to verify."""
        if self.at_limit:
            return attitude_deg >= self.attitude_deg or rate_deg_s >= self.rate_deg_s
        return attitude_deg > self.attitude_deg or rate_deg_s > self.rate_deg_s


TUMBLE = CarryLimits("tumble", CARRY_ATTITUDE_DEG, CARRY_RATE_DEG_S, at_limit=True)
FLAT_SPIN = CarryLimits("flat-spin", FLAT_SPIN_AXIS_DEG, FLAT_SPIN_RATE_DEG_S, at_limit=False)


@dataclass(frozen=True)
class Displacement:
    """How far an observed state is from a table's plans, in attitude [deg] and body rate [deg/s] as ``limits`` measure
    them: a tumble from grid point ``point`` (each in its own body frame, as a tumble grid's axes are); a flat spin
    (``point`` None) from its grid's box, in spin axis and rate."""

    point: int | None
    attitude_deg: float
    rate_deg_s: float
    limits: CarryLimits = TUMBLE
    off_family: bool = False  # from the state's nearest flat spin (a tumble given to a flat-spin table)

    @property
    def beyond_carry(self) -> bool:
        """True when no plan of this kind is known to verify this far (:attr:`limits`)."""
        return self.limits.beyond(self.attitude_deg, self.rate_deg_s)

    def note(self) -> str:
        """The answer's note: the query solved at the state, and why."""
        lim, far = self.limits, f"{self.attitude_deg:.1f}° and {self.rate_deg_s:.2f} °/s"
        if self.off_family:
            where = f"this state is {far} from its nearest flat spin"
        elif self.point is not None:
            where = f"the table's nearest plan (point {self.point}) is {far} from this state"
        else:
            where = (f"this state is {self.attitude_deg:.1f}° of spin axis and {self.rate_deg_s:.2f} °/s outside the "
                     "table's grid")
        return (f"{where}, beyond what a {lim.kind} plan carries ({lim.attitude_deg:g}°, {lim.rate_deg_s:g} °/s): its "
                "plans not tried")


def displacement(point: int | None, state: TargetState, point_state: TargetState) -> Displacement:
    """``state``'s displacement from tumble grid point ``point`` (whose state is ``point_state``; None: a state that is
    no grid point's); q and −q alike."""
    turn = quat_to_matrix(point_state.attitude_wxyz).T @ quat_to_matrix(state.attitude_wxyz)
    angle = float(np.linalg.norm(rotation_log(turn)))
    rate = float(np.linalg.norm(np.asarray(state.omega_body_rad_s) - np.asarray(point_state.omega_body_rad_s)))
    return Displacement(point, math.degrees(angle), math.degrees(rate))


def off_flat_spin_family(state: TargetState, nearest_flat_spin: TargetState) -> Displacement:
    """How far ``state`` is from its nearest flat spin (a grid's family member), judged as a tumble plan's carry: a
    flat spin's plan given a tumbling state is a plan displaced by that attitude and body rate."""
    return replace(displacement(None, state, nearest_flat_spin), off_family=True)


def outside_flat_spin_grid(rate_axis: Sequence[float], in_grid_rate_axis: Sequence[float]) -> Displacement:
    """How far a flat spin lies outside a grid's box: ``rate_axis`` is its (spin rate [deg/s], spin-axis angle in the
    orbital x–z plane [deg]), ``in_grid_rate_axis`` the nearest in the box; the angle between the axes is taken round
    the circle."""
    turn = (float(rate_axis[1]) - float(in_grid_rate_axis[1]) + 180.0) % 360.0 - 180.0
    return Displacement(None, abs(turn), abs(float(rate_axis[0]) - float(in_grid_rate_axis[0])), FLAT_SPIN)


def nearest_displacement(corners: list[int], state: TargetState,
                         point_state: Callable[[int], TargetState]) -> Displacement | None:
    """The displacement of ``state`` from the nearest of a tumble table's ``corners`` (the larger of attitude and rate,
    each in units of its carry; ``point_state``: a grid point's state); None without corners."""
    moves = [displacement(c, state, point_state(c)) for c in corners]
    return min(moves, key=_relative_to_carry, default=None)


def _relative_to_carry(move: Displacement) -> float:
    """The larger of ``move``'s attitude and rate, each in units of its carry."""
    return max(move.attitude_deg / move.limits.attitude_deg, move.rate_deg_s / move.limits.rate_deg_s)


def rate_and_axis(coords: NDArray[np.float64], axis_names: list[str]) -> tuple[float, float]:
    """(spin rate [deg/s], spin-axis angle [deg]) of a flat-spin grid's ``coords``, by its axes' names."""
    return float(coords[axis_names.index("spin_rate_deg_s")]), float(coords[axis_names.index("spin_axis_angle_deg")])
