"""The approach NLP's symbolic motion: the joints' B-spline, the free-floating base and the target's attitude.

Single shooting (paper §4.2): the base is unactuated with zero momentum, so its pose is integrated by RK4 from
the decision variables, along the approach and then along the tracking path (joints moving linearly between
the tracking nodes); the target's attitude is predicted to the start delay τ and along both phases. Every
quantity here is a CasADi MX expression of the decision vector ``w`` and the parameters ``p`` (the observed
target state).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel, pose_rk4_step, quat_rotation_function
from planner.model.target_symbolic import prediction_function
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.phase_spline import approach_vertices

TARGET_STEPS_PER_S = 1.0  # RK4 steps of the symbolic target prediction per second of delay
TRACKING_RK4_STEPS = 3  # base-drift RK4 steps per tracking-node interval


@dataclass(frozen=True)
class ChaserPath:
    """Joints and base along the approach (at its RK4 nodes) and at the tracking nodes."""

    Qn: ca.MX  # (m_steps + 1, 7) joint positions at the RK4 nodes [rad]
    Qdn: ca.MX  # (m_steps + 1, 7) joint rates at the RK4 nodes [rad/s]
    xs: list[ca.MX]  # m_steps + 1 base states (7,): [p_world_base [m], quat_world_base]
    x_tracking: list[ca.MX]  # base state at each tracking node
    q_end: ca.MX  # (7,) joints at t_f¹ [rad]


@dataclass(frozen=True)
class TargetPath:
    """The target's predicted attitude (as rotation matrices, world) at the via points and tracking nodes."""

    R_via: list[ca.MX]  # k × (3, 3), the last at t_f¹
    R_tracking: list[ca.MX]  # one (3, 3) per tracking node
    attitude_tf: ca.MX  # (4,) quaternion wxyz at t_f¹
    omega_tf: ca.MX  # (3,) body rates at t_f¹ [rad/s]
    omega_grasp: ca.MX  # (3,) body rates at the last tracking node (the grasp) [rad/s]
    predict_step: ca.Function  # (attitude, omega, dt) -> (attitude, omega): the step prediction used


def chaser_path(scenario: Scenario, ff: FreeFloatingModel, spline: UniformCubicBSpline, m_steps: int,
                P: ca.MX, base_offset: ca.MX, Q_tracking: list[ca.MX], tracking_times_s: list[float]) -> ChaserPath:
    """The joints of Eq. 23 from ``P`` and the base integrated from θ_b(0) = ``base_offset`` (x, z) [m]."""
    tf = scenario.phases.approach_s
    V = approach_vertices(spline, ca.DM(scenario.q_initial), P)
    nodes = np.linspace(0.0, tf, m_steps + 1)
    mids = 0.5 * (nodes[:-1] + nodes[1:])
    Qn = spline.evaluate(V, nodes)
    Qdn = spline.evaluate(V, nodes, 1)
    Qm = spline.evaluate(V, mids)
    Qdm = spline.evaluate(V, mids, 1)
    x0 = ca.vertcat(base_offset[0], 0.0, base_offset[1], 1.0, 0.0, 0.0, 0.0)
    # the twists at every node and midpoint in two calls, the steps in one: a few nodes for the NLP's Jacobian
    twist = ff.zero_momentum_twist
    at_nodes = twist.map(m_steps + 1)(Qn.T, Qdn.T)
    at_mids = twist.map(m_steps)(Qm.T, Qdm.T)
    steps = pose_rk4_step().mapaccum("approach_base_steps", m_steps)
    after = steps(x0, at_nodes[:, :-1], at_mids, at_nodes[:, 1:], tf / m_steps)
    xs = [x0, *ca.horzsplit(after)]
    q_end = Qn[-1, :].T
    return ChaserPath(Qn, Qdn, xs, _tracking_drift(ff, xs[-1], q_end, Q_tracking, tracking_times_s), q_end)


def _tracking_drift(ff: FreeFloatingModel, x: ca.MX, q_end: ca.MX, Q_tracking: list[ca.MX],
                    tracking_times_s: list[float]) -> list[ca.MX]:
    """Base states at the tracking nodes, the joints moving linearly from node to node."""
    step, twist = pose_rk4_step(), ff.zero_momentum_twist
    x_tr, q_prev, t_prev = [], q_end, 0.0
    for j, t_node in enumerate(tracking_times_s):
        h = (t_node - t_prev) / TRACKING_RK4_STEPS
        qd_seg = (Q_tracking[j] - q_prev) / (t_node - t_prev)
        for s in range(TRACKING_RK4_STEPS):
            qa = q_prev + qd_seg * (s * h)
            x = step(x, twist(qa, qd_seg), twist(qa + qd_seg * (h / 2), qd_seg), twist(qa + qd_seg * h, qd_seg), h)
        x_tr.append(x)
        q_prev, t_prev = Q_tracking[j], t_node
    return x_tr


def target_path(scenario: Scenario, attitude_wxyz: ca.MX, omega_body: ca.MX, start_delay: ca.MX, k: int,
                tracking_times_s: list[float]) -> TargetPath:
    """The target from the observation: to τ = ``start_delay`` by ~1 s steps, then along the approach's ``k``
    via points and the tracking nodes."""
    target, tf = scenario.target, scenario.phases.approach_s
    max_delay = max(scenario.phases.max_start_delay_s, 1e-3)
    predict_delay = prediction_function(target.inertia_body_kg_m2,
                                        max(4, int(np.ceil(max_delay * TARGET_STEPS_PER_S))))
    predict_step = prediction_function(target.inertia_body_kg_m2, max(2, int(np.ceil(tf / k))))
    att, om = predict_delay(attitude_wxyz, omega_body, start_delay)
    rotation = quat_rotation_function()
    R_via = []
    for _ in range(k):
        att, om = predict_step(att, om, tf / k)
        R_via.append(rotation(att))
    att_f, om_f = att, om
    R_tracking, t_prev = [], 0.0
    for t_node in tracking_times_s:
        att, om = predict_step(att, om, t_node - t_prev)
        R_tracking.append(rotation(att))
        t_prev = t_node
    return TargetPath(R_via, R_tracking, att_f, om_f, om, predict_step)
