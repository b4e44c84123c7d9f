"""The observed state of the target at t = 0: attitude ``q_world_body`` and body rates [rad/s]."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.errors import NonUnitQuaternionError, StateFieldError
from planner.model.target_validation import frozen_copy, validate_vector

# ‖q‖ may deviate from 1 by this much in an observed state (estimator output is rounded); it is then
# renormalised. Larger deviations mean a wrong field (e.g. Euler angles or [x, y, z, w] garbage).
UNIT_QUATERNION_TOL = 1e-6


@dataclass(frozen=True)
class TargetState:
    """Observed target state at ``t = 0``.

    ``attitude_wxyz``: ``q_world_body``, unit (within 1e-6; stored renormalised).
    ``omega_body_rad_s``: angular velocity of the body w.r.t. the world, in the body frame [rad/s].
    Invalid values raise ``TargetStateError`` naming the field.
    """

    attitude_wxyz: NDArray[np.float64]  # (4,)
    omega_body_rad_s: NDArray[np.float64]  # (3,) [rad/s]

    def __post_init__(self) -> None:
        q_world_body = validate_vector(self.attitude_wxyz, 4, "attitude_wxyz", StateFieldError)
        norm = float(np.linalg.norm(q_world_body))
        if abs(norm - 1.0) > UNIT_QUATERNION_TOL:
            raise NonUnitQuaternionError(
                "attitude_wxyz",
                f"must be a unit quaternion [w, x, y, z] (|norm - 1| <= {UNIT_QUATERNION_TOL:g}), got norm {norm:.9g}",
                norm,
            )
        omega_body = validate_vector(self.omega_body_rad_s, 3, "omega_body_rad_s", StateFieldError)
        # Frozen dataclass: object.__setattr__ is the sanctioned way to normalise fields in __post_init__.
        object.__setattr__(self, "attitude_wxyz", frozen_copy(q_world_body / norm))
        object.__setattr__(self, "omega_body_rad_s", frozen_copy(omega_body))
