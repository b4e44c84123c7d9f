"""Timing profile of the tracking phase, shared by the tracking IK and the approach NLP (paper §4.2).

Over the tracking time t_f² the desired end-effector pose blends from the pre-grasp pose (reached at rest
by the approach) onto the moving grasp frame by ``BLEND_END``·t_f², the back-off distance closes to zero
by ``CLOSE_END``·t_f², and the last part is pure tracking at zero relative pose and velocity. All
profiles are quintic smoothsteps: zero rate and acceleration at both ends, so joint velocity and
acceleration stay continuous with the approach, which ends at rest (Eq. 6, 23).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

BLEND_END = 0.6  # fraction of t_f² at which the desired pose has fully joined the grasp frame
CLOSE_END = 0.8  # fraction of t_f² at which the back-off distance is closed
GAIN_RAMP = 0.2  # fraction of t_f² over which the feedback and null-space gains ramp up
# tracking nodes of the approach NLP (fractions of t_f²): on the grasp frame, closing, grasped
TRACKING_NODES = (BLEND_END, CLOSE_END, 1.0)


def smoothstep5(s: ArrayLike) -> NDArray[np.float64]:
    """Quintic 0→1 blend of ``s`` clipped to [0, 1], zero first and second derivatives at both ends."""
    s = np.minimum(np.maximum(np.asarray(s, dtype=float), 0.0), 1.0)  # np.clip, without its per-call overhead
    return s**3 * (10 - 15 * s + 6 * s**2)


def node_segment(t_s: float, tracking_s: float) -> int:
    """Index of the tracking segment (between consecutive :data:`TRACKING_NODES`, the first from the start) that
    holds phase time ``t_s`` [s]."""
    return next((i for i, f in enumerate(TRACKING_NODES) if t_s <= f * tracking_s), len(TRACKING_NODES) - 1)


def backoff_m(backoff0_m: float, t_s: float, tracking_s: float) -> float:
    """Remaining back-off distance [m] at time ``t_s`` into the tracking phase."""
    return float(backoff0_m * (1.0 - smoothstep5(t_s / (CLOSE_END * tracking_s))))


def blend(t_s: float, tracking_s: float) -> float:
    """Weight (0→1) of the moving grasp frame in the desired pose at ``t_s`` into tracking."""
    return float(smoothstep5(t_s / (BLEND_END * tracking_s)))


def gain_ramp(t_s: float, tracking_s: float) -> float:
    """Ramp (0→1) of the feedback and null-space gains: no velocity jump at the approach join."""
    return float(smoothstep5(t_s / (GAIN_RAMP * tracking_s)))
