"""Phase 3, stabilization: an NLP over the compound chaser + target (paper Eq. 10-13, 24).

At the grasp the target becomes rigidly attached to the gripper (its inertia is added to the last
link); the compound keeps the momentum it had at that instant (h₀ ≠ 0: the target's spin). The joint
B-spline of Eq. 24 starts at the tracking end state: position, velocity, and an acceleration the scenario
chooses — the tracking IK's (our generalisation: the joint motion is C² across the join and the grasp
wrench starts from zero, which a tight grasp-torque limit needs) or zero (the paper's Eq. 24, which
copes with a grasp where the IK is still accelerating hard) — and brings the joint velocities to zero at
t_f³ (Eq. 11). Constraints at k via points: joint boxes (Eq. 12), collision with the target now in the
chain (Eq. 13), and the grasp wrench within its limits: the force and moment the gripper exerts on the
target, ``F = m_T a_T``, ``M = I_T ω̇_T + ω_T × I_T ω_T + (p_T − p_grasp) × F`` (about the grasp point),
in the grasp frame — what a wrist force/torque sensor reads. Accelerations come from exact time
derivatives (``casadi.jtimes``) of the symbolic twists along the state rates. Costs: chaser attitude
disturbance (Σ‖ω_base‖² at the via points) or peak grasp torque (a slack bounding every component).
With no stabilization cost weight the solve stops at the first iterate inside every constraint
(:mod:`planner.nlp.feasibility_stop`).

The NLP is built once per scenario: where the target was grasped (the compound's last-link inertia, the
wrench's lever arms) enters as parameters (:mod:`planner.model.compound`), so every grasp, at any free-axis
angle, reuses it. It is an MX graph over small SX Functions.

A cold solve goes coarse to fine: the same NLP on ``coarse_via_points`` via points first (a third of the
cost per iteration), then the full NLP from that answer. Scenario II's torque limit leaves a thin feasible
set that IPOPT's limited-memory iterations approach slowly from the heuristic start (122 iterations, 53 s
cold); from the coarse answer the full NLP needs a fraction of that (measured: 38 + 32 iterations, 14 s).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import SceneDistanceCallback, pose_vector
from planner.collision.layout import TARGET_BODY
from planner.collision.nlp_scene import build_scene
from planner.config.scenario import Scenario
from planner.model.compound import GEOMETRY_SIZE, GraspGeometry, grasp_geometry
from planner.model.freefloating import (
    FreeFloatingModel,
    base_pose_rate_sym,
    base_twist_sym,
    generalized_jacobian_sym,
    momentum_map,
    quat_to_rotation_sym,
    rk4_step_function,
)
from planner.model.robot import RobotModel, fk_function
from planner.model.rotation import quat_to_matrix
from planner.nlp import constraint_backoff
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.phase_spline import stabilization_vertices
from planner.nlp.compiled import compiled
from planner.nlp.feasibility_stop import FeasibilityStop
from planner.nlp.ipopt import ipopt_options, ipopt_solver

Array = NDArray[np.float64]

# CasADi's ``jac_penalty`` of the grasp-wrench Function. The NLP's constraint Jacobian pushes one forward
# direction per decision parameter (~35) through each of its ~66 calls; CasADi instead forms the Function's
# own Jacobian (a few reverse sweeps) and multiplies the seeds when jac_penalty × its 69 inputs (34 of state,
# 35 of grasp geometry) is below the number of directions, which the default (2) forbids. Same exact
# derivative, fewer sweeps: measured on scenario II, interpreted, the constraint Jacobian 0.29 s → 0.16 s. (A
# compiled wrench, planner.nlp.compiled, is always differentiated through its compiled Jacobian.)
JACOBIAN_FIRST_PENALTY = 0.25


@dataclass(frozen=True)
class GraspState:
    """The compound's state at the grasp instant (start of stabilization)."""

    q: Array  # rad
    qd: Array  # rad/s
    qdd: Array  # rad/s², the stabilization spline's start acceleration (scenario.stabilization.start_acceleration)
    x_base: Array  # [p_world_base, quat_world_base]
    h_world: Array  # [P, L_G] of the compound, world (N·s, N·m·s)
    T_ee_target: Array  # 4×4, target body frame in the ee (grasp) frame


@dataclass(frozen=True)
class StabilizationSolution:
    params: Array  # Eq. 24 free parameters, planner.nlp.bspline layout
    success: bool
    status: str
    iterations: int
    solve_time_s: float
    build_time_s: float
    cost: float
    peak_torque_nm: float  # at the via points, grasp frame, max |component|
    min_distance_m: float


def grasp_momentum_world(chaser: FreeFloatingModel, compound: FreeFloatingModel, q: Array, qd: Array,
                         x_base: Array) -> Array:
    """Momentum ``[P, L_G]`` (world; N·s, N·m·s) of the compound at the grasp instant.

    Before the grasp the chaser's own momentum is zero, so its base moves with the twist that momentum
    gives; the target moves rigidly with the gripper (matched velocity), so the compound with that base
    twist and the joint rates ``qd`` carries the chaser's and the target's momentum together.
    """
    nu = np.asarray(chaser.base_twist(q, qd, np.zeros(6))).ravel()
    A_b, A_m, _ = (np.asarray(a) for a in compound.momentum(q))
    h_base = A_b @ nu + A_m @ qd
    R = quat_to_matrix(x_base[3:])
    return np.concatenate([R @ h_base[:3], R @ h_base[3:]])


def wrench_function(robot: RobotModel) -> ca.Function:
    """``(x_base, q, qd, qdd, h_world, geometry) -> (F_grasp, M_grasp, ω_base, R_ee, p_ee)``, all SX-exact.

    F, M: force (N) and moment about the grasp point (N·m) the gripper exerts on the target, in the
    grasp frame; ω_base: chaser base angular velocity (rad/s, base frame); R_ee, p_ee: gripper pose in the
    world. ``geometry``: the grasp geometry (:mod:`planner.model.compound`), so the Function depends on the
    chaser ``robot`` alone.
    """
    n = robot.n_joints
    x = ca.SX.sym("x_base", 7)
    q = ca.SX.sym("q", n)
    qd = ca.SX.sym("qd", n)
    qdd = ca.SX.sym("qdd", n)
    h = ca.SX.sym("h_world", 6)
    geo_vec = ca.SX.sym("geometry", GEOMETRY_SIZE)
    geo = GraspGeometry.unpack(geo_vec)
    mm = momentum_map(geo.compound(robot), q)
    R_wb = quat_to_rotation_sym(x[3:7])
    h_base = ca.vertcat(ca.mtimes(R_wb.T, h[:3]), ca.mtimes(R_wb.T, h[3:]))
    J_star, D = generalized_jacobian_sym(mm)
    twist_ee_base = ca.mtimes(J_star, qd) + ca.mtimes(D, h_base)
    R_ee = ca.mtimes(R_wb, mm.R_ee)
    p_ee = x[:3] + ca.mtimes(R_wb, mm.p_ee)
    v_ee = ca.mtimes(R_wb, twist_ee_base[:3])
    w_ee = ca.mtimes(R_wb, twist_ee_base[3:])
    r_T = ca.mtimes(R_ee, geo.p_ee_target)  # grasp point → target COM, world
    v_T = v_ee + ca.cross(w_ee, r_T)
    state = ca.vertcat(x, q, qd)
    rate = ca.vertcat(base_pose_rate_sym(mm, x, qd, h), qd, qdd)
    a_T = ca.jtimes(v_T, state, rate)
    alpha = ca.jtimes(w_ee, state, rate)
    R_T = ca.mtimes(R_ee, geo.R_ee_target)
    I_w = ca.mtimes(ca.mtimes(R_T, geo.target_inertia_body_kg_m2), R_T.T)
    F = geo.target_mass_kg * a_T
    M_com = ca.mtimes(I_w, alpha) + ca.cross(w_ee, ca.mtimes(I_w, w_ee))
    M_grasp = M_com + ca.cross(r_T, F)
    twist_base = base_twist_sym(mm, qd, h_base)
    return ca.Function("grasp_wrench", [x, q, qd, qdd, h, geo_vec],
                       [ca.mtimes(R_ee.T, F), ca.mtimes(R_ee.T, M_grasp), twist_base[3:], R_ee, p_ee],
                       ["x_base", "q", "qd", "qdd", "h_world", "geometry"],
                       ["F_grasp", "M_grasp", "omega_base", "R_ee", "p_ee"],
                       {"jac_penalty": JACOBIAN_FIRST_PENALTY})


def stabilization_spline(scenario: Scenario) -> UniformCubicBSpline:
    """The joint B-spline of Eq. 24 over t_f³ (s) with the scenario's number of vertices."""
    return UniformCubicBSpline(scenario.stabilization.n_vertices, scenario.phases.stabilization_s)


def via_point_times(spline: UniformCubicBSpline, count: int) -> NDArray[np.float64]:
    """``count`` uniform via points in (0, t_f³] plus every interior knot of the spline (s).

    Within a segment the joint accelerations are linear, so the wrench is smooth; at a knot the jerk
    jumps and the wrench's slope kinks, which is where it peaks between uniform via points. Putting a
    via point on every knot removes that blind spot.
    """
    T = spline.duration_s
    uniform = T * np.arange(1, count + 1) / count
    knots = spline.segment_duration_s * np.arange(1, spline.n_segments)
    return np.unique(np.round(np.concatenate([uniform, knots]), 9))


# The feasibility stop's tolerance on the constraint values: IPOPT's iterates sit on the boundary of
# active constraints only to ~1e-6 before mu is small; the back-offs (planner.nlp.constraint_backoff)
# are 1e4 times larger, so this changes nothing dense verification can see.
STOP_CONSTRAINT_TOL = 1e-6


@dataclass(frozen=True)
class InnerFunctions:
    """The SX Functions the stabilization NLP calls at every RK4 node and via point; they depend on the robot
    alone (grasp geometry is an input), so the coarse and the full NLP share one set."""

    rk4_step: ca.Function  # rk4_step_function of the compound, geometry as last input (compiled)
    wrench: ca.Function  # wrench_function (compiled)
    fk: ca.Function  # fk_function

    @staticmethod
    def of(robot: RobotModel) -> InnerFunctions:
        """Build them, the RK4 step and the wrench compiled to C (:mod:`planner.nlp.compiled`)."""
        geometry = ca.SX.sym("geometry", GEOMETRY_SIZE)
        return InnerFunctions(compiled(rk4_step_function(GraspGeometry.unpack(geometry).compound(robot), geometry)),
                              compiled(wrench_function(robot), {"jac_penalty": JACOBIAN_FIRST_PENALTY}),
                              fk_function(robot))


class StabilizationProblem:
    """The stabilization NLP of a scenario; solve() takes the grasp state and its geometry as parameters."""

    def __init__(self, scenario: Scenario, torque_limit_nm: float | None = None,
                 functions: InnerFunctions | None = None) -> None:
        t_build = time.perf_counter()
        self.scenario = sc = scenario
        robot = sc.robot
        n = robot.n_joints
        st = sc.stabilization
        T = sc.phases.stabilization_s
        self.spline = stabilization_spline(sc)
        via_times = via_point_times(self.spline, st.via_points)
        k = len(via_times)
        self.k = k
        self.n_params = n * self.spline.n_free_per_joint
        self.torque_limit_nm = torque_limit_nm
        self.coarse_via_points = st.coarse_via_points
        self._coarse: StabilizationProblem | None = None
        torque_limit = sc.limits.grasp_torque_max_nm if torque_limit_nm is None else torque_limit_nm

        P = ca.MX.sym("P", self.n_params)
        par = ca.MX.sym("par", 3 * n + 7 + 6 + GEOMETRY_SIZE)  # q_in, qd_in, qdd_in, x_base0, h_world, geometry
        q_in, qd_in, a_in = par[:n], par[n:2 * n], par[2 * n:3 * n]
        x = par[3 * n:3 * n + 7]
        h = par[3 * n + 7:3 * n + 13]
        geo_vec = par[3 * n + 13:]
        geo = GraspGeometry.unpack(geo_vec)
        self.functions = fn = functions or InnerFunctions.of(robot)
        V = stabilization_vertices(self.spline, q_in, qd_in, a_in, P)
        # RK4 nodes: a uniform grid refined so that every via point is a node (steps may differ)
        nodes = np.unique(np.round(np.concatenate([np.linspace(0.0, T, st.rk4_steps + 1), via_times]), 9))
        mids = 0.5 * (nodes[:-1] + nodes[1:])
        Qn, Qdn, Qddn = (self.spline.evaluate(V, nodes, d) for d in (0, 1, 2))
        Qm, Qdm = (self.spline.evaluate(V, mids, d) for d in (0, 1))
        xs = [x]
        for i in range(len(nodes) - 1):
            x = fn.rk4_step(x, Qn[i, :].T, Qdn[i, :].T, Qm[i, :].T, Qdm[i, :].T, Qn[i + 1, :].T, Qdn[i + 1, :].T,
                         h, nodes[i + 1] - nodes[i], geo_vec)
            xs.append(x)
        via_idx = [int(np.argmin(np.abs(nodes - tv))) for tv in via_times]
        forces, torques, omegas, poses = [], [], [], []
        for i in via_idx:
            F, M, w_b, R_ee, p_ee = fn.wrench(xs[i], Qn[i, :].T, Qdn[i, :].T, Qddn[i, :].T, h, geo_vec)
            forces.append(F)
            torques.append(M)
            omegas.append(w_b)
            R_wb = quat_to_rotation_sym(xs[i][3:7])
            out = fn.fk(Qn[i, :].T)
            blocks = [pose_vector(ca.mtimes(R_wb, out[2 * b]), xs[i][:3] + ca.mtimes(R_wb, out[2 * b + 1]))
                      for b in range(len(robot.body_names))]
            blocks.append(pose_vector(ca.mtimes(R_ee, geo.R_ee_target), p_ee + ca.mtimes(R_ee, geo.p_ee_target)))
            poses.append(ca.vertcat(*blocks))
        self.scene = build_scene(sc)
        self.distance_cb = SceneDistanceCallback("stabilization_distance", self.scene,
                                                 [*robot.body_names, TARGET_BODY], len(poses))
        dists = [self.distance_cb(ca.vertcat(*poses))]
        q_box = ca.vertcat(*[Qn[i, :].T for i in via_idx])
        qd_box = ca.vertcat(*[Qdn[i, :].T for i in via_idx])
        M_all = ca.vertcat(*torques)
        F_all = ca.vertcat(*forces)
        att = sum(ca.sumsqr(w) for w in omegas) / k
        c = sc.costs
        w_extra, lbw_extra, ubw_extra = [], [], []
        cost = c.attitude_disturbance * att
        g = [q_box, qd_box, *dists, M_all, F_all]
        margin = sc.limits.collision_margin_m
        n_d = len(self.scene.pairs)
        tl = torque_limit if np.isfinite(torque_limit) else np.inf
        fl = sc.limits.grasp_force_max_n if np.isfinite(sc.limits.grasp_force_max_n) else np.inf
        bo = constraint_backoff
        qd_lim = bo.JOINT_VELOCITY_FRACTION * robot.qd_max
        tl, fl = bo.WRENCH_FRACTION * tl, bo.WRENCH_FRACTION * fl
        lbg = [np.tile(robot.q_min + bo.JOINT_POSITION_RAD, k), np.tile(-qd_lim, k),
               np.full(k * n_d, margin + bo.COLLISION_M), np.full(3 * k, -tl), np.full(3 * k, -fl)]
        ubg = [np.tile(robot.q_max - bo.JOINT_POSITION_RAD, k), np.tile(qd_lim, k), np.full(k * n_d, np.inf),
               np.full(3 * k, tl), np.full(3 * k, fl)]
        if c.peak_wrench > 0:
            s = ca.MX.sym("s_torque")
            w_extra.append(s)
            lbw_extra.append(0.0)
            ubw_extra.append(np.inf)
            g += [s - M_all, s + M_all]
            lbg += [np.zeros(3 * k), np.zeros(3 * k)]
            ubg += [np.full(3 * k, np.inf), np.full(3 * k, np.inf)]
            cost = cost + c.peak_wrench * s
        # a small jerk-like regulariser keeps a feasibility solve from returning wild interior vertices
        cost = cost + 1e-6 * ca.sumsqr(P)
        self.n_extra = len(w_extra)
        self.lbg, self.ubg = np.concatenate(lbg), np.concatenate(ubg)
        self.lbw = np.concatenate([np.full(self.n_params, -np.inf), lbw_extra])
        self.ubw = np.concatenate([np.full(self.n_params, np.inf), ubw_extra])
        self.n_box = 2 * k * n
        self.n_dist = k * n_d
        self.outputs = ca.Function("stabilization_outputs", [P, par], [M_all, F_all, ca.vertcat(*dists)])
        nlp = {"x": ca.vertcat(P, *w_extra), "p": par, "f": cost, "g": ca.vertcat(*g)}
        # with nothing to optimise, the first iterate inside every constraint is the answer; the same callback
        # enforces an iteration budget when the caller gives one
        self.feasibility_only = c.attitude_disturbance == 0 and c.peak_wrench == 0
        self.stop = FeasibilityStop("stabilization_stop", self.n_params + self.n_extra, len(self.lbg), par.numel(),
                                    slice(0, 0), 0.0, STOP_CONSTRAINT_TOL)
        self.solver = ipopt_solver("stabilization", nlp, {"iteration_callback": self.stop} | ipopt_options(sc.solver))
        self.build_time_s = time.perf_counter() - t_build

    def initial_params(self, grasp: GraspState) -> Array:
        """Eq. 24 parameters of a smooth deceleration ``q̇(t) = q̇_in (1 − smoothstep(t/T_d))``.

        T_d ≤ t_f³ is short enough that no joint travels past 80 % of its remaining room to the limit
        (each joint moves q̇_in·T_d/2 while decelerating); the NLP then reshapes the profile.
        """
        T = self.spline.duration_s
        rob = self.scenario.robot
        room = np.where(grasp.qd > 0, rob.q_max - grasp.q, grasp.q - rob.q_min)
        with np.errstate(divide="ignore"):
            limits = np.where(np.abs(grasp.qd) > 1e-9, 2 * 0.8 * np.maximum(room, 0.0) / np.abs(grasp.qd), np.inf)
        T_d = float(np.clip(limits.min(), 0.2 * T, T))
        times = np.linspace(0.0, T, 4 * self.spline.n_vertices)
        s = np.minimum(times / T_d, 1.0)
        # ∫₀ˢ (1 − smoothstep5) ds, closed form, times T_d
        integral = s - (2.5 * s**4 - 3 * s**5 + s**6)
        q_path = grasp.q + np.outer(integral * T_d, grasp.qd)
        W = self.spline.weights(times)
        m = self.spline.n_free_per_joint
        n = len(grasp.q)
        offset = stabilization_vertices(self.spline, grasp.q, grasp.qd, grasp.qdd, np.zeros(m * n))
        G = np.stack([stabilization_vertices(self.spline, np.zeros(1), np.zeros(1), np.zeros(1), np.eye(m)[j]).ravel()
                      for j in range(m)], axis=1)
        P, *_ = np.linalg.lstsq(W @ G, q_path - W @ offset, rcond=None)
        return P.reshape(-1)

    def solve(self, grasp: GraspState, warm_params: Array | None = None,
              max_iterations: int | None = None) -> StabilizationSolution:
        """Solve for ``grasp``, from ``warm_params`` or, cold, by way of the coarse problem.

        A cold start first solves the coarse NLP (``coarse_via_points`` via points; per iteration about a
        third of the cost) from :meth:`initial_params` and starts the full NLP from its answer, which sits
        near the full NLP's feasible set; should that solve fail, the full NLP is solved from
        :meth:`initial_params` as well, so a cold solve never does worse than the full NLP alone. The
        returned times and iteration counts cover every solve made. ``max_iterations`` (None: only the
        scenario's per-NLP ``max_iter``) bounds the IPOPT iterations of all those solves together; a solve
        that spends it ends unsuccessful with status ``Iteration_Budget_Exhausted``.
        """
        if warm_params is not None or self.coarse_via_points == 0:
            return self._solve(grasp, warm_params, max_iterations)
        coarse = self.coarse_problem()
        attempts = [coarse._solve(grasp, None, max_iterations)]
        for start in (attempts[0].params, None):
            left = None if max_iterations is None else max_iterations - sum(a.iterations for a in attempts)
            if left is not None and left <= 0:
                break
            attempts.append(self._solve(grasp, start, left))
            if attempts[-1].success:
                break
        last = attempts[-1]
        return replace(last, iterations=sum(a.iterations for a in attempts),
                       solve_time_s=sum(a.solve_time_s for a in attempts),
                       build_time_s=self.build_time_s + coarse.build_time_s)

    def coarse_problem(self) -> StabilizationProblem:
        """The same NLP with ``coarse_via_points`` uniform via points and RK4 steps (built on first use)."""
        if self._coarse is None:
            st = replace(self.scenario.stabilization, via_points=self.coarse_via_points,
                         rk4_steps=self.coarse_via_points, coarse_via_points=0)
            self._coarse = StabilizationProblem(replace(self.scenario, stabilization=st), self.torque_limit_nm,
                                                self.functions)
        return self._coarse

    def parameters(self, grasp: GraspState) -> Array:
        """The NLP's parameter vector for ``grasp``: its state, momentum and geometry."""
        return np.concatenate([grasp.q, grasp.qd, grasp.qdd, grasp.x_base, grasp.h_world,
                               grasp_geometry(self.scenario, grasp.T_ee_target)])

    def _solve(self, grasp: GraspState, warm_params: Array | None,
               max_iterations: int | None = None) -> StabilizationSolution:
        par = self.parameters(grasp)
        w0 = self.initial_params(grasp) if warm_params is None else np.asarray(warm_params, dtype=float)
        if self.n_extra:
            M0, _, _ = self.outputs(w0, par)
            w0 = np.concatenate([w0, [float(np.abs(np.asarray(M0)).max())]])
        self.stop.arm(self.lbg, self.ubg, self.feasibility_only, max_iterations)
        t0 = time.perf_counter()
        sol = self.solver(x0=w0, p=par, lbx=self.lbw, ubx=self.ubw, lbg=self.lbg, ubg=self.ubg)
        elapsed = time.perf_counter() - t0
        stats = self.solver.stats()
        P = np.asarray(sol["x"]).ravel()[: self.n_params]
        M, _, d = (np.asarray(a).ravel() for a in self.outputs(P, par))
        success, status = bool(stats["success"]), str(stats["return_status"])
        if self.stop.stopped:
            success, status = True, "Feasible_Point_Found"
        elif self.stop.budget_exhausted:
            success, status = False, "Iteration_Budget_Exhausted"
        return StabilizationSolution(P, success, status, int(stats["iter_count"]),
                                     elapsed, self.build_time_s, float(sol["f"]), float(np.abs(M).max()),
                                     float(d.min()))
