"""The tracking IK's law (paper Eq. 7) at one state, in one compiled CasADi call (:mod:`planner.phases.tracking`).

The law of :mod:`planner.phases.tracking`'s docstring, evaluated four times per RK4 step: the kinematics, the pose
error, the pseudo-inverse, the null-space motion, the smooth rate cap and the zero-momentum base-pose rate in one
call, where the same numbers from numpy cost a dozen Python-level calls. ``J*⁺`` comes from the QR factors of
``J*ᵀ = Q R`` as ``Q R⁻ᵀ``: numpy's SVD pseudo-inverse to rounding where ``J*`` is well conditioned. The call also
returns ``min |R_ii| / max |R_ii|``; below :data:`WELL_CONDITIONED` (at and near a singular pose, where ``R⁻ᵀ`` is
huge or infinite and the SVD drops the lost direction) the caller falls back to numpy's pseudo-inverse.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.model.freefloating import FreeFloatingModel, pose_rate_sym, quat_to_rotation_sym
from planner.nlp.compiled import compiled
from planner.nlp.costs import manipulability_sym
from planner.phases.tracking_kinematics import Buffered

Array = NDArray[np.float64]

# below this ratio of R's smallest to largest diagonal the QR pseudo-inverse loses more than ~1e-10 of its digits
# (rounding grows with the ratio's inverse): the law is evaluated with numpy's SVD instead
WELL_CONDITIONED = 1e-6
_SMALL_ANGLE = 1e-6  # below this sin θ the rotation log uses θ/sin θ's series [1]
_NEAR_PI_RAD = 1e-3  # within this of π the rotation log takes its axis from R's symmetric part [rad]


def rotation_log_sym(R: ca.SX) -> ca.SX:
    """Rotation vector ``θ u`` [rad] of a 3×3 rotation, as :func:`planner.model.rotation.rotation_log` computes it:
    ``θ = atan2(‖v‖, (tr R − 1)/2)``, ``v = vee(R − Rᵀ)/2 = sin θ u``; near π the axis from ``(R + Rᵀ)/2 − cos θ I``."""
    v = 0.5 * ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])
    s = ca.norm_2(v)
    c = 0.5 * (ca.trace(R) - 1.0)
    theta = ca.atan2(s, c)
    factor = ca.if_else(s < _SMALL_ANGLE, 1.0 + theta**2 / 6.0, theta / ca.fmax(s, _SMALL_ANGLE))
    B = 0.5 * (R + R.T) - c * ca.SX.eye(3)
    d = ca.diag(B)
    column = ca.if_else(ca.logic_and(d[0] >= d[1], d[0] >= d[2]), B[:, 0], ca.if_else(d[1] >= d[2], B[:, 1], B[:, 2]))
    u = column / ca.fmax(ca.norm_2(column), 1e-300)
    u = ca.if_else(ca.dot(u, v) < 0.0, -u, u)  # the sign sin θ · u carries
    return ca.if_else(theta > np.pi - _NEAR_PI_RAD, theta * u, factor * v)


def tracking_law_function(ff: FreeFloatingModel) -> ca.Function:
    """``(q, x_base, desired, posture, gains) -> [q̇ (n), ẋ_base (7), demand, conditioning]``.

    ``desired`` (18,): ``R_des`` (column-major), ``p_des`` [m], ``[v; ω]_des`` [m/s, rad/s], world; ``posture``
    (2n + 2,): the gain ramp σ, ``q_ref`` [rad], ``q̇_ref`` [rad/s], 1 with a posture reference (else 0); ``gains``
    (n + 4,): K [1/s], k_n, the rate cap's fraction c and power p (``q̇ / (1 + r^p)^(1/p)``, r the p-norm of
    ``q̇ / (c q̇_max)``), ``q̇_max`` [rad/s]. ``demand``: max |q̇ asked| / q̇_max before the cap."""
    n = ff.robot.n_joints
    q, x = ca.SX.sym("q", n), ca.SX.sym("x_base", 7)
    desired, posture, gains = ca.SX.sym("desired", 18), ca.SX.sym("posture", 2 * n + 2), ca.SX.sym("gains", n + 4)
    J_star, _, R_ee, p_ee = ff.gen_jacobian(q)
    R_wb = quat_to_rotation_sym(x[3:7])
    J = ca.vertcat(ca.mtimes(R_wb, J_star[:3, :]), ca.mtimes(R_wb, J_star[3:, :]))
    R_des = ca.reshape(desired[:9], 3, 3)
    error = ca.vertcat(desired[9:12] - (x[:3] + ca.mtimes(R_wb, p_ee)),
                       rotation_log_sym(ca.mtimes(R_des, ca.mtimes(R_wb, R_ee).T)))
    Q, R = ca.qr(J.T)
    J_pinv = ca.mtimes(Q, ca.solve(R, ca.SX.eye(6)).T)
    ramp, q_ref, qd_ref, with_ref = posture[0], posture[1:n + 1], posture[n + 1:2 * n + 1], posture[2 * n + 1]
    K, k_n, cap, power, qd_max = gains[0], gains[1], gains[2], gains[3], gains[4:]
    qd = ca.mtimes(J_pinv, desired[12:18] + K * ramp * error)
    null = k_n * ca.gradient(manipulability_sym(J_star), q) + with_ref * (qd_ref + K * (q_ref - q))
    qd = qd + ca.mtimes(ca.SX.eye(n) - ca.mtimes(J_pinv, J), ramp * null)
    demand = ca.fabs(qd) / qd_max
    r = ca.sum1((demand / cap) ** power) ** (1.0 / power)
    qd = qd / (1.0 + r**power) ** (1.0 / power)
    x_rate = pose_rate_sym(x, ff.base_twist(q, qd, ca.DM.zeros(6)), R_wb)
    diagonal = ca.fabs(ca.diag(R))
    return ca.Function("tracking_law", [q, x, desired, posture, gains],
                       [ca.vertcat(qd, x_rate, ca.mmax(demand), ca.mmin(diagonal) / ca.mmax(diagonal))])


@dataclass(frozen=True)
class LawAt:
    """The law at one state: the capped joint rates [rad/s], the base pose's rate, the rate demand before the cap
    (max |q̇ᵢ| / q̇_max,i) and the pseudo-inverse's conditioning (``min |R_ii| / max |R_ii|``)."""

    qd: Array  # (n,) [rad/s]
    x_base_rate: Array  # (7,) [m/s, 1/s]
    demand: float
    conditioning: float


class TrackingLaw:
    """:func:`tracking_law_function` of one robot, compiled (or interpreted where that is not possible) and called
    through a FunctionBuffer: make one object per simulation (:meth:`evaluator`), never share it between threads."""

    def __init__(self, law: ca.Function, n_joints: int) -> None:
        self.function = law
        self.n_joints = n_joints
        self._law = Buffered(law)

    @classmethod
    def of(cls, ff: FreeFloatingModel) -> TrackingLaw:
        """The law of ``ff``'s robot."""
        return cls(compiled(tracking_law_function(ff), with_jacobian=False), ff.robot.n_joints)

    def evaluator(self) -> TrackingLaw:
        """Another object on the same Function, with its own buffers."""
        return TrackingLaw(self.function, self.n_joints)

    def __call__(self, q: Array, x: Array, desired: Array, posture: Array, gains: Array) -> LawAt:
        """The law at joints ``q`` (n,) [rad], base pose ``x`` (7,) and the inputs of :func:`tracking_law_function`."""
        flat = self._law(q, x, desired, posture, gains)
        n = self.n_joints
        return LawAt(flat[:n], flat[n:n + 7], float(flat[n + 7]), float(flat[n + 8]))
