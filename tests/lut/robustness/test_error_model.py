"""The error model: checked inputs, the body-frame composition against scipy's rotation vectors, the draws'
covariance, and the zero error that returns the observed state bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lut.robustness.error_model import ErrorModel, ErrorModelError, perturbed_states, standard_draws
from planner.model.target_state import TargetState

OBSERVED = TargetState(np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2]),
                       np.radians([0.4, -0.2, 3.75]))


def as_scipy(q_wxyz) -> Rotation:
    return Rotation.from_quat(np.roll(np.asarray(q_wxyz, dtype=float), -1, axis=-1))  # scipy is [x, y, z, w]


@pytest.mark.parametrize("att, rate", [(-0.1, 0.0), (0.0, -1e-3), (float("nan"), 0.0), (0.0, float("inf"))])
def test_sigmas_must_be_finite_and_non_negative(att, rate):
    with pytest.raises(ErrorModelError):
        ErrorModel.from_sigmas(att, rate)


@pytest.mark.parametrize("matrix, words", [
    (np.eye(5), "6×6"),
    (np.eye(6) + np.triu(np.ones((6, 6)), 1) * 0.1, "symmetric"),
    (np.diag([1, 1, 1, 1, 1, -1.0]), "positive semi-definite"),
    (np.full((6, 6), np.nan), "finite"),
])
def test_a_covariance_must_be_6x6_symmetric_psd(matrix, words):
    with pytest.raises(ErrorModelError, match=words):
        ErrorModel.from_matrix(matrix, "cov.txt")


def test_covariance_file_reads_commas_and_comments(tmp_path):
    c = np.diag([1e-4, 2e-4, 3e-4, 1e-6, 2e-6, 3e-6])
    c[0, 3] = c[3, 0] = 5e-6
    path = tmp_path / "cov.txt"
    path.write_text("# δθ [rad], δω [rad/s]\n" + "\n".join(", ".join(f"{v:.17g}" for v in row) for row in c) + "\n")
    assert np.array_equal(ErrorModel.from_file(path).covariance, c)
    (tmp_path / "bad.txt").write_text("1 2 3\n4 5 6\n")
    with pytest.raises(ErrorModelError, match="6×6"):
        ErrorModel.from_file(tmp_path / "bad.txt")


def test_a_singular_covariance_draws_only_along_its_range():
    model = ErrorModel.from_sigmas(0.0, 1e-3)  # attitude exact: every draw keeps the observed attitude
    states = perturbed_states(OBSERVED, model, standard_draws(50, 3), 1.0)
    for s in states:
        assert np.allclose(s.attitude_wxyz, OBSERVED.attitude_wxyz, atol=1e-15)
    assert np.std([s.omega_body_rad_s for s in states]) > 5e-4


def test_true_attitude_is_the_observed_one_rotated_in_the_body_frame():
    model = ErrorModel.from_sigmas(np.radians(2.0), np.radians(0.1))
    z = standard_draws(20, 11)
    states = perturbed_states(OBSERVED, model, z, 1.5)
    deltas = 1.5 * z @ model.square_root().T
    for s, d in zip(states, deltas, strict=True):
        expected = as_scipy(OBSERVED.attitude_wxyz) * Rotation.from_rotvec(d[:3])  # R_obs · Exp(δθ)
        assert (as_scipy(s.attitude_wxyz).inv() * expected).magnitude() < 1e-12
        assert np.allclose(s.omega_body_rad_s, OBSERVED.omega_body_rad_s + d[3:], atol=1e-15)


def test_draws_have_the_model_covariance():
    c = np.diag([4e-4, 1e-4, 9e-4, 1e-6, 4e-6, 1e-6])
    c[1, 4] = c[4, 1] = 1.5e-5  # a correlation between an attitude and a rate axis
    model = ErrorModel.from_matrix(c, "c")
    states = perturbed_states(OBSERVED, model, standard_draws(4000, 5), 1.0)
    rotvec = (as_scipy(OBSERVED.attitude_wxyz).inv() * as_scipy([s.attitude_wxyz for s in states])).as_rotvec()
    x = np.hstack([rotvec, [s.omega_body_rad_s - OBSERVED.omega_body_rad_s for s in states]])
    sd = np.sqrt(np.diag(c))
    # normalised sample covariance within 5 standard errors (1/√4000 ≈ 0.016) of the model's
    assert np.allclose(np.cov(x.T) / np.outer(sd, sd), c / np.outer(sd, sd), atol=0.08)


def test_zero_error_is_the_observed_state_and_the_seed_fixes_the_draws():
    model = ErrorModel.from_sigmas(np.radians(0.5), np.radians(0.05))
    assert all(s is OBSERVED for s in perturbed_states(OBSERVED, model, standard_draws(5, 1), 0.0))
    assert np.array_equal(standard_draws(7, 42), standard_draws(7, 42))
    assert not np.array_equal(standard_draws(7, 42), standard_draws(7, 43))


@pytest.mark.parametrize("c", [np.diag([1e-4, 0, 3e-4, 1e-6, 0, 3e-6]), np.full((6, 6), 2e-5) + np.eye(6) * 1e-5,
                               np.outer(np.arange(1.0, 7.0), np.arange(1.0, 7.0)) * 1e-6])
def test_square_root_reproduces_diagonal_definite_and_singular_covariances(c):
    L = ErrorModel.from_matrix(c, "c").square_root()
    assert np.allclose(L @ L.T, c, atol=1e-15)
