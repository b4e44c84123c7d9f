"""Torque-free target prediction inside an NLP (CasADi), so the meeting time can be a decision variable.

The NLP needs the grasp pose at ``t = τ + t_f¹`` with the start delay τ free; the accurate propagation
of :mod:`planner.model.target` (adaptive DOP853) is not symbolic, so here Euler's equations and the quaternion
kinematics ``q̇ = ½ q ⊗ [0, ω_body]`` are integrated by a fixed number of RK4 steps of symbolic length
``t/n``. With body rates ≤ 4 °/s and ≤ 1 s steps the attitude error is ~1e-8 rad (RK4's local error
(ω h)⁵/120 per step); :mod:`planner.verify.verifier` re-checks every plan against the accurate propagation.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from numpy.typing import NDArray


def _attitude_rate(inertia_body: NDArray[np.float64], x: ca.SX | ca.MX) -> ca.SX | ca.MX:
    """``[q̇; ω̇]`` of the 7-state ``x = [q_world_body (4), ω_body (3)]`` [rad/s], torque-free."""
    q, w = x[:4], x[4:7]
    inertia = ca.DM(inertia_body)
    w_dot = ca.solve(inertia, -ca.cross(w, ca.mtimes(inertia, w)))
    q_dot = 0.5 * ca.vertcat(
        -q[1] * w[0] - q[2] * w[1] - q[3] * w[2],
        q[0] * w[0] + q[2] * w[2] - q[3] * w[1],
        q[0] * w[1] - q[1] * w[2] + q[3] * w[0],
        q[0] * w[2] + q[1] * w[1] - q[2] * w[0],
    )
    return ca.vertcat(q_dot, w_dot)


def prediction_function(inertia_body: NDArray[np.float64], n_steps: int) -> ca.Function:
    """CasADi Function ``(attitude_wxyz0, omega_body0, t) -> (attitude_wxyz(t), omega_body(t))``.

    ``t`` [s] may be symbolic; ``n_steps`` RK4 steps of length t/n_steps; the quaternion is renormalised.
    """
    x = ca.SX.sym("x", 7)
    rate = ca.Function("target_rate", [x], [_attitude_rate(np.asarray(inertia_body, dtype=float), x)])
    q0 = ca.SX.sym("attitude_wxyz0", 4)
    w0 = ca.SX.sym("omega_body0", 3)
    t = ca.SX.sym("t")
    h = t / n_steps
    xk = ca.vertcat(q0, w0)
    for _ in range(n_steps):
        k1 = rate(xk)
        k2 = rate(xk + 0.5 * h * k1)
        k3 = rate(xk + 0.5 * h * k2)
        k4 = rate(xk + h * k3)
        xk = xk + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        xk = ca.vertcat(xk[:4] / ca.norm_2(xk[:4]), xk[4:])
    return ca.Function("target_prediction", [q0, w0, t], [xk[:4], xk[4:]],
                       ["attitude_wxyz0", "omega_body0", "t"], ["attitude_wxyz", "omega_body"])
