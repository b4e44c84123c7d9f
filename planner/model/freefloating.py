"""Free-floating chaser: momentum map, base twist, generalized Jacobian, base-pose integration (Eq. 1-2).

With no external force (the robot phases), linear and angular momentum are conserved:
``A_b(q) ν_b + A_m(q) q̇ = h``. Everything here is written in the **base frame** (the map does not
depend on the base pose); ``ν_b = [v_b; ω_b]`` is the velocity of the base frame origin and the base
angular velocity, both in base coordinates (pinocchio's free-flyer velocity convention), and
``h = [P; L_G]`` is the linear momentum and the angular momentum about the system COM, in base
coordinates (``h_base = blkdiag(Rᵀ, Rᵀ) h_world``).

With bodies i (base included) of mass m_i, COM r_i, inertia I_i (base coordinates, about the COM),
joints j of origin o_j and axis k_j, ``J_T,i = [k_j × (r_i − o_j)]_{j drives i}``, ``J_R,i = [k_j]``,
M = Σ m_i, r_g = Σ m_i r_i / M, ``J_Tw = Σ m_i J_T,i``, ``H_wq = Σ (I_i J_R,i + m_i [r_i]× J_T,i)``:

    P   = M v_b − M [r_g]× ω_b + J_Tw q̇
    L_G = Ĩ ω_b + (H_wq − [r_g]× J_Tw) q̇,     Ĩ = Σ (I_i − m_i [r_i]×²) + M [r_g]×²  (system inertia about r_g)

so the base twist is a 3×3 (Schur) solve: ``ω_b = Ĩ⁻¹ (L_G − (H_wq − [r_g]× J_Tw) q̇)``,
``v_b = (P − J_Tw q̇)/M + [r_g]× ω_b``. The generalized Jacobian (Umetani–Yoshida) follows as
``J* = J_m − J_b A_b⁻¹ A_m``; for h ≠ 0 the end-effector twist is ``J* q̇ + J_b A_b⁻¹ h``.
Base pose: ``ṗ_world_base = R v_b``, ``q̇_world_base = ½ q ⊗ [0, ω_b]`` (quaternions ``[w, x, y, z]``).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.model.robot import RobotModel, chain_kinematics
from planner.nlp.compiled import compiled

Array = NDArray[np.float64]
Symbolic = ca.SX | ca.MX | ca.DM  # a CasADi expression: the functions here build SX/MX graphs or evaluate on DM


def _skew(v: Symbolic) -> Symbolic:
    """Cross-product matrix ``[v]×`` of a 3-vector (SX, MX or DM)."""
    return ca.vertcat(
        ca.horzcat(0, -v[2], v[1]),
        ca.horzcat(v[2], 0, -v[0]),
        ca.horzcat(-v[1], v[0], 0),
    )


def quat_to_rotation_sym(quat: Symbolic) -> Symbolic:
    """Rotation matrix of a symbolic ``[w, x, y, z]`` quaternion (normalised inside)."""
    n = ca.sqrt(ca.sumsqr(quat))
    w, x, y, z = quat[0] / n, quat[1] / n, quat[2] / n, quat[3] / n
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        ca.horzcat(2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        ca.horzcat(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


@functools.cache
def quat_rotation_function() -> ca.Function:
    """:func:`quat_to_rotation_sym` as one SX Function ``quat (4,) -> R (3, 3)``: one node in an MX graph."""
    quat = ca.SX.sym("quat_wxyz", 4)
    return ca.Function("quat_rotation", [quat], [quat_to_rotation_sym(quat)], ["quat_wxyz"], ["R"])


def _quat_times_pure(quat: Symbolic, omega: Symbolic) -> Symbolic:
    """``quat ⊗ [0, ω]``."""
    w, x, y, z = quat[0], quat[1], quat[2], quat[3]
    a, b, c = omega[0], omega[1], omega[2]
    return ca.vertcat(
        -x * a - y * b - z * c,
        w * a + y * c - z * b,
        w * b - x * c + z * a,
        w * c + x * b - y * a,
    )


def pose_rate_sym(x_base: Symbolic, twist_base: Symbolic, R_world_base: Symbolic) -> Symbolic:
    """Rate of the base pose ``x = [p_world_base (3), quat_world_base (4)]`` at the base twist ``[v_b; ω_b]`` (base
    frame): ``[R v_b; ½ q ⊗ [0, ω_b]]``, ``R_world_base`` the pose's rotation (computed once by the caller)."""
    return ca.vertcat(ca.mtimes(R_world_base, twist_base[:3]), 0.5 * _quat_times_pure(x_base[3:7], twist_base[3:]))


@dataclass(frozen=True)
class MomentumMap:
    """Symbolic pieces of the momentum map for joint angles ``q`` (base frame, see module doc)."""

    mass_kg: float | Symbolic  # [kg], a number or a symbol
    r_g: Symbolic  # (3,) system COM [m]
    inertia_g: Symbolic  # (3, 3) Ĩ, system inertia about the COM [kg·m²]
    J_Tw: Symbolic  # (3, n)
    H_L: Symbolic  # (3, n), H_wq − [r_g]× J_Tw
    p_ee: Symbolic  # (3,) [m]
    R_ee: Symbolic  # (3, 3)
    J_m_ee: Symbolic  # (6, n), ee twist (base frame) for a fixed base


def momentum_map(robot: RobotModel, q: ca.SX | ca.MX) -> MomentumMap:
    """Build the momentum-map quantities of the module docstring for symbolic ``q`` [rad]."""
    kin = chain_kinematics(robot, q)
    n = robot.n_joints
    zeros = ca.SX.zeros if isinstance(q, ca.SX) else ca.MX.zeros
    # inertias may be numbers or, for the compound after the grasp, symbols (planner.model.compound)
    M = sum(body.mass_kg for body in robot.inertias)
    coms, Ib = [], []
    for i, body in enumerate(robot.inertias):
        coms.append(kin.p[i] + ca.mtimes(kin.R[i], body.com_body_m))
        Ib.append(ca.mtimes(ca.mtimes(kin.R[i], body.inertia_com_kg_m2), kin.R[i].T))
    r_g = sum((body.mass_kg * coms[i] for i, body in enumerate(robot.inertias)), zeros(3)) / M
    inertia_sum = zeros(3, 3)
    J_Tw = zeros(3, n)
    H_wq = zeros(3, n)
    for i, body in enumerate(robot.inertias):
        m = body.mass_kg
        S = _skew(coms[i])
        inertia_sum += Ib[i] - m * ca.mtimes(S, S)
        if i == 0:
            continue
        # joints 0..i-1 drive body i (body i is carried by joint i-1)
        cols_T = [ca.cross(kin.axes_base[j], coms[i] - kin.origins_base[j]) for j in range(i)]
        cols_R = [kin.axes_base[j] for j in range(i)]
        J_T = ca.horzcat(*cols_T, zeros(3, n - i))
        J_R = ca.horzcat(*cols_R, zeros(3, n - i))
        J_Tw += m * J_T
        H_wq += ca.mtimes(Ib[i], J_R) + m * ca.mtimes(S, J_T)
    Sg = _skew(r_g)
    inertia_g = inertia_sum + M * ca.mtimes(Sg, Sg)
    H_L = H_wq - ca.mtimes(Sg, J_Tw)
    J_T_ee = ca.horzcat(*[ca.cross(kin.axes_base[j], kin.p_ee - kin.origins_base[j]) for j in range(n)])
    J_R_ee = ca.horzcat(*kin.axes_base)
    return MomentumMap(M, r_g, inertia_g, J_Tw, H_L, kin.p_ee, kin.R_ee, ca.vertcat(J_T_ee, J_R_ee))


def base_twist_sym(mm: MomentumMap, qd: Symbolic, h_base: Symbolic) -> Symbolic:
    """Base twist ``[v_b; ω_b]`` (base frame) that gives momentum ``h_base`` at joint rates ``qd``."""
    omega = ca.solve(mm.inertia_g, h_base[3:] - ca.mtimes(mm.H_L, qd))
    v = (h_base[:3] - ca.mtimes(mm.J_Tw, qd)) / mm.mass_kg + ca.cross(mm.r_g, omega)
    return ca.vertcat(v, omega)


def generalized_jacobian_sym(mm: MomentumMap) -> tuple[Symbolic, Symbolic]:
    """``(J*, D)`` with ee twist (base frame) ``= J* q̇ + D h_base``; J* is 6×n, D is 6×6."""
    Ig_inv = ca.inv(mm.inertia_g)
    Sg = _skew(mm.r_g)
    # base twist per unit q̇ and per unit h (columns of −A_b⁻¹ A_m and A_b⁻¹)
    W_q = -ca.mtimes(Ig_inv, mm.H_L)
    V_q = -mm.J_Tw / mm.mass_kg + ca.mtimes(Sg, W_q)
    V_h = ca.horzcat(ca.DM.eye(3) / mm.mass_kg, ca.mtimes(Sg, Ig_inv))
    W_h = ca.horzcat(ca.DM.zeros(3, 3), Ig_inv)
    # ee twist from a base twist [v; ω]: v_ee = v + ω × p_ee = v − [p_ee]× ω, ω_ee = ω
    Se = _skew(mm.p_ee)
    J_star = mm.J_m_ee + ca.vertcat(V_q - ca.mtimes(Se, W_q), W_q)
    D = ca.vertcat(V_h - ca.mtimes(Se, W_h), W_h)
    return J_star, D


def base_pose_rate_sym(mm: MomentumMap, x_base: Symbolic, qd: Symbolic, h_world: Symbolic) -> Symbolic:
    """Time derivative of the base pose ``x = [p_world_base (3), quat_world_base (4)]``."""
    R = quat_to_rotation_sym(x_base[3:7])
    h_base = ca.vertcat(ca.mtimes(R.T, h_world[:3]), ca.mtimes(R.T, h_world[3:]))
    return pose_rate_sym(x_base, base_twist_sym(mm, qd, h_base), R)


@dataclass
class FreeFloatingModel:
    """CasADi Functions of the free-floating robot, built once per robot model.

    * ``momentum(q) -> (A_b 6×6, A_m 6×n, r_g)`` base frame
    * ``base_twist(q, qd, h_base) -> twist_base (6)``
    * ``gen_jacobian(q) -> (J_star 6×n, D 6×6, R_ee, p_ee)`` base frame
    * ``rk4_step(x, q0, qd0, qm, qdm, q1, qd1, h_world, dt) -> x_next`` (quaternion renormalised)
    * ``zero_momentum_twist(q, qd) -> twist_base (6)``: the base twist at zero momentum, which depends on the joints
      alone; with :func:`pose_rk4_step` it is :meth:`rk4_step` at ``h_world = 0`` split in two
    Call them with numpy for numeric use or with SX/MX inside an NLP. ``compile_rk4``: ``rk4_step`` compiled to
    C (:mod:`planner.nlp.compiled`), for a model whose RK4 steps an NLP differentiates (the chaser's, in a Planner);
    off for the models made per grasp, which would each compile a library.
    """

    robot: RobotModel
    compile_rk4: bool = False
    # the dense re-simulation's RK4 step with parameters as last input (a compound's compiled step, its grasp
    # geometry the parameters), used instead of this model's own step when given
    parametric_rk4: tuple[ca.Function, Array] | None = None
    momentum: ca.Function = field(init=False)
    base_twist: ca.Function = field(init=False)
    gen_jacobian: ca.Function = field(init=False)
    rk4_step: ca.Function = field(init=False)
    zero_momentum_twist: ca.Function = field(init=False)

    def __post_init__(self) -> None:
        n = self.robot.n_joints
        q = ca.SX.sym("q", n)
        qd = ca.SX.sym("qd", n)
        h = ca.SX.sym("h", 6)
        mm = momentum_map(self.robot, q)
        Sg = _skew(mm.r_g)
        A_b = ca.vertcat(
            ca.horzcat(mm.mass_kg * ca.DM.eye(3), -mm.mass_kg * Sg),
            ca.horzcat(ca.DM.zeros(3, 3), mm.inertia_g),
        )
        A_m = ca.vertcat(mm.J_Tw, mm.H_L)
        self.momentum = ca.Function("momentum", [q], [A_b, A_m, mm.r_g], ["q"], ["A_b", "A_m", "r_g"])
        self.base_twist = ca.Function("base_twist", [q, qd, h], [base_twist_sym(mm, qd, h)],
                                      ["q", "qd", "h_base"], ["twist_base"])
        J_star, D = generalized_jacobian_sym(mm)
        self.gen_jacobian = ca.Function("gen_jacobian", [q], [J_star, D, mm.R_ee, mm.p_ee],
                                        ["q"], ["J_star", "D", "R_ee", "p_ee"])
        self.rk4_step = rk4_step_function(self.robot)
        self.zero_momentum_twist = ca.Function("zero_momentum_twist", [q, qd], [base_twist_sym(mm, qd, ca.DM.zeros(6))],
                                               ["q", "qd"], ["twist_base"])
        if self.compile_rk4:
            self.rk4_step = compiled(self.rk4_step)
            self.zero_momentum_twist = compiled(self.zero_momentum_twist)

    def integrate_base(
        self,
        times_s: Array,
        joint_state: Callable[[Array], tuple[Array, Array]],
        x0: Array,
        h_world: Array | None = None,
    ) -> Array:
        """Base poses ``[p (3), quat (4)]`` at ``times_s`` by RK4 along a joint motion (numeric).

        ``joint_state(t) -> (q, qd)`` evaluates the joint motion at any time [s]; RK4 stages use the
        midpoint. Returns (len(times_s), 7).
        """
        t = np.asarray(times_s, dtype=float)
        mids = 0.5 * (t[:-1] + t[1:])
        nodes = [joint_state(tk) for tk in t]
        halves = [joint_state(tm) for tm in mids]
        return self.integrate_base_sampled(t, np.array([a for a, _ in nodes]), np.array([b for _, b in nodes]),
                                           np.array([a for a, _ in halves]).reshape(len(mids), -1),
                                           np.array([b for _, b in halves]).reshape(len(mids), -1), x0, h_world)

    def integrate_base_sampled(self, times_s: Array, q: Array, qd: Array, q_mid: Array, qd_mid: Array, x0: Array,
                               h_world: Array | None = None) -> Array:
        """:meth:`integrate_base` from joint samples: ``q``, ``qd`` (rad, rad/s) at ``times_s`` (n, n_joints),
        ``q_mid``, ``qd_mid`` at the step midpoints (n − 1, n_joints). One CasADi call for all steps.
        """
        t = np.asarray(times_s, dtype=float)
        h = np.zeros(6) if h_world is None else np.asarray(h_world, dtype=float)
        xs = np.empty((len(t), 7))
        xs[0] = x0
        steps = len(t) - 1
        if steps == 0:
            return xs
        step, extra = self.rk4_step, []
        if self.parametric_rk4 is not None:
            step, parameters = self.parametric_rk4
            extra = [np.tile(np.asarray(parameters, dtype=float)[:, None], (1, steps))]
        run = step.mapaccum("rk4_base_steps", steps)
        xs[1:] = np.asarray(run(x0, q[:-1].T, qd[:-1].T, q_mid.T, qd_mid.T, q[1:].T, qd[1:].T,
                                np.tile(h[:, None], (1, steps)), np.diff(t)[None, :], *extra)).T
        return xs


def rk4_step_function(robot: RobotModel, parameters: ca.SX | None = None) -> ca.Function:
    """``(x, q0, qd0, qm, qdm, q1, qd1, h_world, dt[, parameters]) -> x_next``: one RK4 step of the base pose.

    ``parameters``: the SX symbols ``robot``'s inertias are written in (the compound's grasp geometry,
    :mod:`planner.model.compound`), which become the Function's last input; None for a numeric robot.
    """
    n = robot.n_joints
    extra = [] if parameters is None else [parameters]
    x = ca.SX.sym("x", 7)
    q0, qd0, qm, qdm, q1, qd1 = (ca.SX.sym(nm, n) for nm in ("q0", "qd0", "qm", "qdm", "q1", "qd1"))
    h = ca.SX.sym("h_world", 6)
    dt = ca.SX.sym("dt")
    # one momentum-map Function per stage keeps the expression graph small (shared subexpressions)
    qs = ca.SX.sym("qs", n)
    qds = ca.SX.sym("qds", n)
    xs = ca.SX.sym("xs", 7)
    rate = ca.Function("base_rate", [xs, qs, qds, h, *extra],
                       [base_pose_rate_sym(momentum_map(robot, qs), xs, qds, h)])
    k1 = rate(x, q0, qd0, h, *extra)
    k2 = rate(x + 0.5 * dt * k1, qm, qdm, h, *extra)
    k3 = rate(x + 0.5 * dt * k2, qm, qdm, h, *extra)
    k4 = rate(x + dt * k3, q1, qd1, h, *extra)
    x_next = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    quat = x_next[3:7] / ca.sqrt(ca.sumsqr(x_next[3:7]))
    names = ["x", "q0", "qd0", "qm", "qdm", "q1", "qd1", "h_world", "dt"] + ["parameters"] * len(extra)
    return ca.Function("rk4_base_step", [x, q0, qd0, qm, qdm, q1, qd1, h, dt, *extra],
                       [ca.vertcat(x_next[:3], quat)], names, ["x_next"])


@functools.cache
def pose_rk4_step() -> ca.Function:
    """``(x, twist0, twist_mid, twist1, dt) -> x_next``: one RK4 step of the base pose from its base-frame twists
    at the step's start, midpoint and end (quaternion renormalised).

    At zero momentum the twist depends on the joints alone (:attr:`FreeFloatingModel.zero_momentum_twist`), so
    both midpoint stages share one, and a step's end twist is the next step's start: an NLP evaluates and
    differentiates the momentum map twice per step instead of four times. Same operations as :func:`rk4_step_function`.
    """
    x, dt = ca.SX.sym("x", 7), ca.SX.sym("dt")
    t0, tm, t1 = (ca.SX.sym(nm, 6) for nm in ("twist0", "twist_mid", "twist1"))

    def rate(xk: ca.SX, twist: ca.SX) -> ca.SX:
        return pose_rate_sym(xk, twist, quat_to_rotation_sym(xk[3:7]))

    k1 = rate(x, t0)
    k2 = rate(x + 0.5 * dt * k1, tm)
    k3 = rate(x + 0.5 * dt * k2, tm)
    k4 = rate(x + dt * k3, t1)
    x_next = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    quat = x_next[3:7] / ca.sqrt(ca.sumsqr(x_next[3:7]))
    return ca.Function("pose_rk4_step", [x, t0, tm, t1, dt], [ca.vertcat(x_next[:3], quat)],
                       ["x", "twist0", "twist_mid", "twist1", "dt"], ["x_next"])
