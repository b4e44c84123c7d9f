"""Cost terms (paper Eq. 14-16 and the stabilization costs), symbolic for the NLPs and numeric for reports."""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import NDArray

# det(J Jᵀ) is taken at least this: at a singular pose it is zero or, by rounding, negative, and √ of it (or its
# gradient, which the tracking IK's null space follows) would be NaN
DET_FLOOR = 1e-16


def manipulability_sym(J: ca.MX | ca.SX) -> ca.MX | ca.SX:
    """Eq. 14: ``sqrt(det(J Jᵀ))`` of the generalized Jacobian ``(6, 7)`` (maximised); below :data:`DET_FLOOR`
    ``sqrt(DET_FLOOR)`` with a zero gradient, not NaN (a branch, so that above it the numbers are √det's bit for
    bit: a stored plan's re-simulation reproduces its samples)."""
    det = ca.det(ca.mtimes(J, J.T))
    return ca.if_else(det > DET_FLOOR, ca.sqrt(det), np.sqrt(DET_FLOOR))


def manipulability(J: NDArray[np.float64]) -> float:
    """Numeric Eq. 14, floored like :func:`manipulability_sym`."""
    return float(np.sqrt(max(np.linalg.det(J @ J.T), DET_FLOOR)))


def approach_energy(base_offset_m: NDArray[np.float64]) -> float:
    """Eq. 16: ``‖θ_b(0)‖²`` [m²] of the base offset ``(2,)`` [m] (the spacecraft approach manoeuvre)."""
    return float(np.dot(base_offset_m, base_offset_m))
