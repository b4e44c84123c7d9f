"""Where a table's plan starts at the observed state: whole spin periods into the window, after the answer can come
(``placed_start_s``), and a flat-spin table's period against a tumble's (none)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lut.query.table_start import placed_start_s, table_period_s
from planner.model.target_state import TargetState

WINDOW = (0.0, 90.0)
INERTIA = np.diag([800.0, 1100.0, 1500.0])
DEG = math.pi / 180.0


def test_a_start_in_the_window_and_after_the_answer_is_kept():
    assert placed_start_s(30.0, 84.0, WINDOW, earliest_s=12.0) == 30.0
    assert placed_start_s(12.0, 84.0, WINDOW, earliest_s=12.0) == 12.0  # exactly when the answer can come: on time
    assert placed_start_s(30.0, math.inf, WINDOW, earliest_s=12.0) == 30.0


def test_a_start_beyond_the_window_comes_back_by_whole_periods_as_before():
    assert placed_start_s(30.0 + 2 * 84.0, 84.0, WINDOW) == pytest.approx(30.0, abs=1e-12)
    assert placed_start_s(95.0, 100.0, WINDOW) == 90.0  # no whole period fits: clamped, as the wrap did


def test_a_start_before_the_answer_moves_a_period_later_when_the_window_holds_it():
    assert placed_start_s(3.0, 84.0, WINDOW, earliest_s=12.0) == pytest.approx(87.0, abs=1e-12)
    assert placed_start_s(3.0, 84.0, WINDOW, earliest_s=3.0 + 1e-9) == pytest.approx(87.0, abs=1e-12)
    assert placed_start_s(3.0, 40.0, WINDOW, earliest_s=50.0) == pytest.approx(83.0, abs=1e-12)  # two periods


def test_a_start_before_the_answer_with_no_later_period_in_the_window_is_late():
    assert placed_start_s(7.0, 84.0, WINDOW, earliest_s=12.0) is None  # 91 s: past the window's 90
    assert placed_start_s(6.0, 84.0, WINDOW, earliest_s=12.0) == pytest.approx(90.0, abs=1e-12)  # its very end
    assert placed_start_s(3.0, math.inf, WINDOW, earliest_s=12.0) is None  # a tumble: no later start meets it


def test_a_flat_spin_table_answers_with_the_observed_rates_period_and_a_tumble_table_only_where_the_motion_repeats():
    noisy_flat = TargetState([1.0, 0.0, 0.0, 0.0], [0.03 * DEG, 0.0, 4.0 * DEG])  # an estimator's, off the family
    assert table_period_s(noisy_flat, INERTIA, flat_spin_table=True) == pytest.approx(
        2 * math.pi / float(np.linalg.norm(noisy_flat.omega_body_rad_s)))
    assert table_period_s(noisy_flat, INERTIA, flat_spin_table=False) == math.inf
    tumble = TargetState([1.0, 0.0, 0.0, 0.0], [4.0 * DEG, 4.0 * DEG, 4.0 * DEG])
    assert table_period_s(tumble, INERTIA, flat_spin_table=False) == math.inf
    about_x = TargetState([1.0, 0.0, 0.0, 0.0], [4.0 * DEG, 0.0, 0.0])  # a tumble grid's point on a principal axis
    assert table_period_s(about_x, INERTIA, flat_spin_table=False) == pytest.approx(90.0)
