"""The stabilization's dynamics as CasADi Functions: the compound's momentum at the grasp and the grasp wrench.

The target, rigidly attached to the gripper, moves with the last link; the wrench the gripper exerts on it is
``F = m_T a_T``, ``M = I_T ω̇_T + ω_T × I_T ω_T + (p_T − p_grasp) × F`` (about the grasp point), in the grasp
frame — what a wrist force/torque sensor reads. Accelerations come from exact time derivatives
(``casadi.jtimes``) of the symbolic twists along the state rates. See docs/phases.md, Stabilization.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import chaser_pose_blocks, pose_vector
from planner.model.compound import GEOMETRY_SIZE, GraspGeometry
from planner.model.freefloating import (
    FreeFloatingModel,
    base_pose_rate_sym,
    base_twist_sym,
    generalized_jacobian_sym,
    momentum_map,
    quat_to_rotation_sym,
    rk4_step_function,
)
from planner.model.per_robot import PerRobot
from planner.model.robot import RobotModel, fk_function
from planner.model.rotation import quat_to_matrix
from planner.nlp.compiled import compiled

Array = NDArray[np.float64]

# CasADi's ``jac_penalty`` of the grasp-wrench Function. The NLP's constraint Jacobian pushes one forward
# direction per decision parameter (~35) through each of its ~66 calls; CasADi instead forms the Function's
# own Jacobian (a few reverse sweeps) and multiplies the seeds when jac_penalty × its 69 inputs (34 of state,
# 35 of grasp geometry) is below the number of directions, which the default (2) forbids: the same exact
# derivative in fewer sweeps. (A compiled wrench, planner.nlp.compiled, is always differentiated through its
# compiled Jacobian.)
JACOBIAN_FIRST_PENALTY = 0.25


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

    F, M: force [N] and moment about the grasp point [N·m] the gripper exerts on the target, in the
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


@dataclass(frozen=True)
class InnerFunctions:
    """The SX Functions the stabilization NLP calls at every RK4 node and via point; they depend on the robot
    alone (grasp geometry is an input), so the coarse and the full NLP share one set."""

    rk4_step: ca.Function  # rk4_step_function of the compound, geometry as last input (compiled)
    wrench: ca.Function  # wrench_function (compiled)
    poses: ca.Function  # compound_poses_function

    @staticmethod
    def of(robot: RobotModel) -> InnerFunctions:
        """Build them, the RK4 step and the wrench compiled to C (:mod:`planner.nlp.compiled`)."""
        return InnerFunctions(compound_rk4_step(robot),
                              compiled(wrench_function(robot), {"jac_penalty": JACOBIAN_FIRST_PENALTY}),
                              compound_poses_function(robot, fk_function(robot)))


def compound_poses_function(robot: RobotModel, fk: ca.Function) -> ca.Function:
    """``(x_base, q, R_ee, p_ee, geometry) -> body poses``: the chaser's bodies and the grasped target in the world,
    stacked as the distance callback takes them (:func:`planner.collision.callback.pose_vector` each).

    One SX Function per via point: the NLP's Jacobian pushes every decision direction through its operations,
    far cheaper in one SX call than as separate MX nodes.
    """
    x, q, p_ee = ca.SX.sym("x_base", 7), ca.SX.sym("q", robot.n_joints), ca.SX.sym("p_ee", 3)
    R_ee, geo_vec = ca.SX.sym("R_ee", 3, 3), ca.SX.sym("geometry", GEOMETRY_SIZE)
    geo = GraspGeometry.unpack(geo_vec)
    blocks, _ = chaser_pose_blocks(fk(q), len(robot.body_names), x)
    blocks.append(pose_vector(ca.mtimes(R_ee, geo.R_ee_target), p_ee + ca.mtimes(R_ee, geo.p_ee_target)))
    return ca.Function("compound_poses", [x, q, R_ee, p_ee, geo_vec], [ca.vertcat(*blocks)],
                       ["x_base", "q", "R_ee", "p_ee", "geometry"], ["body_poses"])


# compound RK4 steps compound_rk4_step keeps per process (one per robot model object); the oldest goes first
COMPOUND_STEPS_KEPT = 4


def _compiled_compound_step(robot: RobotModel) -> ca.Function:
    """:func:`rk4_step_function` of the compound of ``robot`` and any grasped target, the grasp geometry
    (:mod:`planner.model.compound`) as last input, compiled."""
    geometry = ca.SX.sym("geometry", GEOMETRY_SIZE)
    return compiled(rk4_step_function(GraspGeometry.unpack(geometry).compound(robot), geometry))


# made once per process for each robot object: the stabilization NLP and every plan's dense re-simulation share it
compound_rk4_step = PerRobot(_compiled_compound_step, COMPOUND_STEPS_KEPT)
