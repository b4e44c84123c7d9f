"""The tracking IK's kinematics at one configuration, in one compiled CasADi call (:mod:`planner.phases.tracking`).

The IK law evaluates them four times per RK4 step: the generalized Jacobian and end-effector pose in world,
the manipulability gradient (Eq. 14) and the zero-momentum base twist per unit joint rate (Eq. 3 with h = 0),
whose product with q̇ gives the base pose's rate. One call returns them all as one flat vector: a CasADi call
from Python costs more in argument and output conversion than these expressions cost to evaluate.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.model.freefloating import FreeFloatingModel, quat_to_rotation_sym
from planner.nlp.compiled import compiled
from planner.nlp.costs import manipulability_sym

Array = NDArray[np.float64]


@dataclass(frozen=True)
class KinematicsAt:
    """The chaser's kinematics at joints ``q`` [rad] and base pose ``x = [p_world_base [m], quat_world_base]``."""

    J_world: Array  # (6, n) generalized Jacobian (zero momentum): ee twist [v; ω] world per unit q̇ [m, 1]
    R_world_ee: Array  # (3, 3)
    p_world_ee_m: Array  # (3,)
    grad_manipulability: Array  # (n,) ∂w/∂q of Eq. 14 [1/rad]
    base_twist_per_rate: Array  # (6, n) base twist [v_b; ω_b] (base frame) per unit q̇, zero momentum [m, 1]
    R_world_base: Array  # (3, 3)

    def base_pose_rate(self, qd: Array, x: Array) -> Array:
        """Rate (7,) of the base pose ``x = [p, quat_wxyz]`` at joint rates ``qd`` (n,) [rad/s], zero momentum."""
        nu = self.base_twist_per_rate @ qd
        w = nu[3:]
        qw, qx, qy, qz = x[3:]
        quat_dot = 0.5 * np.array([-qx * w[0] - qy * w[1] - qz * w[2], qw * w[0] + qy * w[2] - qz * w[1],
                                   qw * w[1] - qx * w[2] + qz * w[0], qw * w[2] + qx * w[1] - qy * w[0]])
        return np.concatenate([self.R_world_base @ nu[:3], quat_dot])


def tracking_kinematics_function(ff: FreeFloatingModel) -> ca.Function:
    """``(q, x_base) -> flat``: the fields of :class:`KinematicsAt` in its order, each column-major, stacked."""
    n = ff.robot.n_joints
    q = ca.SX.sym("q", n)
    x = ca.SX.sym("x_base", 7)
    qd = ca.SX.sym("qd", n)
    J_star, _, R_ee, p_ee = ff.gen_jacobian(q)
    R_wb = quat_to_rotation_sym(x[3:7])
    J_world = ca.vertcat(ca.mtimes(R_wb, J_star[:3, :]), ca.mtimes(R_wb, J_star[3:, :]))
    # the base twist is linear in q̇ at zero momentum: its Jacobian in q̇ is the map itself
    W = ca.jacobian(ff.base_twist(q, qd, ca.DM.zeros(6)), qd)
    parts = [J_world, ca.mtimes(R_wb, R_ee), x[:3] + ca.mtimes(R_wb, p_ee), ca.gradient(manipulability_sym(J_star), q),
             W, R_wb]
    return ca.Function("tracking_kinematics", [q, x], [ca.vertcat(*(ca.vec(part) for part in parts))])


class TrackingKinematics:
    """:class:`KinematicsAt` of one robot, from a compiled :func:`tracking_kinematics_function`.

    Each call goes through a CasADi FunctionBuffer (arguments and output in numpy arrays it holds), a third of
    the overhead of an ordinary call. One buffer serves one thread: make one object per simulation
    (:meth:`evaluator`), never share it between threads.
    """

    def __init__(self, fn: ca.Function, n_joints: int) -> None:
        self.fn = fn
        shapes = [(6, n_joints), (3, 3), (3,), (n_joints,), (6, n_joints), (3, 3)]
        ends = np.cumsum([int(np.prod(shape)) for shape in shapes])
        self._slices = [(slice(end - int(np.prod(shape)), end), shape) for end, shape in zip(ends, shapes, strict=True)]
        self._q, self._x, self._out = np.zeros(n_joints), np.zeros(7), np.zeros(int(ends[-1]))
        self._buffer, self._eval = fn.buffer()
        self._buffer.set_arg(0, memoryview(self._q))
        self._buffer.set_arg(1, memoryview(self._x))
        self._buffer.set_res(0, memoryview(self._out))

    @classmethod
    def of(cls, ff: FreeFloatingModel) -> TrackingKinematics:
        """The kinematics of ``ff``'s robot, compiled to C (or interpreted where that is not possible)."""
        return cls(compiled(tracking_kinematics_function(ff), with_jacobian=False), ff.robot.n_joints)

    def evaluator(self) -> TrackingKinematics:
        """Another object on the same Function, with its own buffer."""
        return TrackingKinematics(self.fn, len(self._q))

    def __call__(self, q: Array, x: Array) -> KinematicsAt:
        """The kinematics at joints ``q`` (n,) [rad] and base pose ``x`` (7,)."""
        self._q[:] = q
        self._x[:] = x
        self._eval()
        flat = self._out.copy()
        return KinematicsAt(*(flat[s].reshape(shape, order="F") for s, shape in self._slices))
