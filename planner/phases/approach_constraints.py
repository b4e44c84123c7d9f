"""The approach NLP's constraint families as symbolic expressions (paper Eq. 8, 17-21; see docs/phases.md, Approach).

Each function builds one family from the symbolic motion (:mod:`planner.phases.approach_motion`): the
end-effector on the pre-grasp pose at t_f¹, on the moving grasp frame at the tracking nodes, the tracking
law's joint rates at the grasp, and the gripper's clearance while the tracking blends onto the grasp frame.
Bounds are set where the families are added to the NLP (:mod:`planner.phases.approach`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import SceneDistanceCallback, chaser_pose_blocks, pose_vector
from planner.collision.contact_rule import TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import TARGET_BODY, SceneLayout, scene_layout
from planner.collision.nlp_scene import build_collision_scene
from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel, quat_to_rotation_sym
from planner.model.robot import RobotModel, fk_function
from planner.phases.approach_motion import TargetPath
from planner.phases.pregrasp_pose import pregrasp_position
from planner.phases.tracking_profile import backoff_m, blend

Array = NDArray[np.float64]

# fractions of t_f² at which the gripper–handle clearance of the blend onto the moving grasp frame is constrained
BLEND_CHECK_NODES = (0.15, 0.3, 0.45)


def free_axis_rotation(M: ca.MX, axis: Array) -> ca.MX:
    """Rotation ``(3, 3)`` about ``axis`` by the angle ψ of M about it (symbolic twin of tracking.free_axis_angle)."""
    e = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e = e - np.dot(e, axis) * axis
    e = e / np.linalg.norm(e)
    Me = ca.mtimes(M, ca.DM(e))
    c = ca.dot(ca.DM(e), Me)
    s = ca.dot(ca.DM(axis), ca.cross(ca.DM(e), Me))
    r = ca.sqrt(c * c + s * s)
    K = ca.DM(np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]]))
    return ca.DM.eye(3) + (s / r) * K + (1 - c / r) * ca.mtimes(K, K)


def vee_skew(M: ca.MX) -> ca.MX:
    """vee((M − Mᵀ)/2) ``(3,)``: the sin-scaled rotation-error vector of a relative rotation M ``(3, 3)``."""
    return 0.5 * ca.vertcat(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])


def _ee_to_body(robot: RobotModel, body: str) -> Array:
    """``T_ee_body`` ``(4, 4)``: the pose of ``body``'s frame in the ee frame, when both are on the last link."""
    out = fk_function(robot)(np.zeros(robot.n_joints))
    i = list(robot.body_names).index(body)
    T_b_body, T_b_ee = np.eye(4), np.eye(4)
    T_b_body[:3, :3], T_b_body[:3, 3] = np.asarray(out[2 * i]), np.asarray(out[2 * i + 1]).ravel()
    T_b_ee[:3, :3], T_b_ee[:3, 3] = np.asarray(out[-2]), np.asarray(out[-1]).ravel()
    return np.linalg.inv(T_b_ee) @ T_b_body


@dataclass(frozen=True)
class ScenePoses:
    """World poses of the chaser's bodies and the target, as the distance callbacks take them.

    One SX Function of a point's base state, joints and target attitude: the NLP's Jacobian pushes every decision
    direction through each of its operations, which costs far less in one SX call than as separate MX nodes.
    """

    robot: RobotModel
    fk: ca.Function
    com: ca.DM  # (3,) target COM, world [m] (it does not move: zero momentum of the free target's COM)

    @cached_property
    def function(self) -> ca.Function:
        """``(x_base (7,), q (n,), R_target (3, 3)) -> (body poses, R_world_ee (3, 3), p_world_ee (3,) [m])``."""
        x, q, R = ca.SX.sym("x_base", 7), ca.SX.sym("q", self.robot.n_joints), ca.SX.sym("R_target", 3, 3)
        out = self.fk(q)
        blocks, R_wb = chaser_pose_blocks(out, len(self.robot.body_names), x)
        blocks.append(pose_vector(R, self.com))
        return ca.Function("scene_poses", [x, q, R],
                           [ca.vertcat(*blocks), ca.mtimes(R_wb, out[-2]), x[:3] + ca.mtimes(R_wb, out[-1])],
                           ["x_base", "q", "R_target"], ["body_poses", "R_world_ee", "p_world_ee"])

    def __call__(self, x_base: ca.MX, q: ca.MX, R_target: ca.MX) -> tuple[ca.MX, ca.MX, ca.MX]:
        """``(stacked body poses, R_world_ee (3, 3), p_world_ee (3,) [m])`` at base state ``x_base`` (7,)."""
        poses, R_ee, p_ee = self.function(x_base, q, R_target)
        return poses, R_ee, p_ee


def pregrasp_error(scenario: Scenario, R_ee: ca.MX, p_ee: ca.MX, R_target: ca.MX,
                   com: ca.DM) -> tuple[ca.MX, ca.MX, ca.MX]:
    """Eq. 20-21 at t_f¹: ``(position error (3,) [m], rotation error, R_free (3, 3))``.

    The rotation error is the whole orientation's (3,), or with a free grasp axis a only the components of
    a along the two other grasp axes (2,); ``R_free`` is then the rotation about a the gripper arrived with, and the
    back-off runs along the grasp frame turned by it (:mod:`planner.phases.pregrasp_pose`).
    """
    target = scenario.target
    T_bg = target.grasp.T_body_grasp
    R_g = ca.mtimes(R_target, ca.DM(T_bg[:3, :3]))
    p_g = com + ca.mtimes(R_target, ca.DM(T_bg[:3, 3]))
    free = target.grasp.free_axis
    if free is None:
        return p_ee - pregrasp_position(scenario, R_g, p_g), vee_skew(ca.mtimes(R_g.T, R_ee)), ca.DM.eye(3)
    others = [e for e in np.eye(3) if abs(e @ free) < 0.5]
    a_ee = ca.mtimes(R_ee, ca.DM(free))
    rot_err = ca.vertcat(*[ca.dot(a_ee, ca.mtimes(R_g, ca.DM(e))) for e in others])
    R_free = free_axis_rotation(ca.mtimes(R_g.T, R_ee), free)
    # backed off along the grasp frame at the gripper's angle: the line the tracking closes along
    return p_ee - pregrasp_position(scenario, ca.mtimes(R_g, R_free), p_g), rot_err, R_free


def tracking_node_errors(scenario: Scenario, poses: ScenePoses, x_tracking: list[ca.MX], Q_tracking: list[ca.MX],
                         R_tracking: list[ca.MX], tracking_times_s: list[float],
                         R_free: ca.MX) -> tuple[ca.MX, list[ca.MX]]:
    """The ee on the grasp frame (angle about a free axis kept), back-off closing: ``(errors, body poses)``."""
    T_bg, com = scenario.target.grasp.T_body_grasp, poses.com
    b0, t2 = scenario.approach.pregrasp_backoff_m, scenario.phases.tracking_s
    tr_err, tr_poses = [], []
    for j, t_node in enumerate(tracking_times_s):
        poses_j, R_ee_j, p_ee_j = poses(x_tracking[j], Q_tracking[j], R_tracking[j])
        R_G = ca.mtimes(ca.mtimes(R_tracking[j], ca.DM(T_bg[:3, :3])), R_free)
        p_G = com + ca.mtimes(R_tracking[j], ca.DM(T_bg[:3, 3]))
        d = backoff_m(b0, t_node, t2)
        tr_err += [p_ee_j - (p_G - d * R_G[:, 2]), vee_skew(ca.mtimes(R_G.T, R_ee_j))]
        tr_poses.append(poses_j)
    return ca.vertcat(*tr_err), tr_poses


def grasp_joint_rates(ff: FreeFloatingModel, x_base: ca.MX, q: ca.MX, qd_nodes: ca.MX, R_target: ca.MX,
                      omega_body: ca.MX, T_body_grasp: Array) -> ca.MX:
    """Joint rates ``(7,)`` [rad/s] of the tracking law (Eq. 7, :mod:`planner.phases.tracking`) at the grasp.

    There the pose error is zero and the gains have ramped up, so the IK's rates are
    ``J*⁺ t_g + (I − J*⁺J*) q̇_ref`` with ``t_g`` the grasp frame's twist (target COM fixed, rotating
    at ``R_target ω_body``) and ``q̇_ref`` the null-space reference, the slope between the last two
    tracking nodes (its manipulability and posture-feedback terms nearly cancel and are left out). Near a
    singularity of J* (the elbow straight) the first term blows up, which the node-to-node rates cannot see.
    """
    R_wb = quat_to_rotation_sym(x_base[3:7])
    w_T = ca.mtimes(R_target, omega_body)
    v_g = ca.cross(w_T, ca.mtimes(R_target, ca.DM(T_body_grasp[:3, 3])))
    twist_base = ca.vertcat(ca.mtimes(R_wb.T, v_g), ca.mtimes(R_wb.T, w_T))
    J = ff.gen_jacobian(q)[0]
    # J⁺ t + (I − J⁺J) q̇_ref = q̇_ref + J⁺ (t − J q̇_ref), with J⁺ = Jᵀ (J Jᵀ)⁻¹ (J has full row rank)
    return qd_nodes + ca.mtimes(J.T, ca.solve(ca.mtimes(J, J.T), twist_base - ca.mtimes(J, qd_nodes)))


def blend_clearances(scenario: Scenario, target: TargetPath, R_ee0: ca.MX, p_ee0: ca.MX,
                     R_free: ca.MX) -> tuple[SceneDistanceCallback | None, list[ca.MX], Array]:
    """Gripper–handle distances at :data:`BLEND_CHECK_NODES` of the tracking: ``(callback, distances, lower
    bounds [m])`` (no callback and nothing to bound without a gripper–handle pair).

    While the tracking IK's desired pose blends from the pre-grasp pose (at rest) onto the moving grasp
    frame, the gripper lags the target; a target moving against the approach axis closes the gap faster
    than the back-off does. The gripper is placed at that desired pose (:mod:`planner.phases.tracking`;
    the rotation blend to second order in its angle, a few degrees here).
    """
    sc = scenario
    layout = scene_layout(sc.robot, sc.target)
    if layout.gripper_handle is None:
        return None, [], np.zeros(0)
    scene = build_collision_scene(SceneLayout(layout.bodies, (layout.gripper_handle,), None, ()))
    gripper = layout.gripper_handle[0]
    callback = SceneDistanceCallback("blend_distance", scene, [gripper, TARGET_BODY], len(BLEND_CHECK_NODES))
    T_ee_gripper = _ee_to_body(sc.robot, gripper)
    T_bg, com = sc.target.grasp.T_body_grasp, ca.DM(sc.target.p_world_com)
    b0, t2, margin = sc.approach.pregrasp_backoff_m, sc.phases.tracking_s, sc.limits.collision_margin_m
    att, om = target.attitude_tf, target.omega_tf
    poses, bounds, t_prev = [], [], 0.0
    for frac in BLEND_CHECK_NODES:
        t = frac * t2
        att, om = target.predict_step(att, om, t - t_prev)
        t_prev = t
        R_t = quat_to_rotation_sym(att)
        R_G = ca.mtimes(ca.mtimes(R_t, ca.DM(T_bg[:3, :3])), R_free)
        p_G = com + ca.mtimes(R_t, ca.DM(T_bg[:3, 3]))
        s = blend(t, t2)
        p_des = (1 - s) * p_ee0 + s * (p_G - backoff_m(b0, t, t2) * R_G[:, 2])
        phi = ca.skew(s * vee_skew(ca.mtimes(R_ee0.T, R_G)))
        R_des = ca.mtimes(R_ee0, ca.DM.eye(3) + phi + 0.5 * ca.mtimes(phi, phi))
        R_grip = ca.mtimes(R_des, ca.DM(T_ee_gripper[:3, :3]))
        p_grip = p_des + ca.mtimes(R_des, ca.DM(T_ee_gripper[:3, 3]))
        poses.append(ca.vertcat(pose_vector(R_grip, p_grip), pose_vector(R_t, com)))
        bounds.append(required_clearance_m([layout.gripper_handle], layout.gripper_handle, margin, TRACKING,
                                           closed_backoff_m(b0, t, t2)))
    return callback, [callback(ca.vertcat(*poses))], np.concatenate(bounds)
