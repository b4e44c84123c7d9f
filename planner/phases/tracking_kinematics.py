"""The tracking IK's kinematics at one configuration, in one compiled CasADi call (:mod:`planner.phases.tracking`).

The IK law evaluates them four times per RK4 step: the generalized Jacobian and end-effector pose in world and
the manipulability gradient (Eq. 14) in one call, one flat vector, and then the zero-momentum base twist at the
commanded rates (Eq. 3 with h = 0). An ordinary CasADi call from Python costs more in argument and output
conversion than these expressions cost to evaluate: both are compiled and called through FunctionBuffers. The
numbers are the interpreted Functions' bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.model.freefloating import FreeFloatingModel, quat_to_rotation_sym
from planner.model.rotation import quat_to_matrix
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


def tracking_kinematics_function(ff: FreeFloatingModel) -> ca.Function:
    """``(q, x_base) -> flat``: the fields of :class:`KinematicsAt` in its order, each column-major, stacked."""
    n = ff.robot.n_joints
    q = ca.SX.sym("q", n)
    x = ca.SX.sym("x_base", 7)
    J_star, _, R_ee, p_ee = ff.gen_jacobian(q)
    R_wb = quat_to_rotation_sym(x[3:7])
    J_world = ca.vertcat(ca.mtimes(R_wb, J_star[:3, :]), ca.mtimes(R_wb, J_star[3:, :]))
    parts = [J_world, ca.mtimes(R_wb, R_ee), x[:3] + ca.mtimes(R_wb, p_ee), ca.gradient(manipulability_sym(J_star), q)]
    return ca.Function("tracking_kinematics", [q, x], [ca.vertcat(*(ca.vec(part) for part in parts))])


class Buffered:
    """A CasADi Function called through a FunctionBuffer: its inputs and its one output live in numpy arrays it
    holds (a third of the overhead of an ordinary call). Not to be shared between threads."""

    def __init__(self, fn: ca.Function) -> None:
        self.inputs = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.output = np.zeros(fn.nnz_out(0))
        self._buffer, self._eval = fn.buffer()
        for i, a in enumerate(self.inputs):
            self._buffer.set_arg(i, memoryview(a))
        self._buffer.set_res(0, memoryview(self.output))

    def __call__(self, *args: Array) -> Array:
        """The output (a copy) at ``args``, each flattened column-major."""
        for into, a in zip(self.inputs, args, strict=True):
            into[:] = np.ravel(a, order="F")
        self._eval()
        return self.output.copy()


class TrackingKinematics:
    """:class:`KinematicsAt` and the base pose's rate of one robot, from compiled Functions called through
    FunctionBuffers: make one object per simulation (:meth:`evaluator`), never share it between threads."""

    def __init__(self, kinematics: ca.Function, base_twist: ca.Function, n_joints: int) -> None:
        self.functions = kinematics, base_twist
        shapes = [(6, n_joints), (3, 3), (3,), (n_joints,)]
        ends = np.cumsum([int(np.prod(shape)) for shape in shapes])
        self._slices = [(slice(end - int(np.prod(shape)), end), shape) for end, shape in zip(ends, shapes, strict=True)]
        self._kinematics, self._base_twist = Buffered(kinematics), Buffered(base_twist)
        self._no_momentum = np.zeros(6)

    @classmethod
    def of(cls, ff: FreeFloatingModel) -> TrackingKinematics:
        """The kinematics of ``ff``'s robot, compiled to C (or interpreted where that is not possible)."""
        return cls(compiled(tracking_kinematics_function(ff), with_jacobian=False),
                   compiled(ff.base_twist, with_jacobian=False), ff.robot.n_joints)

    def evaluator(self) -> TrackingKinematics:
        """Another object on the same Functions, with its own buffers."""
        return TrackingKinematics(*self.functions, self._slices[3][1][0])

    def __call__(self, q: Array, x: Array) -> KinematicsAt:
        """The kinematics at joints ``q`` (n,) [rad] and base pose ``x`` (7,)."""
        flat = self._kinematics(q, x)
        return KinematicsAt(*(flat[s].reshape(shape, order="F") for s, shape in self._slices))

    def base_pose_rate(self, q: Array, qd: Array, x: Array) -> Array:
        """Rate (7,) of the base pose ``x = [p, quat_wxyz]`` at joints ``q`` [rad] and rates ``qd`` [rad/s], zero
        momentum: the base twist [v_b; ω_b] (base frame, Eq. 3 with h = 0) moved to world and to the quaternion."""
        nu = self._base_twist(q, qd, self._no_momentum)
        w = nu[3:]
        qw, qx, qy, qz = x[3:]
        quat_dot = 0.5 * np.array([-qx * w[0] - qy * w[1] - qz * w[2], qw * w[0] + qy * w[2] - qz * w[1],
                                   qw * w[1] - qx * w[2] + qz * w[0], qw * w[2] + qx * w[1] - qy * w[0]])
        return np.concatenate([quat_to_matrix(x[3:]) @ nu[:3], quat_dot])
