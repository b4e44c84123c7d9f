"""Cost terms (paper Eq. 14-16 and the stabilization costs), symbolic for the NLPs and numeric for reports."""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import NDArray


def manipulability_sym(J):  # noqa: ANN001, ANN201
    """Eq. 14: ``sqrt(det(J Jᵀ))`` of the (6×7) generalized Jacobian (maximised)."""
    return ca.sqrt(ca.det(ca.mtimes(J, J.T)))


def manipulability(J: NDArray[np.float64]) -> float:
    """Numeric Eq. 14."""
    return float(np.sqrt(max(np.linalg.det(J @ J.T), 0.0)))


def approach_energy(base_offset_m: NDArray[np.float64]) -> float:
    """Eq. 16: ``‖θ_b(0)‖²`` (m²), the translation of the spacecraft approach maneuver."""
    return float(np.dot(base_offset_m, base_offset_m))
