"""Tests of planner.nlp.bspline and planner.nlp.phase_spline: B-spline trajectories, Eq. 23 / 24 layouts."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.interpolate import BSpline

from planner.nlp.bspline import UniformCubicBSpline, resample
from planner.nlp.phase_spline import (
    approach_params_from_vertices,
    approach_vertices,
    fit_approach_params,
    stabilization_params_from_vertices,
    stabilization_vertices,
)

N_VALUES = [8, 10, 15, 42]
N_JOINTS = 7
TOL = 1e-12


def _spline(n_vertices: int) -> UniformCubicBSpline:
    # Durations of a few seconds to tens of seconds, as in the planner's phases.
    return UniformCubicBSpline(n_vertices, 4.0 + 0.3 * n_vertices)


def _params(spline: UniformCubicBSpline, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=spline.n_free_per_joint * N_JOINTS)


def _state(spline: UniformCubicBSpline, vertices, t: float) -> np.ndarray:
    """(4, n) rows position, velocity, acceleration, jerk at time t."""
    return np.vstack([spline.evaluate(vertices, [t], d) for d in range(4)])


def _close(actual, expected, tol: float = TOL) -> None:
    """Max abs error ≤ tol relative to the magnitude of the values (≥ 1)."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    scale = max(1.0, float(np.max(np.abs(expected), initial=0.0)))
    err = float(np.max(np.abs(actual - expected), initial=0.0))
    assert err <= tol * scale, f"max error {err:.3e} > {tol:.1e} * {scale:.3g}"


@pytest.mark.parametrize("n_vertices", N_VALUES)
def test_approach_boundary_conditions_eq23(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(n_vertices)
    theta_in = rng.uniform(-2.0, 2.0, N_JOINTS)
    params = _params(spline, 1)
    P = params.reshape(spline.n_free_per_joint, N_JOINTS)
    V = approach_vertices(spline, theta_in, params)
    assert V.shape == (n_vertices, N_JOINTS)
    zero = np.zeros(N_JOINTS)
    _close(_state(spline, V, 0.0), np.vstack([theta_in, zero, zero, P[0]]))
    _close(_state(spline, V, spline.duration_s), np.vstack([P[-2], zero, zero, P[-1]]))
    # Interior rows of the layout are the vertices B_5..B_{N-4} themselves.
    np.testing.assert_array_equal(V[4 : n_vertices - 4], P[1:-2])


@pytest.mark.parametrize("n_vertices", N_VALUES)
def test_stabilization_boundary_conditions_eq24(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(100 + n_vertices)
    theta_in, theta_dot_in, acc_in = rng.uniform(-1.0, 1.0, (3, N_JOINTS))
    params = _params(spline, 2)
    P = params.reshape(spline.n_free_per_joint, N_JOINTS)
    V = stabilization_vertices(spline, theta_in, theta_dot_in, acc_in, params)
    zero = np.zeros(N_JOINTS)
    _close(_state(spline, V, 0.0), np.vstack([theta_in, theta_dot_in, acc_in, P[0]]))
    _close(_state(spline, V, spline.duration_s), np.vstack([P[-2], zero, zero, P[-1]]))
    # acc_in=None is the paper's a_in = 0.
    V0 = stabilization_vertices(spline, theta_in, theta_dot_in, None, params)
    _close(spline.evaluate(V0, [0.0], 2), zero[None])


@pytest.mark.parametrize("n_vertices", N_VALUES)
def test_continuity_at_knots_and_piecewise_constant_jerk(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(200 + n_vertices)
    V = rng.normal(size=(n_vertices, N_JOINTS))
    h = spline.segment_duration_s
    eps = 1e-9 * h
    for i in range(spline.n_segments - 1):
        knot = (i + 1) * h
        for d in range(3):
            left = spline.segment_weights(i, [1.0], d) @ V
            right = spline.segment_weights(i + 1, [0.0], d) @ V
            _close(left, right)
            # Just left/right of the knot by time: differ only by ~eps * (next derivative).
            bound = 10.0 * eps * float(np.max(np.abs(V))) / h ** (d + 1)
            jump = spline.evaluate(V, [knot + eps], d) - spline.evaluate(V, [knot - eps], d)
            assert np.max(np.abs(jump)) <= bound + TOL
        # The jerk generally jumps at a knot (otherwise this test of "constant" below is vacuous).
        jerk_left = spline.segment_weights(i, [1.0], 3) @ V
        jerk_right = spline.segment_weights(i + 1, [0.0], 3) @ V
        assert np.max(np.abs(jerk_left - jerk_right)) > 1e-3
    for i in range(spline.n_segments):
        jerk = spline.evaluate(V, (i + np.linspace(0.0, 0.999, 7)) * h, 3)
        _close(jerk, np.repeat(jerk[:1], 7, axis=0))


@pytest.mark.parametrize("n_vertices", N_VALUES)
def test_derivatives_match_central_finite_differences(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(300 + n_vertices)
    V = rng.normal(size=(n_vertices, N_JOINTS))
    h = spline.segment_duration_s
    # Points strictly inside segments: the jerk is discontinuous at knots.
    times = (np.arange(spline.n_segments)[:, None] + rng.uniform(0.1, 0.9, (1, 3))).ravel() * h
    step = 1e-4 * h
    for d in range(1, 4):
        fd = (spline.evaluate(V, times + step, d - 1) - spline.evaluate(V, times - step, d - 1)) / (2 * step)
        analytic = spline.evaluate(V, times, d)
        _close(fd, analytic, tol=1e-6)


@pytest.mark.parametrize("n_vertices", [8, 15])
def test_casadi_sx_and_mx_match_numpy(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(400 + n_vertices)
    theta_in, theta_dot_in, acc_in = rng.uniform(-1.0, 1.0, (3, N_JOINTS))
    params = _params(spline, 4)
    times = np.linspace(0.0, spline.duration_s, 23)
    n_p = params.size
    for sym in (ca.SX, ca.MX):
        p = sym.sym("p", n_p)
        th, thd, acc = sym.sym("th", N_JOINTS), sym.sym("thd", N_JOINTS), sym.sym("acc", N_JOINTS)
        for d in range(4):
            f_app = ca.Function("f", [p], [spline.evaluate(approach_vertices(spline, theta_in, p), times, d)])
            expected = spline.evaluate(approach_vertices(spline, theta_in, params), times, d)
            _close(np.array(f_app(params)), expected)
            # Stabilization with symbolic initial state as well as symbolic params.
            Vs = stabilization_vertices(spline, th, thd, acc, p)
            f_stab = ca.Function("g", [th, thd, acc, p], [spline.evaluate(Vs, times, d)])
            expected = spline.evaluate(
                stabilization_vertices(spline, theta_in, theta_dot_in, acc_in, params), times, d
            )
            _close(np.array(f_stab(theta_in, theta_dot_in, acc_in, params)), expected)


@pytest.mark.parametrize("n_vertices", [8, 12])
def test_casadi_jacobian_is_constant_weight_product(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    theta_in = np.random.default_rng(5).uniform(-1.0, 1.0, N_JOINTS)
    m = spline.n_free_per_joint
    times = np.linspace(0.0, spline.duration_s, 17)
    W = spline.weights(times)
    # Per-joint linear map params -> vertices, probed through the numpy path (Eq. 23 is affine).
    base = approach_vertices(spline, np.zeros(1), np.zeros(m))
    G = np.stack([approach_vertices(spline, np.zeros(1), e)[:, 0] - base[:, 0] for e in np.eye(m)], axis=1)
    p = ca.SX.sym("p", m * N_JOINTS)
    q = spline.evaluate(approach_vertices(spline, theta_in, p), times)
    J = np.array(ca.Function("J", [p], [ca.jacobian(ca.vec(q), p)])(np.zeros(m * N_JOINTS)))
    # ca.vec is column-major: row j * n_times + t; params layout: column k * n_joints + j.
    expected = np.zeros_like(J)
    WG = W @ G
    for j in range(N_JOINTS):
        expected[j * times.size : (j + 1) * times.size, j::N_JOINTS] = WG
    _close(J, expected)


@pytest.mark.parametrize("n_vertices", N_VALUES)
def test_boundary_and_params_roundtrips(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(600 + n_vertices)
    start, end = rng.normal(size=(2, 4, N_JOINTS))
    interior = rng.normal(size=(spline.n_interior, N_JOINTS))
    V = spline.vertices_from_boundary(start, end, interior)
    s2, e2, i2 = spline.boundary_from_vertices(V)
    _close(s2, start)
    _close(e2, end)
    np.testing.assert_array_equal(i2, interior)
    # And the other way round, from arbitrary vertices.
    _close(spline.vertices_from_boundary(*spline.boundary_from_vertices(V * 3.0)), V * 3.0)

    theta_in, theta_dot_in, acc_in = rng.uniform(-1.0, 1.0, (3, N_JOINTS))
    params = _params(spline, 6)
    _close(approach_params_from_vertices(spline, approach_vertices(spline, theta_in, params)), params)
    Vs = stabilization_vertices(spline, theta_in, theta_dot_in, acc_in, params)
    _close(stabilization_params_from_vertices(spline, Vs), params)
    _close(stabilization_vertices(spline, theta_in, theta_dot_in, acc_in, params), Vs)


def test_vertices_from_boundary_casadi_matches_numpy() -> None:
    spline = _spline(10)
    rng = np.random.default_rng(7)
    start, end = rng.normal(size=(2, 4, 3))
    interior = rng.normal(size=(spline.n_interior, 3))
    s = ca.SX.sym("s", 4, 3)
    V = spline.vertices_from_boundary(s, end, interior)
    assert isinstance(V, ca.SX) and V.shape == (10, 3)
    _close(np.array(ca.Function("f", [s], [V])(start)), spline.vertices_from_boundary(start, end, interior))


@pytest.mark.parametrize("n_vertices", N_VALUES)
def test_matches_scipy_bspline_oracle(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(700 + n_vertices)
    V = rng.normal(size=(n_vertices, N_JOINTS))
    h = spline.segment_duration_s
    # Uniform knots t_seg * (-3 .. N): the base interval [t_3, t_N] is [0, t_f].
    oracle = BSpline(h * np.arange(-3, n_vertices + 1, dtype=float), V, 3, extrapolate=False)
    knots = h * np.arange(spline.n_segments + 1)
    times = np.concatenate([rng.uniform(0.0, spline.duration_s, 50), knots])
    for d in range(4):
        _close(spline.evaluate(V, times, d), oracle(times, nu=d))


@pytest.mark.parametrize("n_vertices", [8, 15, 42])
def test_fit_approach_params_recovers_generating_params(n_vertices: int) -> None:
    spline = _spline(n_vertices)
    rng = np.random.default_rng(800 + n_vertices)
    theta_in = rng.uniform(-1.0, 1.0, N_JOINTS)
    params = _params(spline, 8)
    times = np.linspace(0.0, spline.duration_s, 5 * spline.n_segments + 1)
    q = spline.evaluate(approach_vertices(spline, theta_in, params), times)
    fitted = fit_approach_params(spline, theta_in, times, q)
    _close(fitted, params, tol=1e-8)


def test_resample_keeps_boundary_and_approximates_curve() -> None:
    coarse, fine = UniformCubicBSpline(10, 8.0), UniformCubicBSpline(40, 8.0)
    rng = np.random.default_rng(9)
    V = approach_vertices(coarse, rng.uniform(-1.0, 1.0, 3), rng.normal(size=coarse.n_free_per_joint * 3))
    # Same spline: exact identity.
    _close(resample(coarse, V, coarse), V, tol=1e-10)
    Vf = resample(coarse, V, fine)
    assert Vf.shape == (40, 3)
    _close(_state(fine, Vf, 0.0), _state(coarse, V, 0.0))
    _close(_state(fine, Vf, 8.0), _state(coarse, V, 8.0))
    times = np.linspace(0.0, 8.0, 301)
    err = np.max(np.abs(fine.evaluate(Vf, times) - coarse.evaluate(V, times)))
    assert err < 1e-2 * np.max(np.abs(coarse.evaluate(V, times)))
    # Time scaling: same curve in normalised time, derivatives scaled by (t_from / t_to)^d.
    slow = UniformCubicBSpline(10, 16.0)
    Vs = resample(coarse, V, slow)
    _close(slow.evaluate(Vs, 2.0 * times), coarse.evaluate(V, times), tol=1e-10)
    _close(slow.evaluate(Vs, [0.0], 1), 0.5 * coarse.evaluate(V, [0.0], 1))


@pytest.mark.parametrize("n_vertices", [0, 5, 7])
def test_too_few_vertices_raises(n_vertices: int) -> None:
    with pytest.raises(ValueError, match="n_vertices"):
        UniformCubicBSpline(n_vertices, 10.0)


def test_invalid_inputs_raise() -> None:
    spline = _spline(9)
    with pytest.raises(ValueError, match="duration_s"):
        UniformCubicBSpline(9, 0.0)
    with pytest.raises(ValueError, match="times_s"):
        spline.weights([spline.duration_s * 1.01])
    with pytest.raises(ValueError, match="derivative"):
        spline.weights([0.0], derivative=4)
    with pytest.raises(ValueError, match="params"):
        approach_vertices(spline, np.zeros(N_JOINTS), np.zeros(3))
    # t == t_f is on the last segment at u = 1, not out of range.
    np.testing.assert_array_equal(
        spline.weights([spline.duration_s]), spline.segment_weights(spline.n_segments - 1, [1.0])
    )


def test_knot_times_rounded_either_way_use_right_segment() -> None:
    spline = _spline(42)
    for k in range(1, spline.n_segments):
        exact = spline.segment_weights(k, [0.0], 3)
        t = k * spline.duration_s / spline.n_segments
        for tk in (np.nextafter(t, 0.0), t, np.nextafter(t, np.inf)):
            np.testing.assert_array_equal(spline.weights([tk], 3), exact)
