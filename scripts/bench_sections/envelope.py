"""Seeded target states across the paper's envelope (§3): flat spins about the major axis and general tumbles.

Shared by the benchmark's coverage section and ``scripts/make_truth_plans.py``. Attitudes are unit quaternions
``wxyz`` (target body frame in the orbital frame O), body rates in °/s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

if TYPE_CHECKING:
    from planner.model.target_state import TargetState

Array = NDArray[np.float64]
TUMBLE_RATE_MAX_DEG_S = 4.0  # paper §3: up to ±4 °/s about each body axis
FLAT_SPIN_RATE_DEG_S = (1.0, 4.0)  # |ω| of a flat spin: the paper's 4 °/s bound, from a rate that still tumbles


@dataclass(frozen=True)
class EnvelopeState:
    """One observed target state: attitude (wxyz, body in O) and body rates (°/s)."""

    attitude_wxyz: Array
    omega_body_deg_s: Array

    def target_state(self) -> TargetState:
        """This state as the planner's :class:`~planner.model.target_state.TargetState` (body rates in rad/s)."""
        from planner.model.target_state import TargetState

        return TargetState(self.attitude_wxyz, np.radians(self.omega_body_deg_s))


def major_axis_body(inertia_body_kg_m2: Array) -> Array:
    """Unit body-frame axis of the largest principal moment (kg·m²), the flat spin's axis."""
    moments, axes = np.linalg.eigh(np.asarray(inertia_body_kg_m2, dtype=float))
    axis = axes[:, int(np.argmax(moments))]
    return axis if axis[int(np.argmax(np.abs(axis)))] > 0 else -axis


def flat_spin_state(rng: np.random.Generator, major_axis_body: Array,
                    rate_range_deg_s: tuple[float, float] = FLAT_SPIN_RATE_DEG_S) -> EnvelopeState:
    """Spin about the body's major axis (unit, body frame) pointing along (cos α, 0, sin α) in O, α and the
    phase about the axis uniform over the full turn, |ω| uniform in ``rate_range_deg_s``."""
    axis = np.asarray(major_axis_body, dtype=float)
    alpha, phase = rng.uniform(0.0, 2 * np.pi), rng.uniform(0.0, 2 * np.pi)
    to_spin = Rotation.align_vectors([[np.cos(alpha), 0.0, np.sin(alpha)]], [axis])[0]
    R = to_spin * Rotation.from_rotvec(phase * axis)
    return EnvelopeState(wxyz(R), float(rng.uniform(*rate_range_deg_s)) * axis)


def tumble_state(rng: np.random.Generator) -> EnvelopeState:
    """Uniformly random attitude and body rates uniform in ±4 °/s about each body axis."""
    return EnvelopeState(wxyz(Rotation.random(random_state=rng)),
                         rng.uniform(-TUMBLE_RATE_MAX_DEG_S, TUMBLE_RATE_MAX_DEG_S, 3))


def wxyz(R: Rotation) -> Array:
    """The rotation as a scalar-first unit quaternion."""
    x, y, z, w = R.as_quat()
    return np.array([w, x, y, z])
