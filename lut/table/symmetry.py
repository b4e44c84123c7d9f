"""The flat spin's phase ↔ time symmetry: a state at another spin phase is the same state, earlier or later.

A target spinning at ``r`` [deg/s] reaches phase ``φ₁`` from ``φ₀`` after ``(φ₁ − φ₀) / r`` [s]; so a plan made
at phase ``φ₀`` serves phase ``φ₁`` with its start delay shifted by ``−(φ₁ − φ₀) / r``. This is why a
flat-spin grid's phase axis may be coarse (docs/table.md, Grid symmetries). A build carries a warm start
from a parent point to its child with it; a query carries a corner's plan to the observed phase.

A plan carried to another rate keeps the spin angle at which it meets the target: at ``r₀`` it meets the target
at ``φ₀ + r₀·t_m``, at ``r₁`` the same angle is ``(r₀ − r₁)·t_m / r₁`` later than the phase shift alone says
(0.5 °/s over a 60 s meeting is 30° of spin: the arm would reach for the handle where it is not).
"""

from __future__ import annotations

import math

PHASE_SNAP_DEG = 1e-9  # phases this close are the same phase (the roundoff of quaternion → angle) [deg]


def phase_time_shift_s(phase_from_deg: float, phase_to_deg: float, rate_deg_s: float) -> float:
    """Time [s] a flat spin at ``phase_from_deg`` takes to reach ``phase_to_deg`` (mod 360) at ``rate_deg_s``.

    The smallest non-negative shift: ``((to - from) mod 360) / rate``, in ``[0, 360 / rate)``; a
    difference within :data:`PHASE_SNAP_DEG` of a full turn counts as 0. ``rate_deg_s`` must be finite and > 0.
    """
    rate = float(rate_deg_s)
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"rate_deg_s must be finite and > 0, got {rate_deg_s!r}")
    d = (float(phase_to_deg) - float(phase_from_deg)) % 360.0
    if not math.isfinite(d):
        raise ValueError(f"phases must be finite, got {phase_from_deg!r}, {phase_to_deg!r}")
    if d > 360.0 - PHASE_SNAP_DEG:
        d = 0.0
    return d / rate


def start_delay_shift_s(phase_from_deg: float, phase_to_deg: float, rate_deg_s: float, *,
                        forward_turn: bool = False, rate_from_deg_s: float | None = None,
                        meeting_s: float = 0.0) -> float:
    """The start-delay shift [s] that carries a plan made at ``phase_from_deg`` to ``phase_to_deg`` [deg] at
    ``rate_deg_s`` [deg/s], keeping the spin angle at which it meets the target.

    ``−Δφ / rate``: the target at the later phase reaches the plan's configuration Δφ / rate earlier. Phases
    within :data:`PHASE_SNAP_DEG` are one phase (no phase shift, so a plan at its own node keeps its start delay
    bit for bit), and a non-positive rate gives 0. ``forward_turn`` counts Δφ forward, in [0°, 360°) (the
    build's rule); otherwise Δφ is the plain signed difference (the query's). The two differ by whole spin
    periods, which the start-delay wrap (:meth:`planner.plan_parameters.PlanParameters.shifted_in_time`)
    removes; each keeps its own roundoff, so tables and plans stay bit-identical. A plan made at another rate
    ``rate_from_deg_s`` (None: the same) that meets the target ``meeting_s`` [s] after the observation is shifted
    by ``(rate_from − rate)·meeting_s / rate`` more, so that it meets the target at the same spin angle.
    """
    if not rate_deg_s > 0:
        return 0.0
    d = phase_to_deg - phase_from_deg
    shift = 0.0
    if abs(d) > PHASE_SNAP_DEG:
        shift = -phase_time_shift_s(phase_from_deg, phase_to_deg, rate_deg_s) if forward_turn else -d / rate_deg_s
    if rate_from_deg_s is not None:  # 0 at the same rate: the phase shift bit for bit
        shift += (rate_from_deg_s - rate_deg_s) * meeting_s / rate_deg_s
    return shift
