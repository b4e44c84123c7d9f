"""Phase 3, stabilization: an NLP over the compound chaser + target (paper Eq. 10-13, 24).

At the grasp the target becomes rigidly attached to the gripper (its inertia is added to the last
link); the compound keeps the momentum it had at that instant (h₀ ≠ 0: the target's spin). The joint
B-spline of Eq. 24 starts at the tracking end state: position, velocity, and an acceleration the scenario
chooses — the tracking IK's (our generalisation: the joint motion is C² across the join and the grasp
wrench starts from zero, which a tight grasp-torque limit needs) or zero (the paper's Eq. 24, which
copes with a grasp where the IK is still accelerating hard) — and brings the joint velocities to zero at
t_f³ (Eq. 11). Constraints at k via points: joint boxes (Eq. 12), collision with the target now in the
chain (Eq. 13), and the grasp wrench within its limits (:mod:`planner.phases.stabilization_dynamics`).
Costs: chaser attitude disturbance (Σ‖ω_base‖² at the via points) or peak grasp torque (a slack bounding
every component). With no stabilization cost weight the solve stops at the first iterate inside every
constraint (:mod:`planner.nlp.feasibility_stop`). See docs/phases.md, Stabilization.

The NLP is built once per scenario: where the target was grasped (the compound's last-link inertia, the
wrench's lever arms) enters as parameters (:mod:`planner.model.compound`), so every grasp, at any free-axis
angle, reuses it. It is an MX graph over small SX Functions.
Solving it (coarse to fine) is :func:`planner.phases.stabilization_solve.solve_stabilization`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import SceneDistanceCallback
from planner.collision.layout import TARGET_BODY
from planner.collision.nlp_scene import build_scene
from planner.config.scenario import Scenario
from planner.model.compound import GEOMETRY_SIZE, grasp_geometry
from planner.model.robot import RobotModel
from planner.nlp import constraint_backoff
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.feasibility_stop import FeasibilityStop
from planner.nlp.ipopt import ipopt_options, ipopt_solver
from planner.nlp.layout import VectorLayout
from planner.nlp.outcome import SolveOutcome
from planner.nlp.phase_spline import stabilization_vertices
from planner.phases.stabilization_dynamics import (
    JACOBIAN_FIRST_PENALTY,
    InnerFunctions,
    grasp_momentum_world,
    wrench_function,
)

__all__ = ["JACOBIAN_FIRST_PENALTY", "GraspState", "InnerFunctions", "StabilizationProblem", "StabilizationSolution",
           "grasp_momentum_world", "smooth_stop_params", "stabilization_spline", "via_point_times", "wrench_function"]

Array = NDArray[np.float64]

@dataclass(frozen=True)
class GraspState:
    """The compound's state at the grasp instant (start of stabilization)."""

    q: Array  # (7,) [rad]
    qd: Array  # (7,) [rad/s]
    qdd: Array  # (7,) [rad/s²], the stabilization spline's start acceleration (stabilization.start_acceleration)
    x_base: Array  # (7,) [p_world_base [m], quat_world_base]
    h_world: Array  # (6,) [P [N·s], L_G [N·m·s]] of the compound, world
    T_ee_target: Array  # (4, 4) target body frame in the ee (grasp) frame


@dataclass(frozen=True)
class StabilizationSolution:
    """Result of the stabilization NLP."""

    params: Array  # (7·(N−5),) Eq. 24 free parameters, planner.nlp.phase_spline layout [rad, rad/s³]
    success: bool
    status: SolveOutcome
    iterations: int
    solve_time_s: float
    build_time_s: float
    cost: float
    peak_torque_nm: float  # at the via points, grasp frame, max |component| [N·m]
    min_distance_m: float  # at the via points [m]

    @classmethod
    def given(cls, params: Array) -> StabilizationSolution:
        """Given parameters used as they are, without a solve (status ``"given"``, no torque or clearance)."""
        return cls(params, success=True, status=SolveOutcome.GIVEN, iterations=0, solve_time_s=0.0, build_time_s=0.0,
                   cost=0.0, peak_torque_nm=float("nan"), min_distance_m=float("nan"))



def stabilization_spline(scenario: Scenario) -> UniformCubicBSpline:
    """The joint B-spline of Eq. 24 over t_f³ [s] with the scenario's number of vertices."""
    return UniformCubicBSpline(scenario.stabilization.n_vertices, scenario.phases.stabilization_s)


def via_point_times(spline: UniformCubicBSpline, count: int) -> NDArray[np.float64]:
    """``count`` uniform via points in (0, t_f³] plus every interior knot of the spline [s].

    Within a segment the joint accelerations are linear, so the wrench is smooth; at a knot the jerk
    jumps and the wrench's slope kinks, which is where it peaks between uniform via points. Putting a
    via point on every knot removes that blind spot.
    """
    T = spline.duration_s
    uniform = T * np.arange(1, count + 1) / count
    knots = spline.segment_duration_s * np.arange(1, spline.n_segments)
    return np.unique(np.round(np.concatenate([uniform, knots]), 9))


def smooth_stop_params(spline: UniformCubicBSpline, robot: RobotModel, grasp: GraspState) -> Array:
    """Eq. 24 parameters of a smooth deceleration ``q̇(t) = q̇_in (1 − smoothstep(t/T_d))``.

    T_d ≤ t_f³ is short enough that no joint travels past 80 % of its remaining room to the limit
    (each joint moves q̇_in·T_d/2 while decelerating); the NLP then reshapes the profile.
    """
    T = spline.duration_s
    room = np.where(grasp.qd > 0, robot.q_max - grasp.q, grasp.q - robot.q_min)
    with np.errstate(divide="ignore"):
        limits = np.where(np.abs(grasp.qd) > 1e-9, 2 * 0.8 * np.maximum(room, 0.0) / np.abs(grasp.qd), np.inf)
    T_d = float(np.clip(limits.min(), 0.2 * T, T))
    times = np.linspace(0.0, T, 4 * spline.n_vertices)
    s = np.minimum(times / T_d, 1.0)
    # ∫₀ˢ (1 − smoothstep5) ds, closed form, times T_d
    integral = s - (2.5 * s**4 - 3 * s**5 + s**6)
    q_path = grasp.q + np.outer(integral * T_d, grasp.qd)
    W = spline.weights(times)
    m = spline.n_free_per_joint
    n = len(grasp.q)
    offset = stabilization_vertices(spline, grasp.q, grasp.qd, grasp.qdd, np.zeros(m * n))
    G = np.stack([stabilization_vertices(spline, np.zeros(1), np.zeros(1), np.zeros(1), np.eye(m)[j]).ravel()
                  for j in range(m)], axis=1)
    P, *_ = np.linalg.lstsq(W @ G, q_path - W @ offset, rcond=None)
    return P.reshape(-1)


# The feasibility stop's tolerance on the constraint values: IPOPT's iterates sit on the boundary of
# active constraints only to ~1e-6 before mu is small; the back-offs (planner.nlp.constraint_backoff)
# are 1e4 times larger, so this changes nothing dense verification can see.
STOP_CONSTRAINT_TOL = 1e-6



@dataclass(frozen=True)
class _AtViaPoints:
    """The stabilization's symbolic quantities at its via points, each stacked over the k via points."""

    q: ca.MX  # (7k,) joint positions [rad]
    qd: ca.MX  # (7k,) joint rates [rad/s]
    torques: ca.MX  # (3k,) grasp moment, grasp frame [N·m]
    forces: ca.MX  # (3k,) grasp force, grasp frame [N]
    omegas_base: list[ca.MX]  # k × (3,) base angular velocity [rad/s]
    poses: list[ca.MX]  # k stacked body poses (chaser bodies, then the grasped target)


# the torque and clearance between via points are checked at this many times as many instants
# (planner.phases.between_via_points)
DENSE_FACTOR = 4


class StabilizationProblem:
    """The stabilization NLP of a scenario; a solve takes the grasp state and its geometry as parameters.

    Decision variables: the Eq. 24 parameters (and, with a peak-wrench cost, a torque slack). Parameters
    (:attr:`parameter_layout`): the grasp state, the compound's momentum and the grasp geometry. Constraints
    (:attr:`constraints`), at the via points: joint positions and rates, collision, grasp torque and force.
    """

    def __init__(self, scenario: Scenario, torque_limit_nm: float | None = None,
                 functions: InnerFunctions | None = None) -> None:
        t_build = time.perf_counter()
        self.scenario = sc = scenario
        self.spline = stabilization_spline(sc)
        self.via_times_s = via_point_times(self.spline, sc.stabilization.via_points)
        self.k = len(self.via_times_s)
        self.n_params = sc.robot.n_joints * self.spline.n_free_per_joint
        self.torque_limit_nm = torque_limit_nm
        self.coarse_via_points = sc.stabilization.coarse_via_points
        self._coarse: StabilizationProblem | None = None
        self._dense: tuple[ca.Function, SceneDistanceCallback] | None = None
        self.parameter_layout = self._parameter_layout()
        P = ca.MX.sym("P", self.n_params)
        par = ca.MX.sym("par", self.parameter_layout.size)
        self.functions = functions or InnerFunctions.of(sc.robot)
        via = self.at_times(P, par, self.via_times_s)
        self.decision = VectorLayout()
        self.decision.add("spline_params", self.n_params)
        self.constraints = VectorLayout()
        cost, w_extra = self._add_constraints(via, P)
        self.n_extra = len(w_extra)
        self.lbg, self.ubg = self.constraints.lower, self.constraints.upper
        self.lbw, self.ubw = self.decision.lower, self.decision.upper
        self.outputs = ca.Function("stabilization_outputs", [P, par], [via.torques, via.forces, self._distances])
        nlp = {"x": ca.vertcat(P, *w_extra), "p": par, "f": cost, "g": self.constraints.expression()}
        # with nothing to optimise, the first iterate inside every constraint is the answer; the same callback
        # enforces an iteration budget when the caller gives one
        c = sc.costs
        self.feasibility_only = c.attitude_disturbance == 0 and c.peak_wrench == 0
        self.stop = FeasibilityStop("stabilization_stop", self.n_params + self.n_extra, len(self.lbg), par.numel(),
                                    slice(0, 0), 0.0, STOP_CONSTRAINT_TOL)
        self.solver = ipopt_solver("stabilization", nlp, {"iteration_callback": self.stop} | ipopt_options(sc.solver))
        self.build_time_s = time.perf_counter() - t_build

    def _parameter_layout(self) -> VectorLayout:
        """``p``: the grasp state, the compound's momentum and the grasp geometry (see :meth:`parameters`)."""
        n = self.scenario.robot.n_joints
        layout = VectorLayout()
        for name, size in (("q", n), ("qd", n), ("qdd", n), ("x_base", 7), ("h_world", 6),
                           ("geometry", GEOMETRY_SIZE)):
            layout.add(name, size)
        return layout

    def at_times(self, P: ca.MX, par: ca.MX, via_times_s: NDArray[np.float64], with_poses: bool = True) -> _AtViaPoints:
        """Eq. 24's joints from ``P``, the compound's base by RK4, and what the constraints need at ``via_times_s``
        [s into the phase] (the NLP's via points, or a denser set to check between them; ``with_poses`` False leaves
        the bodies' poses out)."""
        sc, fn, lay = self.scenario, self.functions, self.parameter_layout
        T = sc.phases.stabilization_s
        x, h, geo_vec = par[lay.slice("x_base")], par[lay.slice("h_world")], par[lay.slice("geometry")]
        V = stabilization_vertices(self.spline, par[lay.slice("q")], par[lay.slice("qd")], par[lay.slice("qdd")], P)
        # RK4 nodes: a uniform grid refined so that every via point is a node (steps may differ)
        nodes = np.unique(np.round(np.concatenate([np.linspace(0.0, T, sc.stabilization.rk4_steps + 1),
                                                   via_times_s]), 9))
        mids = 0.5 * (nodes[:-1] + nodes[1:])
        Qn, Qdn, Qddn = (self.spline.evaluate(V, nodes, d) for d in (0, 1, 2))
        Qm, Qdm = (self.spline.evaluate(V, mids, d) for d in (0, 1))
        xs = [x]
        for i in range(len(nodes) - 1):
            x = fn.rk4_step(x, Qn[i, :].T, Qdn[i, :].T, Qm[i, :].T, Qdm[i, :].T, Qn[i + 1, :].T, Qdn[i + 1, :].T,
                            h, nodes[i + 1] - nodes[i], geo_vec)
            xs.append(x)
        via_idx = [int(np.argmin(np.abs(nodes - tv))) for tv in via_times_s]
        forces, torques, omegas, poses = [], [], [], []
        for i in via_idx:
            F, M, w_b, R_ee, p_ee = fn.wrench(xs[i], Qn[i, :].T, Qdn[i, :].T, Qddn[i, :].T, h, geo_vec)
            forces.append(F)
            torques.append(M)
            omegas.append(w_b)
            if not with_poses:
                continue
            poses.append(fn.poses(xs[i], Qn[i, :].T, R_ee, p_ee, geo_vec))
        return _AtViaPoints(ca.vertcat(*[Qn[i, :].T for i in via_idx]), ca.vertcat(*[Qdn[i, :].T for i in via_idx]),
                            ca.vertcat(*torques), ca.vertcat(*forces), omegas, poses)

    def _add_constraints(self, via: _AtViaPoints, P: ca.MX) -> tuple[ca.MX, list[ca.MX]]:
        """Joint boxes (Eq. 12), collision (Eq. 13) and the grasp wrench, in order; ``(cost, extra variables)``."""
        sc, robot, k, bo = self.scenario, self.scenario.robot, self.k, constraint_backoff
        self.scene = build_scene(sc)
        self.distance_cb = SceneDistanceCallback("stabilization_distance", self.scene,
                                                 [*robot.body_names, TARGET_BODY], len(via.poses))
        self._distances = self.distance_cb(ca.vertcat(*via.poses))
        tl = bo.WRENCH_FRACTION * (self.torque_limit if np.isfinite(self.torque_limit) else np.inf)
        fl = bo.WRENCH_FRACTION * (sc.limits.grasp_force_max_n if np.isfinite(sc.limits.grasp_force_max_n) else np.inf)
        qd_lim = bo.JOINT_VELOCITY_FRACTION * robot.qd_max
        g = self.constraints
        g.add_expression("joint_positions", via.q, np.tile(robot.q_min + bo.JOINT_POSITION_RAD, k),
                         np.tile(robot.q_max - bo.JOINT_POSITION_RAD, k))
        g.add_expression("joint_velocities", via.qd, np.tile(-qd_lim, k), np.tile(qd_lim, k))
        g.add_expression("collision", self._distances, sc.limits.collision_margin_m + bo.COLLISION_M, np.inf)
        g.add_expression("grasp_torque", via.torques, -tl, tl)
        g.add_expression("grasp_force", via.forces, -fl, fl)
        c = sc.costs
        cost = c.attitude_disturbance * (sum(ca.sumsqr(w) for w in via.omegas_base) / k)
        w_extra = []
        if c.peak_wrench > 0:
            s = ca.MX.sym("s_torque")
            w_extra.append(s)
            self.decision.add("torque_slack", 1, 0.0, np.inf)
            g.add_expression("torque_slack_above", s - via.torques, 0.0, np.inf)
            g.add_expression("torque_slack_below", s + via.torques, 0.0, np.inf)
            cost = cost + c.peak_wrench * s
        # a small jerk-like regulariser keeps a feasibility solve from returning wild interior vertices
        return cost + 1e-6 * ca.sumsqr(P), w_extra

    def initial_params(self, grasp: GraspState) -> Array:
        """:func:`smooth_stop_params` of this problem's spline: the heuristic start of a cold solve."""
        return smooth_stop_params(self.spline, self.scenario.robot, grasp)

    def coarse_problem(self) -> StabilizationProblem:
        """The same NLP with ``coarse_via_points`` uniform via points and RK4 steps (built on first use)."""
        if self._coarse is None:
            st = replace(self.scenario.stabilization, via_points=self.coarse_via_points,
                         rk4_steps=self.coarse_via_points, coarse_via_points=0)
            self._coarse = StabilizationProblem(replace(self.scenario, stabilization=st), self.torque_limit_nm,
                                                self.functions)
        return self._coarse

    @property
    def torque_limit(self) -> float:
        """The grasp torque limit this problem holds [N·m] (per component; inf: none)."""
        return self.scenario.limits.grasp_torque_max_nm if self.torque_limit_nm is None else self.torque_limit_nm

    def dense_samples(self) -> ca.Function:
        """``(P, par) -> (torques (3·m,) [N·m, grasp frame], distances (n_pairs·m,) [m], point-major)`` at
        :attr:`dense_times_s` (the via points among them): the NLP's own model and collision engine between its via
        points, from one integration of the base (built on first use)."""
        if self._dense is None:
            P = ca.MX.sym("P", self.n_params)
            par = ca.MX.sym("par", self.parameter_layout.size)
            at = self.at_times(P, par, self.dense_times_s)
            callback = SceneDistanceCallback("stabilization_dense_distance", self.scene,
                                             [*self.scenario.robot.body_names, TARGET_BODY], len(at.poses))
            # the callback object must outlive the Function that calls it
            self._dense = ca.Function("stabilization_dense", [P, par],
                                      [at.torques, callback(ca.vertcat(*at.poses))]), callback
        return self._dense[0]

    @property
    def dense_times_s(self) -> Array:
        """The instants [s into the phase] :meth:`dense_samples` evaluates: DENSE_FACTOR times as many as the via
        points, evenly spaced, and the via points."""
        uniform = np.linspace(0.0, self.scenario.phases.stabilization_s, DENSE_FACTOR * self.k + 1)
        return np.union1d(uniform, self.via_times_s)

    def parameters(self, grasp: GraspState) -> Array:
        """The NLP's parameter vector for ``grasp``: its state, momentum and geometry."""
        return self.parameter_layout.pack({"q": grasp.q, "qd": grasp.qd, "qdd": grasp.qdd, "x_base": grasp.x_base,
                                           "h_world": grasp.h_world,
                                           "geometry": grasp_geometry(self.scenario, grasp.T_ee_target)})
