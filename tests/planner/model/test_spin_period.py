"""A torque-free motion repeats every 2π/|ω| exactly when it spins about a principal axis: checked against the
integrated attitude (DOP853, the closed form skipped), not against the criterion's own algebra."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planner.model.attitude import propagate
from planner.model.spin_period import NO_REPEAT_S, PRINCIPAL_TOL_RAD, repeat_period_s
from planner.model.target_state import TargetState

DEG = math.pi / 180.0
# a full inertia (not diagonal in the body frame): principal axes found by eigh, not read off the axes
ROTATION = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))[0]
INERTIA = ROTATION @ np.diag([800.0, 1100.0, 1500.0]) @ ROTATION.T
Q0 = np.array([0.9, 0.1, -0.3, 0.3]) / np.linalg.norm([0.9, 0.1, -0.3, 0.3])


def _turned_back(omega_body_rad_s: np.ndarray, after_s: float) -> float:
    """The angle [rad] between the attitude at ``after_s`` of the integrated motion and the initial attitude."""
    state = TargetState(Q0, omega_body_rad_s)
    q = propagate(INERTIA, state, after_s, force_integration=True).attitude_wxyz([after_s])[0]
    return 2.0 * math.acos(min(1.0, abs(float(q @ Q0))))


@pytest.mark.parametrize("axis", [0, 1, 2])  # major, intermediate (unstable, still periodic) and minor
def test_a_spin_about_each_principal_axis_repeats_every_spin_period(axis):
    omega = 4.0 * DEG * np.linalg.eigh(INERTIA)[1][:, axis]
    period = repeat_period_s(TargetState(Q0, omega), INERTIA)
    assert period == pytest.approx(90.0, rel=1e-12)
    assert _turned_back(omega, period) < 1e-7
    assert _turned_back(omega, 0.5 * period) > 3.0  # half a turn: not repeated before


def test_a_tumble_has_no_period_its_attitude_never_returns_after_2pi_over_omega():
    omega = np.array([4.0, 4.0, 4.0]) * DEG
    assert repeat_period_s(TargetState(Q0, omega), INERTIA) == NO_REPEAT_S
    period = 2 * math.pi / float(np.linalg.norm(omega))
    assert _turned_back(omega, period) > 0.1  # what a period shift would assume is 0


def test_a_spin_off_a_principal_axis_beyond_the_tolerance_and_a_target_at_rest_have_no_period():
    axis = np.linalg.eigh(INERTIA)[1][:, 2]
    off = np.cross(axis, [1.0, 0.0, 0.0])
    off /= np.linalg.norm(off)
    within = 4.0 * DEG * (axis + 0.5 * PRINCIPAL_TOL_RAD * off)
    beyond = 4.0 * DEG * (axis + 1e-3 * off)
    assert math.isfinite(repeat_period_s(TargetState(Q0, within), INERTIA))
    assert repeat_period_s(TargetState(Q0, beyond), INERTIA) == NO_REPEAT_S
    assert repeat_period_s(TargetState(Q0, np.zeros(3)), INERTIA) == NO_REPEAT_S
