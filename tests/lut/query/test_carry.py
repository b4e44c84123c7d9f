"""How far a table's plan carries (lut.query.carry): the displacement of an observed state from a grid point, a
tumble's in attitude (the rotation between them, q and −q alike) and body rate, a flat spin's in spin axis (round the
circle) and rate, each judged against its limits at their edges."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lut.query.carry import (
    CARRY_ATTITUDE_DEG,
    CARRY_RATE_DEG_S,
    FLAT_SPIN_AXIS_DEG,
    FLAT_SPIN_RATE_DEG_S,
    displacement,
    nearest_displacement,
    off_flat_spin_family,
    outside_flat_spin_grid,
)
from planner.model.rotation import quat_multiply
from planner.model.target import TargetState


def _quat(axis, angle_rad: float) -> np.ndarray:
    """[w, x, y, z] of a turn by ``angle_rad`` about ``axis``."""
    unit = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle_rad / 2)], math.sin(angle_rad / 2) * unit])


BASE_Q = _quat([0.3, -0.5, 0.8], 1.1)
BASE_W = np.radians([2.0, -3.0, 1.5])


def _turned(angle_deg: float, axis=(1.0, 2.0, -2.0), omega_change_deg_s=(0.0, 0.0, 0.0)) -> TargetState:
    """The base state turned by ``angle_deg`` about a body ``axis``, its body rate changed by ``omega_change``."""
    turn = _quat(axis, math.radians(angle_deg))
    return TargetState(quat_multiply(BASE_Q, turn), BASE_W + np.radians(omega_change_deg_s))


BASE = TargetState(BASE_Q, BASE_W)


@pytest.mark.parametrize("angle_deg", [0.0, 1e-6, 5.0, 19.0, 45.0, 120.0, 179.0, 180.0])
def test_the_attitude_displacement_is_the_rotation_between_them(angle_deg):
    """Degenerate ends included: the same attitude, a micro-degree (where 2·acos|q·p| would round to 0 or to ~1e-6°
    of noise), and the half turn, where the rotation's axis is ill-defined but its angle is not."""
    assert displacement(0, _turned(angle_deg), BASE).attitude_deg == pytest.approx(angle_deg, rel=1e-6, abs=1e-9)


def test_q_and_minus_q_are_the_same_attitude():
    flipped = TargetState(-BASE_Q, BASE_W)
    move = displacement(0, flipped, BASE)
    assert move.attitude_deg == pytest.approx(0.0, abs=1e-9) and move.rate_deg_s == 0.0 and not move.beyond_carry


def test_the_rate_displacement_is_the_norm_of_the_body_rate_difference():
    move = displacement(3, _turned(0.0, omega_change_deg_s=(0.3, -0.4, 0.0)), BASE)
    assert move.rate_deg_s == pytest.approx(0.5, abs=1e-12) and move.point == 3


@pytest.mark.parametrize(("angle_deg", "rate_deg_s", "beyond"), [
    (CARRY_ATTITUDE_DEG - 1e-6, 0.0, False), (CARRY_ATTITUDE_DEG + 1e-6, 0.0, True),
    (0.0, CARRY_RATE_DEG_S - 1e-9, False), (0.0, CARRY_RATE_DEG_S + 1e-9, True),
    (CARRY_ATTITUDE_DEG * 0.9, CARRY_RATE_DEG_S * 0.9, False)])
def test_beyond_carry_at_its_edges(angle_deg, rate_deg_s, beyond):
    move = displacement(0, _turned(angle_deg, omega_change_deg_s=(0.0, rate_deg_s, 0.0)), BASE)
    assert move.beyond_carry is beyond


def test_the_nearest_corner_is_the_nearest_in_units_of_the_carry():
    """Corner 1 is 15° away (0.75 of the attitude's carry), corner 2 0.2° and 0.8 °/s (0.8 of the rate's): 1 is
    nearer, though its attitude is 75 times farther."""
    states = {1: _turned(15.0), 2: _turned(0.2, omega_change_deg_s=(0.8, 0.0, 0.0))}
    nearest = nearest_displacement([2, 1], BASE, states.__getitem__)
    assert nearest is not None and nearest.point == 1 and not nearest.beyond_carry
    assert nearest_displacement([], BASE, states.__getitem__) is None


def test_the_note_names_the_point_and_both_distances():
    note = displacement(7, _turned(30.0, omega_change_deg_s=(1.2, 0.0, 0.0)), BASE).note()
    assert "point 7" in note and "30.0°" in note and "1.20 °/s" in note


@pytest.mark.parametrize(("here", "there", "axis_deg", "rate_deg_s"), [
    ((3.0, 350.0), (3.0, 10.0), 20.0, 0.0),  # across 0°/360°
    ((3.0, 10.0), (3.0, 350.0), 20.0, 0.0),
    ((2.0, 180.0), (2.5, -180.0), 0.0, 0.5),  # the same axis, a whole turn apart
    ((2.0, 90.0), (2.0, 270.0), 180.0, 0.0),  # the opposite axis: the farthest a spin axis can be
    ((1.2, -40.0), (3.7, 95.0), 135.0, 2.5)])
def test_outside_a_flat_spin_grid_is_its_spin_axis_round_the_circle_and_its_rate(here, there, axis_deg, rate_deg_s):
    move = outside_flat_spin_grid(here, there)
    assert move.point is None
    assert move.attitude_deg == pytest.approx(axis_deg, abs=1e-9) and move.rate_deg_s == pytest.approx(rate_deg_s)


@pytest.mark.parametrize(("axis_deg", "rate_deg_s", "beyond"), [
    (FLAT_SPIN_AXIS_DEG, 0.0, False), (FLAT_SPIN_AXIS_DEG + 1e-6, 0.0, True),
    (0.0, FLAT_SPIN_RATE_DEG_S, False), (0.0, FLAT_SPIN_RATE_DEG_S + 1e-9, True),
    (FLAT_SPIN_AXIS_DEG, FLAT_SPIN_RATE_DEG_S, False), (0.0, 0.0, False)])
def test_a_flat_spin_plan_carries_to_half_the_coarse_cell_outside_its_grid_and_no_farther(axis_deg, rate_deg_s,
                                                                                         beyond):
    """Exactly half the coarse envelope grid's cell (30°, 0.5 °/s: where its corners answered states) outside the grid
    is still tried, a hair beyond is not, and inside (0, 0) always."""
    assert outside_flat_spin_grid((3.0 + rate_deg_s, 90.0 + axis_deg), (3.0, 90.0)).beyond_carry is beyond


def test_a_flat_spins_note_says_how_far_outside_the_grid_and_names_its_carry():
    note = outside_flat_spin_grid((4.6, 125.0), (4.0, 90.0)).note()
    assert note.startswith("this state is 35.0° of spin axis and 0.60 °/s outside the table's grid")
    assert note.endswith("beyond what a flat-spin plan carries (30°, 0.5 °/s): its plans not tried")


def test_off_its_flat_spin_a_state_carries_as_a_tumble_plan_and_the_note_says_from_what():
    """A tumble given to a flat-spin table: its distance from its nearest flat spin is judged by the tumble's limits
    (a flat spin's plan at a tumbling state is a plan displaced by that attitude and rate), at their edges."""
    within = off_flat_spin_family(_turned(CARRY_ATTITUDE_DEG - 1e-6), BASE)
    beyond = off_flat_spin_family(_turned(5.0, omega_change_deg_s=(0.0, CARRY_RATE_DEG_S + 1e-9, 0.0)), BASE)
    assert within.point is None and within.off_family and not within.beyond_carry and beyond.beyond_carry
    assert beyond.note().startswith("this state is 5.0° and 1.00 °/s from its nearest flat spin, beyond what a tumble")
