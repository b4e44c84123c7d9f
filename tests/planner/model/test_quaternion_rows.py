"""Row-wise quaternion helpers against the single-frame functions of ``planner.model.rotation``, on every branch
of Shepperd's method and at its degenerate rotations (identity, half turns about each axis, traces near zero)."""

from __future__ import annotations

import numpy as np
import pytest

from planner.model.quaternion_rows import matrices_to_quats, quats_to_matrices
from planner.model.rotation import axis_angle_to_matrix, matrix_to_quat, quat_to_matrix

HALF_TURNS = [axis_angle_to_matrix(a, np.pi) for a in np.eye(3)]  # trace −1: branches 1, 2, 3, never the trace one


def _degenerate_rotations() -> np.ndarray:
    """Identity, half turns about x, y, z and a diagonal, and rotations whose trace is ±1e-12 around 0."""
    diagonal = axis_angle_to_matrix(np.ones(3) / np.sqrt(3), np.pi)
    near_zero_trace = [axis_angle_to_matrix(a, np.arccos(-0.5) + d) for a in np.eye(3) for d in (-1e-12, 0.0, 1e-12)]
    return np.array([np.eye(3), *HALF_TURNS, diagonal, *near_zero_trace])


def _random_rotations(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    return quats_to_matrices(q / np.linalg.norm(q, axis=1, keepdims=True))


@pytest.mark.parametrize("rotations", [_degenerate_rotations(), _random_rotations(500, 3)],
                         ids=["degenerate", "random"])
def test_matrices_to_quats_equals_matrix_to_quat_row_by_row(rotations):
    """Same quaternion (w ≥ 0, unit) as the single-matrix function, to rounding, whichever branch each row takes."""
    rows = matrices_to_quats(rotations)
    single = np.array([matrix_to_quat(R) for R in rotations])
    np.testing.assert_allclose(rows, single, rtol=0, atol=4e-16)
    assert np.all(rows[:, 0] >= 0)
    np.testing.assert_allclose(np.linalg.norm(rows, axis=1), 1.0, rtol=0, atol=4e-16)


def test_matrices_to_quats_round_trips_every_branch():
    """Quaternion → matrix → quaternion returns the quaternion (up to sign) on each branch: trace > 0, and the
    largest diagonal entry x, y or z."""
    branches = np.array([[0.9, 0.1, 0.3, 0.3], [0.1, 0.9, 0.3, 0.3], [0.1, 0.3, 0.9, 0.3], [0.1, 0.3, 0.3, 0.9]])
    q = branches / np.linalg.norm(branches, axis=1, keepdims=True)
    R = np.array([quat_to_matrix(row) for row in q])
    assert np.trace(R[0]) > 0 and all(np.trace(Rk) <= 0 for Rk in R[1:])
    np.testing.assert_allclose(matrices_to_quats(R), q, rtol=0, atol=1e-15)
