"""The free-floating base's drift along a guessed approach, and the guess's IK corrected for it.

The scan of meeting times freezes the base; moving ~70 kg of arm through large angles shifts and turns the
800 kg base by centimetres and degrees, which would leave the NLP far from its end constraint.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import fk_function
from planner.model.rotation import quat_to_matrix
from planner.model.target import TargetMotion
from planner.phases.approach_ik import PoseIK
from planner.phases.pregrasp_pose import at_own_angle, free_axis_turn, pregrasp_position
from planner.phases.tracking_profile import TRACKING_NODES, backoff_m, smoothstep5

Array = NDArray[np.float64]

DRIFT_ITERATIONS = 3


def correct_for_base_drift(sc: Scenario, ik: PoseIK, motion: TargetMotion, configs: list[Array], tau: float,
                            S_pre: Array) -> list[Array]:
    """Re-solve the IK ``configs`` (each ``[q (7,), b_x, b_z]``) with the base where the free-floating base
    actually drifts along the guessed path. The drift does not depend on the base offset (translation
    invariance), so a few fixed-point passes converge."""
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    fk = fk_function(sc.robot)
    for _ in range(DRIFT_ITERATIONS):
        drifts = _base_drift(sc, configs)
        R_g, p_g = (a[0] for a in motion.grasp_pose(tau + tf))
        x_pre = ik.solve(pregrasp_position(sc, R_g, p_g), R_g, S_pre, [configs[0]], drift=drifts[0])
        if x_pre is None:
            return configs
        x_pre = at_own_angle(sc, ik, R_g, p_g, x_pre, drifts[0][1] @ np.asarray(fk(x_pre[:7])[-2]), drifts[0])
        R_free = free_axis_turn(sc, R_g, drifts[0][1] @ np.asarray(fk(x_pre[:7])[-2]))
        new = [x_pre]
        for j, frac in enumerate(TRACKING_NODES):
            t_node = frac * t2
            R_n, p_n = (a[0] for a in motion.grasp_pose(tau + tf + t_node))
            R_G = R_n @ R_free
            x_node = ik.solve(p_n - backoff_m(sc.approach.pregrasp_backoff_m, t_node, t2) * R_G[:, 2], R_G,
                              np.eye(3), [configs[j + 1]], base_fixed=x_pre[7:], drift=drifts[j + 1])
            if x_node is None:
                return configs
            new.append(x_node)
        configs = new
    return configs


def _base_drift(sc: Scenario, configs: list[Array]) -> list[tuple[Array, Array]]:
    """Base displacement and rotation since t = 0 at t_f¹ and at each tracking node (zero momentum).

    Joint path: the quintic blend θ_in → pre-grasp over the approach, then straight lines between the
    tracking nodes — the same path the NLP's guess and its tracking-node integration use.
    """
    ff = _free_floating(sc)
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    q_pre = configs[0][:7]

    def approach_state(t: float) -> tuple[Array, Array]:
        s = t / tf
        ds = 30 * s**2 * (1 - s) ** 2 / tf
        return sc.q_initial + smoothstep5(s) * (q_pre - sc.q_initial), ds * (q_pre - sc.q_initial)

    x = ff.integrate_base(np.linspace(0.0, tf, 41), approach_state, np.array([0, 0, 0, 1.0, 0, 0, 0]))[-1]
    out = [(x[:3].copy(), quat_to_matrix(x[3:]))]
    t_prev, q_prev = 0.0, q_pre
    for frac, c in zip(TRACKING_NODES, configs[1:], strict=True):
        t_node = frac * t2
        qd = (c[:7] - q_prev) / (t_node - t_prev)

        def line(t: float, q0: Array = q_prev, qd: Array = qd) -> tuple[Array, Array]:
            return q0 + qd * t, qd

        x = ff.integrate_base(np.linspace(0.0, t_node - t_prev, 9), line, x)[-1]
        out.append((x[:3].copy(), quat_to_matrix(x[3:])))
        t_prev, q_prev = t_node, c[:7]
    return out


_MODELS: dict[int, FreeFloatingModel] = {}


def _free_floating(scenario: Scenario) -> FreeFloatingModel:
    key = id(scenario.robot)
    if key not in _MODELS:
        _MODELS[key] = FreeFloatingModel(scenario.robot)
    return _MODELS[key]


def ik_jacobian(scenario: Scenario, q: Array) -> Array:
    """Generalized Jacobian J* ``(6, 7)`` (base frame) of the scenario's robot at ``q`` ``(7,)`` [rad]."""
    return np.asarray(_free_floating(scenario).gen_jacobian(q)[0])
