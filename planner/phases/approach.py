"""Phase 1, the robot approach: an NLP solved by IPOPT through CasADi (paper Eq. 2-6, 14-21, 23).

Decision variables ``w = [P (7·(N−5)), θ_b(0) (x, z), τ]``: the B-spline parameters of Eq. 23, the base
offset in the orbital plane (Eq. 16) and the start delay τ along the target trajectory (the planner
picks when to meet; the approach runs on [τ, τ + t_f¹] after the observation). NLP parameters: the
observed target state (attitude quaternion, body rates), so one symbolic problem serves every grid point.

Constraints: joint position and velocity boxes at k via points (Eq. 17-18; linear in P), signed
distance ≥ margin for every collision pair at the via points (Eq. 19, through
:class:`~planner.collision.callback.SceneDistanceCallback`), and at t_f¹ the end-effector on the
pre-grasp pose — the grasp pose backed off along its z axis (Eq. 20-21; with a free grasp axis a only
the direction of a is matched). The base is unactuated with zero momentum: its pose is integrated by
RK4 inside the NLP (single shooting, paper §4.2). Derivatives are exact: CasADi AD for kinematics and
dynamics, witness points for distances. Collision callbacks have no second derivatives, so IPOPT runs
with a limited-memory Hessian.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import SceneDistanceCallback, pose_vector
from planner.collision.contact_rule import APPROACH, TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import TARGET_BODY, SceneLayout, scene_layout
from planner.collision.nlp_scene import build_collision_scene, build_scene
from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel, quat_to_rotation_sym
from planner.model.robot import fk_function
from planner.model.target import TargetState
from planner.model.target_symbolic import prediction_function
from planner.nlp import constraint_backoff
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.phase_spline import approach_vertices
from planner.nlp.costs import manipulability_sym
from planner.nlp.feasibility_stop import FeasibilityStop
from planner.nlp.ipopt import ipopt_options, ipopt_solver
from planner.phases.approach_guess import TRACKING_SPEED_MARGIN, ApproachGuess, initial_guesses
from planner.phases.tracking_profile import TRACKING_NODES, backoff_m, blend
from planner.plan_parameters import ApproachParameters

Array = NDArray[np.float64]

TARGET_STEPS_PER_S = 1.0  # RK4 steps of the symbolic target prediction per second of delay
TRACKING_RK4_STEPS = 3  # base-drift RK4 steps per tracking-node interval
STOPPING_FRACTION = 0.15  # the stabilization guess stops the joints within this fraction of t_f³
# the tracking law's joint rates at the grasp within this fraction of the limits (as on the last node step,
# TRACKING_SPEED_MARGIN): the rate model leaves out two small null-space terms
GRASP_RATE_FRACTION = 0.8
# fractions of t_f² at which the gripper–handle clearance of the blend onto the moving grasp frame is constrained
BLEND_CHECK_NODES = (0.15, 0.3, 0.45)


@dataclass(frozen=True)
class ApproachSolution:
    """Result of the approach NLP. ``params`` in :mod:`planner.nlp.bspline`'s layout (rad, rad/s³)."""

    params: Array
    base_offset_m: Array  # θ_b(0) in the orbital plane: (x, z)
    start_delay_s: float
    q_tracking: Array  # (3, 7) configurations at the tracking nodes (rad)
    success: bool
    status: str
    iterations: int
    solve_time_s: float
    cost: float
    min_distance_m: float  # at the via points and tracking nodes, over the pairs held to the full margin (m)
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
                   success=True, status="given", iterations=0, solve_time_s=0.0, cost=float("nan"),
                   min_distance_m=float("nan"))


def _free_axis_rotation(M, axis: Array):  # noqa: ANN001, ANN202
    """Rotation about ``axis`` by the angle ψ of M about it (symbolic twin of tracking.free_axis_angle)."""
    e = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e = e - np.dot(e, axis) * axis
    e = e / np.linalg.norm(e)
    Me = ca.mtimes(M, ca.DM(e))
    c = ca.dot(ca.DM(e), Me)
    s = ca.dot(ca.DM(axis), ca.cross(ca.DM(e), Me))
    r = ca.sqrt(c * c + s * s)
    K = ca.DM(np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]))
    return ca.DM.eye(3) + (s / r) * K + (1 - c / r) * ca.mtimes(K, K)


def _vee_skew(M):  # noqa: ANN001, ANN202
    """vee((M − Mᵀ)/2): the sin-scaled rotation-error vector of a relative rotation M."""
    return 0.5 * ca.vertcat(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])


def _ee_to_body(robot, body: str) -> Array:  # noqa: ANN001
    """``T_ee_body`` (4×4): the pose of ``body``'s frame in the ee frame, when both are on the last link."""
    out = fk_function(robot)(np.zeros(robot.n_joints))
    i = list(robot.body_names).index(body)
    T_b_body, T_b_ee = np.eye(4), np.eye(4)
    T_b_body[:3, :3], T_b_body[:3, 3] = np.asarray(out[2 * i]), np.asarray(out[2 * i + 1]).ravel()
    T_b_ee[:3, :3], T_b_ee[:3, 3] = np.asarray(out[-2]), np.asarray(out[-1]).ravel()
    return np.linalg.inv(T_b_ee) @ T_b_body


class ApproachProblem:
    """The approach NLP of one scenario, built once and solved for many target states.

    The tracking phase's constraints enter the NLP (paper §4.2) through three configuration variables
    ``Q_tr`` at the tracking nodes (fractions :data:`TRACKING_NODES` of t_f²): the end-effector on the
    moving grasp frame (with the closing back-off), joint boxes, collision, and joint-velocity bounds on
    the steps between nodes; the base drift along that path is integrated too. At the grasp node the
    tracking law's joint rates are bounded, and the joints must have room to stop from them (the
    stabilization starts there). The tracking IK then resolves its redundancy toward these
    configurations (null-space reference).
    """

    def __init__(self, scenario: Scenario, ff: FreeFloatingModel | None = None) -> None:
        self.scenario = sc = scenario
        self.robot = sc.robot
        self.ff = ff or FreeFloatingModel(sc.robot, compile_rk4=True)
        n = self.robot.n_joints
        st = sc.approach
        tf = sc.phases.approach_s
        t2 = sc.phases.tracking_s
        self.spline = UniformCubicBSpline(st.n_vertices, tf)
        k = st.via_points
        m_steps = k * int(np.ceil(st.rk4_steps / k))  # via points sit on RK4 nodes
        self.k, self.m_steps = k, m_steps
        self.n_params = n * self.spline.n_free_per_joint
        n_tr = len(TRACKING_NODES)
        self.n_w = self.n_params + 3 + n_tr * n
        self.i_b = self.n_params
        self.i_tau = self.n_params + 2
        self.i_tr = self.n_params + 3

        # ---- smooth part: an MX graph over small SX Functions (fast to build, see FINDINGS) -------
        w = ca.MX.sym("w", self.n_w)
        p = ca.MX.sym("p", 7)  # target attitude (4) and body rates (3) at the observation
        P = w[: self.n_params]
        b = w[self.i_b: self.i_b + 2]
        tau = w[self.i_tau]
        Q_tr = [w[self.i_tr + j * n: self.i_tr + (j + 1) * n] for j in range(n_tr)]
        V = approach_vertices(self.spline, ca.DM(sc.q_initial), P)
        nodes = np.linspace(0.0, tf, m_steps + 1)
        mids = 0.5 * (nodes[:-1] + nodes[1:])
        Qn = self.spline.evaluate(V, nodes)
        Qdn = self.spline.evaluate(V, nodes, 1)
        Qm = self.spline.evaluate(V, mids)
        Qdm = self.spline.evaluate(V, mids, 1)
        x = ca.vertcat(b[0], 0.0, b[1], 1.0, 0.0, 0.0, 0.0)
        h0 = ca.DM.zeros(6)
        dt = tf / m_steps
        xs = [x]
        for i in range(m_steps):
            x = self.ff.rk4_step(x, Qn[i, :].T, Qdn[i, :].T, Qm[i, :].T, Qdm[i, :].T, Qn[i + 1, :].T,
                                 Qdn[i + 1, :].T, h0, dt)
            xs.append(x)
        q_end = Qn[-1, :].T
        # base drift along the tracking path, joints moving linearly between the tracking nodes
        tr_times = [f * t2 for f in TRACKING_NODES]
        x_tr, q_prev, t_prev = [], q_end, 0.0
        for j, t_node in enumerate(tr_times):
            h = (t_node - t_prev) / TRACKING_RK4_STEPS
            qd_seg = (Q_tr[j] - q_prev) / (t_node - t_prev)
            for s in range(TRACKING_RK4_STEPS):
                qa = q_prev + qd_seg * (s * h)
                x = self.ff.rk4_step(x, qa, qd_seg, qa + qd_seg * (h / 2), qd_seg, qa + qd_seg * h, qd_seg, h0, h)
            x_tr.append(x)
            q_prev, t_prev = Q_tr[j], t_node

        # target prediction: to τ by ~1 s steps, then along the approach and the tracking nodes
        target = sc.target
        max_delay = max(sc.phases.max_start_delay_s, 1e-3)
        predict_delay = prediction_function(target.inertia_body_kg_m2,
                                            max(4, int(np.ceil(max_delay * TARGET_STEPS_PER_S))))
        predict_step = prediction_function(target.inertia_body_kg_m2, max(2, int(np.ceil(tf / k))))
        att, om = predict_delay(p[:4], p[4:], tau)
        target_R = []
        for _ in range(k):
            att, om = predict_step(att, om, tf / k)
            target_R.append(quat_to_rotation_sym(att))
        att_f, om_f = att, om  # the target at t_f¹, where the tracking starts
        target_R_tr, t_prev = [], 0.0
        for t_node in tr_times:
            att, om = predict_step(att, om, t_node - t_prev)
            target_R_tr.append(quat_to_rotation_sym(att))
            t_prev = t_node
        com = ca.DM(target.p_world_com)

        fk = fk_function(self.robot)

        def scene_poses(x_base, q, R_target):  # noqa: ANN001, ANN202
            R_wb = quat_to_rotation_sym(x_base[3:7])
            out = fk(q)
            blocks = [pose_vector(ca.mtimes(R_wb, out[2 * i]), x_base[:3] + ca.mtimes(R_wb, out[2 * i + 1]))
                      for i in range(len(self.robot.body_names))]
            blocks.append(pose_vector(R_target, com))
            return ca.vertcat(*blocks), ca.mtimes(R_wb, out[-2]), x_base[:3] + ca.mtimes(R_wb, out[-1])

        via_idx = [m_steps // k * (j + 1) for j in range(k)]
        via_poses = [scene_poses(xs[i], Qn[i, :].T, target_R[j])[0] for j, i in enumerate(via_idx)]

        # end-effector on the pre-grasp pose at t_f¹ (the last via point is t_f¹), Eq. 20-21
        T_bg = target.grasp.T_body_grasp
        _, R_ee, p_ee = scene_poses(xs[-1], q_end, target_R[-1])
        R_g = ca.mtimes(target_R[-1], ca.DM(T_bg[:3, :3]))
        p_g = com + ca.mtimes(target_R[-1], ca.DM(T_bg[:3, 3]))
        pos_err = p_ee - (p_g - st.pregrasp_backoff_m * R_g[:, 2])
        free = target.grasp.free_axis
        if free is None:
            rot_err = _vee_skew(ca.mtimes(R_g.T, R_ee))
            R_free = ca.DM.eye(3)
        else:
            # only the free axis direction must match: its components along the two other grasp axes
            others = [e for e in np.eye(3) if abs(e @ free) < 0.5]
            a_ee = ca.mtimes(R_ee, ca.DM(free))
            rot_err = ca.vertcat(*[ca.dot(a_ee, ca.mtimes(R_g, ca.DM(e))) for e in others])
            R_free = _free_axis_rotation(ca.mtimes(R_g.T, R_ee), free)
        # tracking nodes: ee on the grasp frame (angle about a free axis kept), back-off closing
        tr_err, tr_poses = [], []
        for j, t_node in enumerate(tr_times):
            poses_j, R_ee_j, p_ee_j = scene_poses(x_tr[j], Q_tr[j], target_R_tr[j])
            R_G = ca.mtimes(ca.mtimes(target_R_tr[j], ca.DM(T_bg[:3, :3])), R_free)
            p_G = com + ca.mtimes(target_R_tr[j], ca.DM(T_bg[:3, 3]))
            d = backoff_m(st.pregrasp_backoff_m, t_node, t2)
            tr_err += [p_ee_j - (p_G - d * R_G[:, 2]), _vee_skew(ca.mtimes(R_G.T, R_ee_j))]
            tr_poses.append(poses_j)
        # joint boxes at the via points (Eq. 17-18) and at the tracking nodes (Eq. 8)
        # stopping room for the stabilization: decelerating from the grasp rates over STOPPING_FRACTION·t_f³
        # moves a joint by q̇·STOPPING_FRACTION·t_f³/2, which must stay inside the limits. The rates are the
        # tracking law's at the grasp, not the finite difference between the last two nodes: near the
        # elbow singularity the IK's rates grow like 1/sin(q4) in the last fraction of a second (scenario I
        # met its grasp at q4 = 0.05 rad with 1.1 rad/s on joint 1, and no stabilization could start there)
        qd_nodes = (Q_tr[-1] - Q_tr[-2]) / (tr_times[-1] - tr_times[-2])
        qd_grasp = self._grasp_joint_rates(x_tr[-1], Q_tr[-1], qd_nodes, target_R_tr[-1], om, T_bg)
        q_stop = Q_tr[-1] + qd_grasp * (STOPPING_FRACTION * sc.phases.stabilization_s / 2)
        q_box = ca.vertcat(*[Qn[i, :].T for i in via_idx], *Q_tr, q_stop)
        qd_box = ca.vertcat(*[Qdn[i, :].T for i in via_idx])
        q_steps = [q_end, *Q_tr]
        qd_steps = ca.vertcat(*[(q_steps[j + 1] - q_steps[j]) / (tr_times[j] - (tr_times[j - 1] if j else 0.0))
                                for j in range(n_tr)])
        # costs (Eq. 14-16)
        manip = manipulability_sym(self.ff.gen_jacobian(q_end)[0])
        energy = ca.sumsqr(b)
        self.pose_size = via_poses[0].numel()

        # ---- NLP: smooth part + collision callbacks ----------------------------------------------
        self.scene = build_scene(sc, scale=1.0, gripper_handle=True)
        body_order = [*self.robot.body_names, TARGET_BODY]
        all_poses = [*via_poses, *tr_poses]
        self.distance_cb = SceneDistanceCallback("approach_distance", self.scene, body_order, len(all_poses))
        dists = [self.distance_cb(ca.vertcat(*all_poses))]
        c = sc.costs
        cost = c.approach_energy * energy - c.manipulability * manip
        rob = self.robot
        n_d = len(self.scene.pairs)
        n_q_box = k + n_tr + 1
        tr_err_v = ca.vertcat(*tr_err)
        blend_dists, blend_bounds = self._blend_clearances(predict_step, att_f, om_f, R_ee, p_ee, R_free)
        g_parts = [pos_err, rot_err, tr_err_v, q_box, qd_box, qd_steps, qd_grasp, *dists, *blend_dists]
        bo = constraint_backoff
        q_lo, q_hi = rob.q_min + bo.JOINT_POSITION_RAD, rob.q_max - bo.JOINT_POSITION_RAD
        qd_lim = bo.JOINT_VELOCITY_FRACTION * rob.qd_max
        lbg = [np.zeros(3), np.zeros(rot_err.numel()), np.zeros(tr_err_v.numel()), np.tile(q_lo, n_q_box),
               np.tile(-qd_lim, k), np.concatenate([-f * rob.qd_max for f in TRACKING_SPEED_MARGIN]),
               -GRASP_RATE_FRACTION * rob.qd_max, self._clearance_bounds(k, tr_times) + bo.COLLISION_M,
               blend_bounds + bo.COLLISION_M]
        ubg = [np.zeros(3), np.zeros(rot_err.numel()), np.zeros(tr_err_v.numel()), np.tile(q_hi, n_q_box),
               np.tile(qd_lim, k), np.concatenate([f * rob.qd_max for f in TRACKING_SPEED_MARGIN]),
               GRASP_RATE_FRACTION * rob.qd_max, np.full(len(all_poses) * n_d, np.inf),
               np.full(len(blend_bounds), np.inf)]
        self.n_before_dist = sum(part.numel() for part in g_parts[:7])
        start = sum(part.numel() for part in g_parts[:5])
        self._rate_slice = slice(start, start + qd_steps.numel())
        self.tracking_speed_scale = 1.0
        extra_w, lbw_extra, ubw_extra = [], [], []
        if c.min_distance > 0:
            # Eq. 15 on overscaled geometry: maximise a slack s below every scaled distance
            self.scaled_scene = build_scene(sc, scale=c.overscale)
            self.scaled_cb = SceneDistanceCallback("approach_distance_scaled", self.scaled_scene, body_order,
                                                   len(all_poses))
            s = ca.MX.sym("s_dist")
            extra_w.append(s)
            lbw_extra.append(-10.0)
            ubw_extra.append(10.0)
            n_scaled = len(self.scaled_scene.pairs) * len(all_poses)
            g_parts.append(self.scaled_cb(ca.vertcat(*all_poses)) - s)
            lbg.append(np.zeros(n_scaled))
            ubg.append(np.full(n_scaled, np.inf))
            cost = cost - c.min_distance * s
        self.n_extra = len(extra_w)
        self.lbg = np.concatenate(lbg)
        self.ubg = np.concatenate(ubg)
        (bx, bz) = sc.base_offset_bounds_m
        self.lbw = np.concatenate([np.full(self.n_params, -np.inf), [bx[0], bz[0], 0.0],
                                   np.tile(rob.q_min, n_tr), lbw_extra])
        self.ubw = np.concatenate([np.full(self.n_params, np.inf), [bx[1], bz[1], sc.phases.max_start_delay_s],
                                   np.tile(rob.q_max, n_tr), ubw_extra])
        self._nlp = {"x": ca.vertcat(w, *extra_w), "p": p, "f": cost, "g": ca.vertcat(*g_parts)}
        # an optional iteration budget per solve (the planner gives its retries from later guesses one); the
        # callback only counts, it never changes an iterate
        self.budget = FeasibilityStop("approach_budget", self.n_w + self.n_extra, len(self.lbg), 7, slice(0, 0), 0.0,
                                      0.0)
        self._options = ipopt_options(sc.solver) | {"iteration_callback": self.budget}
        self.solver = ipopt_solver("approach", self._nlp, self._options)
        self._cold_solver: ca.Function | None = None
        # the last scan of initial guesses, keyed by target state and count: a plan that retries from the
        # next guesses (planner.plan) asks for the same scan again
        self._scan: tuple[tuple[bytes, bytes, int], list[ApproachGuess]] | None = None
        self.n_pairs = n_d
        self.n_dist = len(all_poses) * n_d
        dist_bounds = self.lbg[self.n_before_dist: self.n_before_dist + self.n_dist]
        self._held_to_margin = dist_bounds == dist_bounds.max()  # the gripper-handle pair closing in: not held

    def _blend_clearances(self, predict_step: ca.Function, att, om, R_ee0, p_ee0,  # noqa: ANN001
                          R_free) -> tuple[list, Array]:  # noqa: ANN001
        """Gripper–handle distances at :data:`BLEND_CHECK_NODES` of the tracking, and their lower bounds (m).

        While the tracking IK's desired pose blends from the pre-grasp pose (at rest) onto the moving grasp
        frame, the gripper lags the target; a target moving against the approach axis closes the gap faster
        than the back-off does. The gripper is placed at that desired pose (:mod:`planner.phases.tracking`;
        the rotation blend to second order in its angle, a few degrees here).
        """
        sc = self.scenario
        layout = scene_layout(sc.robot, sc.target)
        if layout.gripper_handle is None:
            return [], np.zeros(0)
        scene = build_collision_scene(SceneLayout(layout.bodies, (layout.gripper_handle,), None, ()))
        gripper = layout.gripper_handle[0]
        self.blend_cb = SceneDistanceCallback("blend_distance", scene, [gripper, TARGET_BODY], len(BLEND_CHECK_NODES))
        T_ee_gripper = _ee_to_body(self.robot, gripper)
        T_bg, com = sc.target.grasp.T_body_grasp, ca.DM(sc.target.p_world_com)
        b0, t2, margin = sc.approach.pregrasp_backoff_m, sc.phases.tracking_s, sc.limits.collision_margin_m
        poses, bounds, t_prev = [], [], 0.0
        for frac in BLEND_CHECK_NODES:
            t = frac * t2
            att, om = predict_step(att, om, t - t_prev)
            t_prev = t
            R_t = quat_to_rotation_sym(att)
            R_G = ca.mtimes(ca.mtimes(R_t, ca.DM(T_bg[:3, :3])), R_free)
            p_G = com + ca.mtimes(R_t, ca.DM(T_bg[:3, 3]))
            s = blend(t, t2)
            p_des = (1 - s) * p_ee0 + s * (p_G - backoff_m(b0, t, t2) * R_G[:, 2])
            phi = ca.skew(s * _vee_skew(ca.mtimes(R_ee0.T, R_G)))
            R_des = ca.mtimes(R_ee0, ca.DM.eye(3) + phi + 0.5 * ca.mtimes(phi, phi))
            R_grip = ca.mtimes(R_des, ca.DM(T_ee_gripper[:3, :3]))
            p_grip = p_des + ca.mtimes(R_des, ca.DM(T_ee_gripper[:3, 3]))
            poses.append(ca.vertcat(pose_vector(R_grip, p_grip), pose_vector(R_t, com)))
            bounds.append(required_clearance_m([layout.gripper_handle], layout.gripper_handle, margin, TRACKING,
                                               closed_backoff_m(b0, t, t2)))
        return [self.blend_cb(ca.vertcat(*poses))], np.concatenate(bounds)

    def _clearance_bounds(self, k: int, tr_times: list[float]) -> Array:
        """Lower bounds (m) of the distances at the k via points, then at the tracking nodes (contact rule)."""
        sc = self.scenario
        layout = scene_layout(sc.robot, sc.target)
        margin, b0, t2 = sc.limits.collision_margin_m, sc.approach.pregrasp_backoff_m, sc.phases.tracking_s
        parts = [required_clearance_m(self.scene.pairs, layout.gripper_handle, margin, APPROACH)] * k
        parts += [required_clearance_m(self.scene.pairs, layout.gripper_handle, margin, TRACKING,
                                       closed_backoff_m(b0, t_node, t2)) for t_node in tr_times]
        return np.concatenate(parts)

    def _grasp_joint_rates(self, x_base, q, qd_nodes, R_target, omega_body,  # noqa: ANN001, ANN202
                           T_body_grasp: Array):
        """Joint rates (rad/s) of the tracking law (Eq. 7, :mod:`planner.phases.tracking`) at the grasp.

        There the pose error is zero and the gains have ramped up, so the IK's rates are
        ``J*⁺ t_g + (I − J*⁺J*) q̇_ref`` with ``t_g`` the grasp frame's twist (target COM fixed, rotating
        at ``R_target ω_body``) and ``q̇_ref`` the null-space reference, the slope between the last two
        tracking nodes (its manipulability and posture-feedback terms nearly cancel and are left out:
        measured 0.005 rad/s on scenario I). Near a singularity of J* (the elbow straight) the first term
        blows up, which the node-to-node rates cannot see.
        """
        R_wb = quat_to_rotation_sym(x_base[3:7])
        w_T = ca.mtimes(R_target, omega_body)
        v_g = ca.cross(w_T, ca.mtimes(R_target, ca.DM(T_body_grasp[:3, 3])))
        twist_base = ca.vertcat(ca.mtimes(R_wb.T, v_g), ca.mtimes(R_wb.T, w_T))
        J = self.ff.gen_jacobian(q)[0]
        # J⁺ t + (I − J⁺J) q̇_ref = q̇_ref + J⁺ (t − J q̇_ref), with J⁺ = Jᵀ (J Jᵀ)⁻¹ (J has full row rank)
        return qd_nodes + ca.mtimes(J.T, ca.solve(ca.mtimes(J, J.T), twist_base - ca.mtimes(J, qd_nodes)))

    def solve(self, state: TargetState, warm_start: ApproachParameters | None = None,
              max_starts: int = 3, tracking_speed_scale: float | None = None,
              skip_guesses: int = 0, max_iterations: int | None = None) -> ApproachSolution:
        """Solve for one observed target state.

        With ``warm_start`` (e.g. a solved neighbour of a grid) the NLP starts there; otherwise, and if
        that fails, it starts from the ``max_starts`` best scanned initial guesses, best first, less the
        first ``skip_guesses`` of them (the planner's next grasp when a stabilization failed), and returns
        the first success (or the last attempt, with its failure status; its ``start_guess`` says which
        guess). ``tracking_speed_scale`` scales the tracking-node rate bounds (kept for later solves).
        ``max_iterations`` (None: only the scenario's per-NLP ``max_iter``) bounds the IPOPT iterations of all
        the starts together; a solve that spends it ends unsuccessful, status ``Iteration_Budget_Exhausted``.
        (The budget counts IPOPT's iteration callbacks; a cold start, in the restoration phase, calls back once
        more than its reported iteration count.)
        """
        if tracking_speed_scale is not None:
            self.tracking_speed_scale = tracking_speed_scale
        t0 = time.perf_counter()
        starts = []
        result = None
        iterations = 0
        if warm_start is None and self.scenario.costs.approach_energy > 0 and skip_guesses == 0:
            # Eq. 16 is smallest at the base-offset guess (0 in the paper's scenarios), but free-base starts
            # lead IPOPT into local minima where the stopping room and the tracking rates hold the base
            # away (scenario I: |θ_b(0)| = 0.885 m, while a plan with the base pinned at 0 is feasible).
            # Solve with the base pinned first; if that succeeds, the free solve starts at the optimum.
            warm_start = self._solve_base_pinned(state, max_starts)
            iterations += warm_start.iterations
            if not warm_start.success:
                result, warm_start = warm_start, None
        if warm_start is not None:
            starts.append(np.concatenate([warm_start.params, warm_start.base_offset_m, [warm_start.start_delay_s],
                                          warm_start.q_tracking.ravel()]))
        n_warm = len(starts)
        for attempt in range(max_starts + len(starts)):
            if attempt == len(starts):
                starts += [np.concatenate([g.params, g.base_offset_m, [g.start_delay_s], g.q_tracking.ravel()])
                           for g in self._scanned_guesses(state, max_starts)[skip_guesses:]]
            if attempt >= len(starts) or (attempt > 0 and time.perf_counter() - t0 > self.scenario.solver.max_wall_s):
                break
            left = None if max_iterations is None else max_iterations - iterations
            if left is not None and left <= 0:
                break
            result = self._solve_once(state, starts[attempt], cold=attempt >= n_warm, max_iterations=left)
            if attempt >= n_warm:
                result = replace(result, start_guess=skip_guesses + attempt - n_warm)
            iterations += result.iterations
            if result.success or self.budget.budget_exhausted:
                break
        if result is None:
            return self._no_start("no scanned initial guess left to start from", self.scenario.base_offset_guess_m,
                                  time.perf_counter() - t0)
        return replace(result, iterations=iterations, solve_time_s=time.perf_counter() - t0)

    def forget_scan(self) -> None:
        """Drop the kept scan of initial guesses, so the next solve of any state scans anew."""
        self._scan = None

    def _scanned_guesses(self, state: TargetState, count: int) -> list[ApproachGuess]:
        """``initial_guesses`` for this scenario, computed once per target state and count (deterministic)."""
        key = (state.attitude_wxyz.tobytes(), state.omega_body_rad_s.tobytes(), count)
        if self._scan is None or self._scan[0] != key:
            self._scan = (key, initial_guesses(self.scenario, self.spline, state, count))
        return self._scan[1]

    def _no_start(self, status: str, base_offset_m: tuple[float, float], elapsed_s: float) -> ApproachSolution:
        """A failed solution for when no NLP start exists (``status`` says why)."""
        return ApproachSolution(np.zeros(self.n_params), np.asarray(base_offset_m, dtype=float), 0.0,
                                np.zeros((len(TRACKING_NODES), self.robot.n_joints)), False, status, 0, elapsed_s,
                                np.inf, np.nan)

    def _solve_base_pinned(self, state: TargetState, max_starts: int) -> ApproachSolution:
        """The NLP with θ_b(0) fixed at the scenario's base-offset guess, from guesses made for that base."""
        t0 = time.perf_counter()
        gx, gz = self.scenario.base_offset_guess_m
        pinned = replace(self.scenario, base_offset_bounds_m=((gx, gx), (gz, gz)))
        lbw, ubw = self.lbw.copy(), self.ubw.copy()
        lbw[self.n_params: self.n_params + 2] = ubw[self.n_params: self.n_params + 2] = (gx, gz)
        result, iterations = None, 0
        for g in initial_guesses(pinned, self.spline, state, max_starts):
            w0 = np.concatenate([g.params, g.base_offset_m, [g.start_delay_s], g.q_tracking.ravel()])
            result = self._solve_once(state, w0, lbw, ubw, cold=True)
            iterations += result.iterations
            if result.success or time.perf_counter() - t0 > self.scenario.solver.max_wall_s:
                break
        if result is None:
            return self._no_start("no reachable meeting time with the base pinned", (gx, gz), time.perf_counter() - t0)
        return replace(result, iterations=iterations, solve_time_s=time.perf_counter() - t0)

    @property
    def cold_solver(self) -> ca.Function:
        """The NLP's solver for starts from scanned guesses: IPOPT begins in its restoration phase.

        A guess violates the pre-grasp and tracking constraints by decimetres. From there IPOPT's normal
        phase, with a limited-memory Hessian of a Lagrangian whose multipliers are still meaningless,
        takes steps the filter cuts to 1e-4 and falls into the restoration phase again and again (scenario
        I: 108 iterations, 6 restoration calls); the restoration phase (minimum ℓ1 violation near the
        start) is what makes progress, so start there. Measured on 14 cold solves of both scenarios:
        the worst fell from 130 to 29 iterations, the easy ones took up to 7 more. Warm starts (a solved
        neighbour, an interpolated table entry) are near-feasible and keep the normal phase, with which the
        table builds and query refines were measured. Built on first use.
        """
        if self._cold_solver is None:
            self._cold_solver = ipopt_solver("approach_cold", self._nlp,
                                            self._options | {"ipopt.start_with_resto": "yes"})
        return self._cold_solver

    def _solve_once(self, state: TargetState, w0: Array, lbw: Array | None = None,
                    ubw: Array | None = None, cold: bool = False,
                    max_iterations: int | None = None) -> ApproachSolution:
        p = np.concatenate([state.attitude_wxyz, state.omega_body_rad_s])
        lbw = self.lbw if lbw is None else lbw
        ubw = self.ubw if ubw is None else ubw
        w0 = np.clip(w0, lbw[: self.n_w], ubw[: self.n_w])
        if self.n_extra:
            w0 = np.concatenate([w0, [0.0]])
        t0 = time.perf_counter()
        lbg, ubg = self.lbg.copy(), self.ubg.copy()
        lbg[self._rate_slice] *= self.tracking_speed_scale
        ubg[self._rate_slice] *= self.tracking_speed_scale
        solver = self.cold_solver if cold else self.solver
        self.budget.arm(lbg, ubg, stop_when_feasible=False, max_iterations=max_iterations)
        sol = solver(x0=w0, p=p, lbx=lbw, ubx=ubw, lbg=lbg, ubg=ubg)
        elapsed = time.perf_counter() - t0
        stats = solver.stats()
        wopt = np.asarray(sol["x"]).ravel()
        g = np.asarray(sol["g"]).ravel()
        dists = g[self.n_before_dist: self.n_before_dist + self.n_dist]
        return ApproachSolution(
            params=wopt[: self.n_params],
            base_offset_m=wopt[self.n_params: self.n_params + 2],
            start_delay_s=float(wopt[self.i_tau]),
            q_tracking=wopt[self.i_tr: self.n_w].reshape(len(TRACKING_NODES), -1),
            success=bool(stats["success"]) and not self.budget.budget_exhausted,
            status="Iteration_Budget_Exhausted" if self.budget.budget_exhausted else str(stats["return_status"]),
            iterations=int(stats["iter_count"]),
            solve_time_s=elapsed,
            cost=float(sol["f"]),
            min_distance_m=float(dists[self._held_to_margin].min()),
        )
