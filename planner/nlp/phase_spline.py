"""The phases' B-spline parameters (paper Eq. 23-24): vertices from the free parameters, and back.

The optimisation variables of a phase are the boundary values not fixed by Eq. 23 / 24 plus the interior
vertices ``B_5..B_{N-4}`` (see :mod:`planner.nlp.bspline` for the spline itself). Parameter layout (both
phases, ``n_free = N - 5`` rows, one column per joint)::

    P = [ p_j0          ]   row 0            jerk at t = 0 [rad/s³]
        [ B_5           ]   rows 1..N-8      interior vertices [rad]
        [ ...           ]
        [ B_{N-4}       ]
        [ p_θtf         ]   row N-7          position at t = t_f [rad]
        [ p_jtf         ]   row N-6          jerk at t = t_f [rad/s³]

flattened row-major into one vector ``params = P.reshape(-1)`` of length ``n_joints * (N - 5)``, i.e.
``params[k * n_joints + j] = P[k, j]``. Every function accepts numpy arrays or casadi ``SX``/``MX``/``DM``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.nlp.bspline import Matrix, UniformCubicBSpline, as_casadi, is_casadi


def _numel(x: Matrix) -> int:
    return int(x.numel()) if is_casadi(x) else int(np.asarray(x).size)


def _row(x: Matrix, n: int, name: str) -> Matrix:
    """A per-joint vector as a ``(1, n)`` row (numpy or casadi)."""
    if _numel(x) != n:
        raise ValueError(f"{name}: expected {n} values, got {_numel(x)}")
    if is_casadi(x):
        return ca.reshape(x, 1, n)
    return np.asarray(x, dtype=float).reshape(1, n)


def _param_rows(spline: UniformCubicBSpline, params: Matrix, n: int) -> Matrix:
    """Flat ``params`` -> ``(N - 5, n)`` rows (row-major layout of the module docstring)."""
    m = spline.n_free_per_joint
    if _numel(params) != m * n:
        raise ValueError(f"params: expected {m} x {n} = {m * n} values, got {_numel(params)}")
    if is_casadi(params):
        # casadi reshapes column-major: reshape to (n, m) then transpose gives P[k, j] = params[k * n + j].
        return ca.reshape(params, n, m).T
    return np.asarray(params, dtype=float).reshape(m, n)


def _phase_vertices(spline: UniformCubicBSpline, start_rows: list[Matrix], params: Matrix, n: int) -> Matrix:
    P = _param_rows(spline, params, n)
    k_end = spline.n_free_per_joint - 2  # row of p_θtf
    use_casadi = is_casadi(P) or any(is_casadi(r) for r in start_rows)
    if use_casadi:
        rows = [as_casadi(r) for r in start_rows]
        P = as_casadi(P)
        start = ca.vertcat(*rows, P[0, :])
        zero = ca.DM.zeros(1, n)
        end = ca.vertcat(P[k_end, :], zero, zero, P[k_end + 1, :])
    else:
        start = np.vstack([*start_rows, P[0:1]])
        zero = np.zeros((1, n))
        end = np.vstack([P[k_end : k_end + 1], zero, zero, P[k_end + 1 : k_end + 2]])
    return spline.vertices_from_boundary(start, end, P[1:k_end, :])


def approach_vertices(spline: UniformCubicBSpline, theta_in: Matrix, params: Matrix) -> Matrix:
    """Vertices ``(N, n)`` of an approach phase (Eq. 23).

    Boundary conditions: start ``(θ_in, 0, 0, p_j0)``, end ``(p_θtf, 0, 0, p_jtf)``.

    Args:
        spline: the phase's spline.
        theta_in: initial joint positions ``(n,)`` [rad], numpy or casadi.
        params: flat vector of length ``n * (N - 5)`` in the module's row-major layout, numpy or casadi.
    Returns numpy if all inputs are numpy, else casadi.
    """
    n = _numel(theta_in)
    zero = np.zeros((1, n))
    return _phase_vertices(spline, [_row(theta_in, n, "theta_in"), zero, zero], params, n)


def stabilization_vertices(
    spline: UniformCubicBSpline,
    theta_in: Matrix,
    theta_dot_in: Matrix,
    acc_in: Matrix | None,
    params: Matrix,
) -> Matrix:
    """Vertices ``(N, n)`` of a stabilization phase (Eq. 24, generalised to a given initial acceleration).

    Boundary conditions: start ``(θ_in, θ̇_in, a_in, p_j0)``, end ``(p_θtf, 0, 0, p_jtf)``.  The paper uses
    ``a_in = 0``; passing the previous phase's final acceleration keeps joint acceleration continuous.

    Args:
        spline: the phase's spline.
        theta_in: initial joint positions ``(n,)`` [rad].
        theta_dot_in: initial joint velocities ``(n,)`` [rad/s].
        acc_in: initial joint accelerations ``(n,)`` [rad/s²]; ``None`` means zero (the paper's choice).
        params: flat vector of length ``n * (N - 5)`` (module layout).
    Any of these may be casadi; then the result is casadi.
    """
    n = _numel(theta_in)
    acc_row = np.zeros((1, n)) if acc_in is None else _row(acc_in, n, "acc_in")
    rows = [_row(theta_in, n, "theta_in"), _row(theta_dot_in, n, "theta_dot_in"), acc_row]
    return _phase_vertices(spline, rows, params, n)


def _params_from_vertices(spline: UniformCubicBSpline, vertices: ArrayLike) -> NDArray[np.float64]:
    start, end, interior = spline.boundary_from_vertices(vertices)
    return np.vstack([start[3:4], interior, end[0:1], end[3:4]]).reshape(-1)


def approach_params_from_vertices(spline: UniformCubicBSpline, vertices: ArrayLike) -> NDArray[np.float64]:
    """Flat params (module layout) of Eq. 23 from vertices ``(N, n)``; inverse of :func:`approach_vertices`.

    The boundary values Eq. 23 fixes (start position/velocity/acceleration, end velocity/acceleration)
    are not part of the params and are dropped, so vertices of any phase give a usable warm start.
    """
    return _params_from_vertices(spline, vertices)


def stabilization_params_from_vertices(
    spline: UniformCubicBSpline, vertices: ArrayLike
) -> NDArray[np.float64]:
    """Flat params (module layout) of Eq. 24 from vertices; inverse of :func:`stabilization_vertices`.

    Same layout as the approach phase; the fixed boundary values are dropped.
    """
    return _params_from_vertices(spline, vertices)


def fit_approach_params(
    spline: UniformCubicBSpline, theta_in: ArrayLike, times_s: ArrayLike, q_samples: ArrayLike
) -> NDArray[np.float64]:
    """Least-squares Eq. 23 params whose positions best match sampled joint positions (initial guesses).

    Args:
        spline: the phase's spline.
        theta_in: initial joint positions ``(n,)`` [rad]; imposed exactly, not fitted.
        times_s: sample times ``(n_times,)`` in ``[0, t_f]`` [s].
        q_samples: joint positions ``(n_times, n)`` [rad].
    Returns the flat params (module layout).  With fewer than ``N - 5`` informative samples the problem is
    under-determined and the minimum-norm solution is returned.
    """
    theta = np.asarray(theta_in, dtype=float).ravel()
    n = theta.size
    q = np.asarray(q_samples, dtype=float).reshape(-1, n)
    W = spline.weights(times_s)
    if W.shape[0] != q.shape[0]:
        raise ValueError(f"q_samples: expected {W.shape[0]} rows (one per time), got {q.shape[0]}")
    m = spline.n_free_per_joint
    # Eq. 23 is affine in the params and acts on each joint with the same (N, N-5) matrix G, so one
    # least-squares solve with n right-hand sides fits all joints.
    offset = approach_vertices(spline, theta, np.zeros(m * n))
    G = np.stack([approach_vertices(spline, np.zeros(1), np.eye(m)[k]).ravel() for k in range(m)], axis=1)
    P, *_ = np.linalg.lstsq(W @ G, q - W @ offset, rcond=None)
    return P.reshape(-1)
