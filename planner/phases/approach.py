"""Phase 1, the robot approach: the NLP of one scenario, built once (paper Eq. 2-6, 14-21, 23).

Decision variables ``w = [P (7·(N−5)), θ_b(0) (x, z), τ, Q_tr]``: the B-spline parameters of Eq. 23, the base
offset in the orbital plane (Eq. 16), the start delay τ along the target trajectory (the planner picks when
to meet; the approach runs on [τ, τ + t_f¹] after the observation) and the configurations at the tracking
nodes. NLP parameters: the observed target state (attitude quaternion, body rates), so one symbolic problem
serves every grid point. Constraints, in order: the pre-grasp pose at t_f¹ (Eq. 20-21), the grasp frame at the
tracking nodes, joint positions (Eq. 17, 8) and velocities (Eq. 18), the rates between tracking nodes and at
the grasp, signed distance ≥ margin for every collision pair (Eq. 19), the gripper's clearance during the
tracking blend. Derivatives are exact (CasADi AD; witness points for distances); collision callbacks have no
second derivatives, so IPOPT runs with a limited-memory Hessian. See docs/phases.md, Approach. Solving it is
:func:`planner.phases.approach_solve.solve_approach`.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import SceneDistanceCallback
from planner.collision.contact_rule import APPROACH, TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import TARGET_BODY, scene_layout
from planner.collision.nlp_scene import build_scene
from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import fk_function
from planner.model.singular_joints import singular_angles
from planner.model.target_state import TargetState
from planner.nlp import constraint_backoff as backoff
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.costs import manipulability_sym
from planner.nlp.feasibility_stop import FeasibilityStop
from planner.nlp.ipopt import ipopt_options, ipopt_solver
from planner.nlp.layout import VectorLayout
from planner.nlp.outcome import SolveOutcome
from planner.phases import approach_constraints as family
from planner.phases.approach_guess import TRACKING_SPEED_MARGIN
from planner.phases.approach_motion import ChaserPath, TargetPath, chaser_path, target_path
from planner.phases.tracking_profile import TRACKING_NODES
from planner.plan_parameters import ApproachParameters

Array = NDArray[np.float64]

STOPPING_FRACTION = 0.15  # the stabilization guess stops the joints within this fraction of t_f³
# the tracking law's joint rates at the grasp within this fraction of the limits (as on the last node step,
# TRACKING_SPEED_MARGIN): the rate model leaves out two small null-space terms
GRASP_RATE_FRACTION = 0.8
BLEND_CHECK_NODES = family.BLEND_CHECK_NODES


@dataclass(frozen=True)
class ApproachSolution:
    """Result of the approach NLP (its parameters in :class:`ApproachParameters`' units)."""

    params: Array  # (7·(N−5),) Eq. 23 free parameters, planner.nlp.phase_spline layout [rad, rad/s³]
    base_offset_m: Array  # (2,) θ_b(0) in the orbital plane: (x, z) [m]
    start_delay_s: float  # [s]
    q_tracking: Array  # (3, 7) configurations at the tracking nodes [rad]
    success: bool
    status: SolveOutcome
    iterations: int
    solve_time_s: float
    cost: float
    min_distance_m: float  # at the via points and tracking nodes, over the pairs held to the full margin [m]
    # index of the scanned initial guess (approach_guess.initial_guesses, best first) this solution descends
    # from; -1 when it started from a warm start
    start_guess: int = -1

    @property
    def parameters(self) -> ApproachParameters:
        """The decision parameters alone (what a warm start or a table needs)."""
        return ApproachParameters(self.params, self.base_offset_m, self.start_delay_s, self.q_tracking)

    @classmethod
    def given(cls, parameters: ApproachParameters) -> ApproachSolution:
        """Given parameters used as they are, without a solve (status ``"given"``, no cost or clearance)."""
        return cls(parameters.params, parameters.base_offset_m, parameters.start_delay_s, parameters.q_tracking,
                   success=True, status=SolveOutcome.GIVEN, iterations=0, solve_time_s=0.0, cost=float("nan"),
                   min_distance_m=float("nan"))


def approach_spline(scenario: Scenario) -> UniformCubicBSpline:
    """The approach's joint B-spline: ``n_vertices`` over t_f¹ (paper Eq. 22-23)."""
    return UniformCubicBSpline(scenario.approach.n_vertices, scenario.phases.approach_s)


class ApproachProblem:
    """The approach NLP of one scenario, built once and solved for many target states.

    The tracking phase's constraints enter the NLP (paper §4.2) through three configuration variables
    ``Q_tr`` at the tracking nodes (fractions :data:`TRACKING_NODES` of t_f²): the end-effector on the
    moving grasp frame (with the closing back-off), joint boxes, collision, and joint-velocity bounds on
    the steps between nodes; the base drift along that path is integrated too. At the grasp node the
    tracking law's joint rates are bounded, and the joints must have room to stop from them (the
    stabilization starts there). The tracking IK then resolves its redundancy toward these
    configurations (null-space reference). The problem holds only what the scenario fixed.
    """

    def __init__(self, scenario: Scenario, ff: FreeFloatingModel | None = None) -> None:
        self.scenario = sc = scenario
        self.robot = sc.robot
        self.ff = ff or FreeFloatingModel(sc.robot, compile_rk4=True)
        self.spline = approach_spline(sc)
        self.k = k = sc.approach.via_points
        self.m_steps = k * int(np.ceil(sc.approach.rk4_steps / k))  # via points sit on RK4 nodes
        self.n_params = self.robot.n_joints * self.spline.n_free_per_joint
        self.tracking_times_s = [f * sc.phases.tracking_s for f in TRACKING_NODES]
        self.singular_angles = singular_angles(sc.robot)
        self.decision = self._decision_layout()
        self.n_w = self.decision.size
        self.parameter_layout = VectorLayout()
        self.parameter_layout.add("attitude_wxyz", 4)
        self.parameter_layout.add("omega_body_rad_s", 3)
        # an MX graph over small SX Functions: fast to build
        w = ca.MX.sym("w", self.n_w)
        p = ca.MX.sym("p", self.parameter_layout.size)
        self.constraints = VectorLayout()
        cost, extra_w = self._build(w, p)
        self.n_extra = len(extra_w)
        self.lbw, self.ubw = self.decision.lower, self.decision.upper
        self.lbg, self.ubg = self.constraints.lower, self.constraints.upper
        self._nlp = {"x": ca.vertcat(w, *extra_w), "p": p, "f": cost, "g": self.constraints.expression()}
        # an optional iteration budget per solve (the planner gives its retries from later guesses one); the
        # callback only counts, it never changes an iterate
        self.budget = FeasibilityStop("approach_budget", self.n_w + self.n_extra, len(self.lbg),
                                      self.parameter_layout.size, slice(0, 0), 0.0, 0.0)
        self._options = ipopt_options(sc.solver) | {"iteration_callback": self.budget}
        self._solver: ca.Function | None = None
        self._cold_solver: ca.Function | None = None
        self._objective: ca.Function | None = None
        dist_bounds = self.lbg[self.constraints.slice("collision")]
        self.held_to_margin = dist_bounds == dist_bounds.max()  # the gripper-handle pair closing in: not held

    def objective_at(self, w: Array, state: TargetState) -> float:
        """The NLP's weighted cost (Eq. 14-16) at the decision vector ``w`` (without the distance slack) for the
        observed ``state``; the slack of Eq. 15, when weighted, at its best value (the smallest scaled distance)."""
        if self._objective is None:
            self._objective = ca.Function("approach_objective", [self._nlp["x"], self._nlp["p"]],
                                          [self._nlp["f"], self._nlp["g"]])
        p = self.parameter_layout.pack({"attitude_wxyz": state.attitude_wxyz,
                                        "omega_body_rad_s": state.omega_body_rad_s})
        x = np.concatenate([w, np.zeros(self.n_extra)])
        if self.n_extra:  # with s = 0 the scaled-distance rows are the scaled distances themselves
            scaled = np.asarray(self._objective(x, p)[1]).ravel()[self.constraints.slice("scaled_distance")]
            x[-1] = np.clip(scaled.min(), self.lbw[-1], self.ubw[-1])
        return float(self._objective(x, p)[0])

    def _decision_layout(self) -> VectorLayout:
        """``w``'s blocks and bounds (the optional distance slack is added by the cost)."""
        sc, rob = self.scenario, self.robot
        (bx, bz) = sc.base_offset_bounds_m
        w = VectorLayout()
        w.add("spline_params", self.n_params)
        w.add("base_offset_m", 2, [bx[0], bz[0]], [bx[1], bz[1]])
        w.add("start_delay_s", 1, *sc.phases.start_delay_window_s)
        w.add("tracking_nodes", len(TRACKING_NODES) * rob.n_joints, np.tile(rob.q_min, len(TRACKING_NODES)),
              np.tile(rob.q_max, len(TRACKING_NODES)))
        return w

    def _build(self, w: ca.MX, p: ca.MX) -> tuple[ca.MX, list[ca.MX]]:
        """Every constraint family into :attr:`constraints`, in order; ``(cost, extra decision variables)``."""
        n, d, par = self.robot.n_joints, self.decision, self.parameter_layout
        base_offset = w[d.slice("base_offset_m")]
        nodes = d.slice("tracking_nodes").start
        Q_tr = [w[nodes + j * n: nodes + (j + 1) * n] for j in range(len(TRACKING_NODES))]
        chaser = chaser_path(self.scenario, self.ff, self.spline, self.m_steps, w[d.slice("spline_params")],
                             base_offset, Q_tr, self.tracking_times_s)
        target = target_path(self.scenario, p[par.slice("attitude_wxyz")], p[par.slice("omega_body_rad_s")],
                             w[d.slice("start_delay_s").start], self.k, self.tracking_times_s)
        poses = family.ScenePoses(self.robot, fk_function(self.robot), ca.DM(self.scenario.target.p_world_com))
        via_idx = [self.m_steps // self.k * (j + 1) for j in range(self.k)]
        via_poses = [poses(chaser.xs[i], chaser.Qn[i, :].T, target.R_via[j])[0] for j, i in enumerate(via_idx)]
        R_ee, p_ee, R_free, tr_poses = self._add_poses(poses, chaser, target, Q_tr)
        self._add_joint_limits(chaser, target, Q_tr, via_idx)
        manip = manipulability_sym(self.ff.gen_jacobian(chaser.q_end)[0])
        c = self.scenario.costs
        all_poses = [*via_poses, *tr_poses]
        self._add_collision(all_poses)
        self._add_blend_clearance(target, R_ee, p_ee, R_free)
        cost = c.approach_energy * ca.sumsqr(base_offset) - c.manipulability * manip
        return self._add_distance_slack(cost, all_poses)

    def _add_poses(self, poses: family.ScenePoses, chaser: ChaserPath, target: TargetPath,
                   Q_tr: list[ca.MX]) -> tuple[ca.MX, ca.MX, ca.MX, list[ca.MX]]:
        """The pre-grasp pose at t_f¹ (Eq. 20-21) and the grasp frame at the tracking nodes (equalities)."""
        _, R_ee, p_ee = poses(chaser.xs[-1], chaser.q_end, target.R_via[-1])
        pos_err, rot_err, R_free = family.pregrasp_error(self.scenario, R_ee, p_ee, target.R_via[-1], poses.com)
        tr_err, tr_poses = family.tracking_node_errors(self.scenario, poses, chaser.x_tracking, Q_tr,
                                                       target.R_tracking, self.tracking_times_s, R_free)
        g = self.constraints
        g.add_expression("pregrasp_position", pos_err, 0.0, 0.0)
        g.add_expression("pregrasp_orientation", rot_err, 0.0, 0.0)
        g.add_expression("tracking_poses", tr_err, 0.0, 0.0)
        return R_ee, p_ee, R_free, tr_poses

    def _add_joint_limits(self, chaser: ChaserPath, target: TargetPath, Q_tr: list[ca.MX], via_idx: list[int]) -> None:
        """Joint boxes at the via points, tracking nodes and stopping point (Eq. 17, 8), rates (Eq. 18) at the via
        points, or with Eq. 14-15 weighted at every RK4 node (:meth:`_rate_nodes`).

        Stopping room for the stabilization: decelerating from the grasp rates over STOPPING_FRACTION·t_f³
        moves a joint by q̇·STOPPING_FRACTION·t_f³/2, which must stay inside the limits. The rates are the
        tracking law's at the grasp, not the finite difference between the last two nodes: near the elbow
        singularity the IK's rates grow like 1/sin(q4) in the last fraction of a second.
        """
        rob, t_tr = self.robot, self.tracking_times_s
        qd_nodes = (Q_tr[-1] - Q_tr[-2]) / (t_tr[-1] - t_tr[-2])
        qd_grasp = family.grasp_joint_rates(self.ff, chaser.x_tracking[-1], Q_tr[-1], qd_nodes, target.R_tracking[-1],
                                            target.omega_grasp, self.scenario.target.grasp.T_body_grasp)
        q_stop = Q_tr[-1] + qd_grasp * (STOPPING_FRACTION * self.scenario.phases.stabilization_s / 2)
        q_box = ca.vertcat(*[chaser.Qn[i, :].T for i in via_idx], *Q_tr, q_stop)
        rate_idx = self._rate_nodes(via_idx)
        # when the joint-rate rows hold [s since the approach's start]: what planner.phases.approach_rates reads between
        self.rate_times_s = np.asarray(rate_idx, dtype=float) * self.scenario.phases.approach_s / self.m_steps
        qd_box = ca.vertcat(*[chaser.Qdn[i, :].T for i in rate_idx])
        q_steps = [chaser.q_end, *Q_tr]
        qd_steps = ca.vertcat(*[(q_steps[j + 1] - q_steps[j]) / (t_tr[j] - (t_tr[j - 1] if j else 0.0))
                                for j in range(len(TRACKING_NODES))])
        n_q_box = self.k + len(TRACKING_NODES) + 1
        qd_lim = backoff.JOINT_VELOCITY_FRACTION * rob.qd_max
        step_lim = np.concatenate([f * rob.qd_max for f in TRACKING_SPEED_MARGIN])
        g = self.constraints
        g.add_expression("joint_positions", q_box, np.tile(rob.q_min + backoff.JOINT_POSITION_RAD, n_q_box),
                         np.tile(rob.q_max - backoff.JOINT_POSITION_RAD, n_q_box))
        g.add_expression("joint_velocities", qd_box, np.tile(-qd_lim, len(rate_idx)), np.tile(qd_lim, len(rate_idx)))
        g.add_expression("tracking_rates", qd_steps,
                         np.concatenate([-f * rob.qd_max for f in TRACKING_SPEED_MARGIN]), step_lim)
        g.add_expression("grasp_rates", qd_grasp, -GRASP_RATE_FRACTION * rob.qd_max, GRASP_RATE_FRACTION * rob.qd_max)

    def _rate_nodes(self, via_idx: list[int]) -> list[int]:
        """The RK4 nodes whose joint rates are bounded: the via points, or, when the cost weighs the arm's motion (Eq.
        14-15), every node between the approach's ends (whose rates are 0). Those terms drive the rates onto their
        bounds, and the spline's rates then peak between via points (scenario II's safety descent: 1.029× a limit
        between two 0.5 s apart); Eq. 16 weighs θ_b(0) alone and leaves the rates inside (a scenario II energy plan's
        at 0.88 of the limits at most). The rows are linear in the spline's parameters, so cheap."""
        return list(range(1, self.m_steps)) if self.scenario.costs.weights_arm_motion else via_idx

    def _add_collision(self, all_poses: list[ca.MX]) -> None:
        """Signed distance of every pair at the via points and tracking nodes ≥ its clearance (Eq. 19)."""
        self.scene = build_scene(self.scenario, scale=1.0, gripper_handle=True)
        self.body_order = [*self.robot.body_names, TARGET_BODY]
        self.distance_cb = SceneDistanceCallback("approach_distance", self.scene, self.body_order, len(all_poses))
        self.n_pairs = len(self.scene.pairs)
        self.constraints.add_expression("collision", self.distance_cb(ca.vertcat(*all_poses)),
                                        self._clearance_bounds() + backoff.COLLISION_M, np.inf)

    def _clearance_bounds(self) -> Array:
        """Lower bounds [m] of the distances at the k via points, then at the tracking nodes (contact rule)."""
        sc = self.scenario
        layout = scene_layout(sc.robot, sc.target)
        margin, b0, t2 = sc.limits.collision_margin_m, sc.approach.pregrasp_backoff_m, sc.phases.tracking_s
        parts = [required_clearance_m(self.scene.pairs, layout.gripper_handle, margin, APPROACH)] * self.k
        parts += [required_clearance_m(self.scene.pairs, layout.gripper_handle, margin, TRACKING,
                                       closed_backoff_m(b0, t_node, t2)) for t_node in self.tracking_times_s]
        return np.concatenate(parts)

    def _add_blend_clearance(self, target: TargetPath, R_ee: ca.MX, p_ee: ca.MX, R_free: ca.MX) -> None:
        """The gripper's clearance from the handle while the tracking blends onto the grasp frame."""
        self.blend_cb, dists, bounds = family.blend_clearances(self.scenario, target, R_ee, p_ee, R_free)
        if dists:
            self.constraints.add_expression("blend_clearance", dists[0], bounds + backoff.COLLISION_M, np.inf)
        else:
            self.constraints.add("blend_clearance", 0)

    def _add_distance_slack(self, cost: ca.MX, all_poses: list[ca.MX]) -> tuple[ca.MX, list[ca.MX]]:
        """Eq. 15 on overscaled geometry, when weighted: maximise a slack s below every scaled distance."""
        c = self.scenario.costs
        if c.min_distance <= 0:
            return cost, []
        self.scaled_scene = build_scene(self.scenario, scale=c.overscale)
        self.scaled_cb = SceneDistanceCallback("approach_distance_scaled", self.scaled_scene, self.body_order,
                                               len(all_poses))
        s = ca.MX.sym("s_dist")
        self.decision.add("distance_slack", 1, -10.0, 10.0)
        self.constraints.add_expression("scaled_distance", self.scaled_cb(ca.vertcat(*all_poses)) - s, 0.0, np.inf)
        return cost - c.min_distance * s, [s]

    @property
    def solver(self) -> ca.Function:
        """The NLP's solver for warm starts (a solved neighbour, a re-solve, a costed step). Built on first use:
        building a solver takes ~1 s, and a plan or a query may need only the cold one, or none."""
        if self._solver is None:
            self._solver = ipopt_solver("approach", self._nlp, self._options)
        return self._solver

    @property
    def cold_solver(self) -> ca.Function:
        """The NLP's solver for starts from scanned guesses: IPOPT begins in its restoration phase.

        A guess violates the pre-grasp and tracking constraints by decimetres. From there IPOPT's normal
        phase, with a limited-memory Hessian of a Lagrangian whose multipliers are still meaningless,
        takes steps the filter cuts to 1e-4 and falls into the restoration phase again and again; the
        restoration phase (minimum ℓ1 violation near the start) is what makes progress, so start there.
        Warm starts (a solved neighbour, an interpolated table entry) are near-feasible and keep the normal
        phase. Built on first use.
        """
        if self._cold_solver is None:
            self._cold_solver = ipopt_solver("approach_cold", self._nlp,
                                             self._options | {"ipopt.start_with_resto": "yes"})
        return self._cold_solver
