"""The table's operations on plan parameters: the start-delay wrap and the weighted mean on the spin circle.

Degenerate cases on purpose: a delay exactly at the window's end, a tiny negative delay whose modulo rounds to
the period itself, corners straddling the period's end, a target that does not spin (infinite period).
"""

from __future__ import annotations

import numpy as np
import pytest

from planner.plan_parameters import ApproachParameters, PlanParameters, signed_gap, wrap_start_delay


def _params(tau_s: float, value: float) -> PlanParameters:
    approach = ApproachParameters(np.full(4, value), np.array([value, -value]), tau_s, np.full((3, 7), value))
    return PlanParameters(approach, np.full(5, value))


@pytest.mark.parametrize("tau_s,expected", [
    (0.0, 0.0),
    (30.0, 30.0),  # exactly at the window's end: kept
    (30.0 + 1e-12, 30.0),  # just beyond: clamped
    (95.0, 5.0),  # one period later
    (-5.0, 30.0),  # 85 s modulo the period: beyond the window, clamped
    (-1e-20, 0.0),  # the modulo rounds to the period itself: the delay is 0, not the window's end
])
def test_wrap_start_delay_at_the_window_edges(tau_s, expected):
    assert wrap_start_delay(tau_s, 90.0, (0.0, 30.0)) == expected


@pytest.mark.parametrize("tau_s,window,expected", [
    (20.0, (20.0, 80.0), 20.0),  # exactly at the earliest start: kept
    (20.0 - 1e-9, (20.0, 80.0), 20.0),  # just before it, one period later beyond the window: the earliest, nearer
    (5.0, (20.0, 30.0), 20.0),  # before the window, 95 s beyond it: the earliest (15 s away) is nearer than 30 (65 s)
    (-25.0, (20.0, 30.0), 30.0),  # 65 s: beyond the latest, clamped to it as before
    (-80.0, (20.0, 80.0), 20.0),  # 10 s, and 100 s beyond the window: the earliest is 10 s away, the latest 20 s
    (-40.0, (20.0, 60.0), 50.0),  # 50 s: inside the window as it is
])
def test_wrap_start_delay_into_a_window_that_starts_later(tau_s, window, expected):
    """A start-delay window that opens after the observation (``phases.min_start_delay_s``): the equivalent delay
    inside it, else its nearer end."""
    assert wrap_start_delay(tau_s, 90.0, window) == pytest.approx(expected, abs=1e-12)


def test_shifted_in_time_wraps_only_with_a_period_and_a_window():
    p = _params(20.0, 1.0)
    assert p.shifted_in_time(100.0).approach.start_delay_s == 120.0  # no period: a plain shift
    assert p.shifted_in_time(100.0, 90.0, (0.0, 30.0)).approach.start_delay_s == 30.0
    assert p.shifted_in_time(-15.0, float("inf"), (0.0, 30.0)).approach.start_delay_s == 5.0  # no spin: no wrap


def test_weighted_mean_averages_delays_across_the_end_of_a_period():
    """Corners 0.1 s either side of the period's end (89.9 s and 0.1 s) average to its end, not to 45 s."""
    mean = PlanParameters.weighted_mean([_params(89.9, 1.0), _params(0.1, 3.0)], np.array([0.5, 0.5]), 90.0)
    assert mean.approach.start_delay_s == pytest.approx(90.0, abs=1e-12)
    np.testing.assert_allclose(mean.approach.params, 2.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(mean.stabilization_params, 2.0, rtol=0, atol=1e-15)


def test_weighted_mean_of_one_member_is_that_member():
    only = _params(12.5, 0.7)
    mean = PlanParameters.weighted_mean([only, _params(40.0, 9.0)], np.array([1.0, 0.0]), 90.0)
    assert mean.approach.start_delay_s == 12.5
    np.testing.assert_array_equal(mean.approach.q_tracking, only.approach.q_tracking)


def test_signed_gap_is_half_open_at_half_a_period_and_plain_without_spin():
    assert signed_gap(45.0, 0.0, 90.0) == -45.0  # [−period/2, period/2)
    assert signed_gap(44.0, 0.0, 90.0) == 44.0
    assert signed_gap(100.0, 0.0, float("inf")) == 100.0
