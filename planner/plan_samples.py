"""A plan's dense trajectory: the phases re-simulated at a fixed step and joined, and the compound at the grasp.

The approach and the stabilization are re-simulated from their B-spline parameters (joint positions and rates
sampled every :data:`SAMPLE_STEP_S`, the base integrated by RK4); the tracking phase comes from the tracking IK
(:mod:`planner.phases.tracking`). Times are seconds since the observation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.compound import compound_robot, grasp_geometry
from planner.model.freefloating import FreeFloatingModel
from planner.model.rotation import axis_angle_to_matrix
from planner.model.target import TargetMotion
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.phase_spline import approach_vertices, stabilization_vertices
from planner.phases.approach import ApproachSolution
from planner.phases.stabilization import GraspState, StabilizationSolution, grasp_momentum_world
from planner.phases.stabilization_dynamics import compound_rk4_step
from planner.phases.tracking import TrackingResult

Array = NDArray[np.float64]

SAMPLE_STEP_S = 0.01  # dense re-simulation step of the approach and stabilization [s]


@dataclass(frozen=True)
class PhaseSamples:
    """One phase sampled densely: times from its start [s] ``(n,)``, joints ``(n, 7)`` [rad, rad/s], base ``(n, 7)``."""

    t: Array
    q: Array
    qd: Array
    x_base: Array  # [p_world_base [m], quat_world_base]


@dataclass(frozen=True)
class JoinedTrajectory:
    """The three phases joined: their time spans and the dense samples (see :class:`planner.plan.GraspPlan`)."""

    phases: dict[str, tuple[float, float]]
    t: Array
    q: Array
    qd: Array
    x_base: Array
    phase_index: Array  # (n,) 0 approach, 1 tracking, 2 stabilization


def spline_samples(spline: UniformCubicBSpline, V: Array, ff: FreeFloatingModel, x0: Array,
                   h_world: Array) -> PhaseSamples:
    """Joint positions/velocities of vertices ``V`` ``(N, 7)`` and the RK4-integrated base at :data:`SAMPLE_STEP_S`."""
    T = spline.duration_s
    n = int(np.ceil(T / SAMPLE_STEP_S))
    t = np.linspace(0.0, T, n + 1)
    q = spline.evaluate(V, t)
    qd = spline.evaluate(V, t, 1)
    mids = 0.5 * (t[:-1] + t[1:])
    x = ff.integrate_base_sampled(t, q, qd, spline.evaluate(V, mids), spline.evaluate(V, mids, 1), x0, h_world)
    return PhaseSamples(t, q, qd, x)


def approach_samples(scenario: Scenario, spline: UniformCubicBSpline, ff: FreeFloatingModel,
                     app: ApproachSolution) -> PhaseSamples:
    """The approach re-simulated from its parameters (the base at rest, zero momentum)."""
    V = approach_vertices(spline, scenario.q_initial, app.params)
    return spline_samples(spline, V, ff, np.array([app.base_offset_m[0], 0.0, app.base_offset_m[1],
                                                   1.0, 0.0, 0.0, 0.0]), np.zeros(6))


def stabilization_samples(spline: UniformCubicBSpline, compound: FreeFloatingModel, stab: StabilizationSolution,
                          grasp: GraspState) -> PhaseSamples:
    """The stabilization re-simulated from its parameters, the ``compound`` (of :func:`grasp_state`) starting at
    the grasp state."""
    V = stabilization_vertices(spline, grasp.q, grasp.qd, grasp.qdd, stab.params)
    return spline_samples(spline, V, compound, grasp.x_base, grasp.h_world)


def grasp_state(scenario: Scenario, ff: FreeFloatingModel, tr: TrackingResult,
                motion: TargetMotion) -> tuple[GraspState, Array, FreeFloatingModel]:
    """Compound state at the grasp, its momentum, the grasp frame used ``(4, 4)`` (free-axis angle applied), and
    the compound's free-floating model (built once: the stabilization's re-simulation reuses it)."""
    sc = scenario
    T_bg = sc.target.grasp.T_body_grasp.copy()
    axis = sc.target.grasp.free_axis
    if axis is not None:
        T_bg[:3, :3] = T_bg[:3, :3] @ axis_angle_to_matrix(axis, tr.free_axis_angle_rad)
    T_ee_target = np.linalg.inv(T_bg)  # the ee frame coincides with the grasp frame at the grasp
    q, qd, x = tr.q[-1], tr.qd[-1], tr.x_base[-1]
    # the dense re-simulation of the stabilization steps with the compiled compound step (geometry as parameters)
    compound = FreeFloatingModel(compound_robot(sc, T_ee_target),
                                 parametric_rk4=(compound_rk4_step(sc.robot), grasp_geometry(sc, T_ee_target)))
    h_world = grasp_momentum_world(ff, compound, q, qd, x)
    qdd = tr.qdd_end if sc.stabilization.start_acceleration == "continuous" else np.zeros_like(qd)
    return GraspState(q, qd, qdd, x, h_world, T_ee_target), T_bg, compound


def joined(scenario: Scenario, start_delay_s: float, app: PhaseSamples, tr: TrackingResult,
           stab: PhaseSamples) -> JoinedTrajectory:
    """The phases one after the other from the start delay [s], each join sampled once."""
    ph = scenario.phases
    tf1, tf2, tf3 = ph.approach_s, ph.tracking_s, ph.stabilization_s
    t0 = start_delay_s
    phases = {"approach": (t0, t0 + tf1), "tracking": (t0 + tf1, t0 + tf1 + tf2),
              "stabilization": (t0 + tf1 + tf2, t0 + tf1 + tf2 + tf3)}
    t = np.concatenate([app.t + t0, tr.t[1:], stab.t[1:] + phases["stabilization"][0]])
    q = np.vstack([app.q, tr.q[1:], stab.q[1:]])
    qd = np.vstack([app.qd, tr.qd[1:], stab.qd[1:]])
    x = np.vstack([app.x_base, tr.x_base[1:], stab.x_base[1:]])
    phase_index = np.concatenate([np.zeros(len(app.t)), np.ones(len(tr.t) - 1), np.full(len(stab.t) - 1, 2)])
    return JoinedTrajectory(phases, t, q, qd, x, phase_index.astype(int))
