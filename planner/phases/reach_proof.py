"""A proof that no plan meets a target state: the grasp's wrist point beyond the chaser's reach at every meeting time.

From θ_b(0) on the chaser floats free (Eq. 2-6, zero momentum), so its centre of mass stays where θ_in at θ_b(0)
put it: c = c_in + (b_x, 0, b_z). At the grasp, the end of the tracking, the gripper holds the grasp frame, so the
wrist point (:mod:`planner.model.wrist_reach`) is the grasp frame's own and lies within the reach radius of c. Where,
for every start delay of the window, every base offset of the box and every angle about a free grasp axis, it lies
farther, no plan exists, whatever its joint motion: the scan's IK need not be asked.

The window and the angle are sampled, and a margin turns the sampled minimum into a bound: the torque-free target
turns at most at |L|/I_min (|L| its angular momentum, I_min its smallest moment of inertia), so between samples δ
apart the wrist point moves at most |L|/I_min·(|r|+|w|)·δ/2 (r the grasp's lever arm, w the wrist point's offset);
the free angle likewise moves it at most |w⊥|·Δψ/2; and verify accepts a grasp within its position and orientation
tolerances, which move it at most tol_p + |w|·tol_R.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.rotation import axis_angle_to_matrix
from planner.model.target import TargetState
from planner.model.wrist_reach import WristReach, centre_of_mass_m, wrist_reach
from planner.verify.checks import GRASP_ORIENTATION_TOL_RAD, GRASP_POSITION_TOL_M

Array = NDArray[np.float64]

SAMPLE_STEP_S = 0.05  # start delays this far apart: a margin of ~1 cm at 4 °/s per axis
ANGLE_SAMPLES = 360  # angles about a free grasp axis, 1° apart: a margin of ~4 mm for a 0.5 m wrist offset


@dataclass(frozen=True)
class ReachProof:
    """How far beyond the arm's reach the grasp stays over the start-delay window, as a certified lower bound.

    ``slack_m``: the smallest, over the window, of the wrist point's distance from the nearest admissible centre of
    mass less the reach radius, less ``margin_m`` [m]; > 0 proves the state out of reach. ``start_delay_s``: where
    that smallest distance is [s]. ``margin_m``: what sampling and verify's grasp tolerances take off [m].
    ``radius_m``: the arm's reach radius about the centre of mass [m]; ``window_s``: the start-delay window
    (earliest, latest) [s]; ``least_offset_m``: how far from its station the chaser would have to wait (below).
    """

    slack_m: float
    start_delay_s: float
    margin_m: float
    radius_m: float
    window_s: tuple[float, float]
    # the least ‖θ_b(0)‖ [m] (from the station, θ_b(0) = 0, in the orbital plane, whatever the box) at which the wrist
    # point comes within the radius at some start delay (a certified lower bound); inf: no base offset brings it
    least_offset_m: float

    @property
    def proven(self) -> bool:
        """True when no plan can reach the grasp at any meeting time of the window."""
        return self.slack_m > 0.0

    def reason(self) -> str:
        """Why the state is out of reach, in one sentence (for an infeasible answer)."""
        earliest, latest = self.window_s
        return (f"out of reach (proven): at every start delay within [{earliest:g}, {latest:g}] s the grasp's wrist "
                f"point stays at least {self.slack_m:.3f} m beyond the {self.radius_m:.3f} m the arm reaches from the "
                f"chaser's centre of mass, wherever in the base-offset box it waits (closest at "
                f"{self.start_delay_s:g} s); {self._offset_needed()}")

    def _offset_needed(self) -> str:
        """How far from its station the chaser would have to wait for the grasp to come within reach at all."""
        if not np.isfinite(self.least_offset_m):
            return "no base offset in the orbital plane brings it within reach"
        return f"it comes within reach only with the chaser at least {self.least_offset_m:.2f} m from its station"


def reach_proof(scenario: Scenario, state: TargetState, step_s: float = SAMPLE_STEP_S) -> ReachProof:
    """The certified reach slack of ``state`` over the scenario's start-delay window (deterministic; milliseconds for a
    fixed grasp, tens of them for one free about an axis)."""
    wrist = wrist_reach(scenario.robot)
    delays_s, wrist_points = _wrist_from_station_com(scenario, state, step_s, wrist)
    distance_m = _nearest_in_box(scenario, wrist_points)
    margin = _margin_m(scenario, state, wrist, float(np.max(np.diff(delays_s), initial=0.0)))
    k = int(np.argmin(distance_m))
    return ReachProof(float(distance_m[k] - wrist.radius_m - margin), float(delays_s[k]), margin, wrist.radius_m,
                      scenario.phases.start_delay_window_s, _least_offset(wrist_points, wrist.radius_m + margin))


def wrist_distance_over_window(scenario: Scenario, state: TargetState, step_s: float = SAMPLE_STEP_S,
                               wrist: WristReach | None = None) -> tuple[Array, Array]:
    """Start delays over the window (the ends included, at most ``step_s`` apart) [s] and, at each, the grasp's wrist
    point's distance from the nearest admissible centre of mass (any base offset of the box, any free-axis angle)
    [m], at the samples (no margin)."""
    delays, wrist_points = _wrist_from_station_com(scenario, state, step_s, wrist)
    return delays, _nearest_in_box(scenario, wrist_points)


def _nearest_in_box(scenario: Scenario, wrist_points: list[Array]) -> Array:
    """At each sample, the wrist point's distance from the nearest centre of mass the box admits (any free-axis turn)
    [m]: the box shifts the station's centre of mass by (b_x, 0, b_z)."""
    (x_lo, x_hi), (z_lo, z_hi) = scenario.base_offset_bounds_m
    nearest = np.full(len(wrist_points[0]), np.inf)
    for d in wrist_points:
        dx, dz = d[:, 0] - np.clip(d[:, 0], x_lo, x_hi), d[:, 2] - np.clip(d[:, 2], z_lo, z_hi)
        nearest = np.minimum(nearest, np.sqrt(dx ** 2 + d[:, 1] ** 2 + dz ** 2))
    return nearest


def _least_offset(wrist_points: list[Array], radius_m: float) -> float:
    """The least ‖θ_b(0)‖ [m] in the orbital plane, whatever the box, that brings one of ``wrist_points`` (from the
    station's centre of mass [m], one ``(n, 3)`` per free-axis turn) within ``radius_m`` of the centre of mass: the
    base offset moves the centre of mass in x and z only, so a point at (x, y, z) needs ‖(x, z)‖ − √(r² − y²) of it,
    and none (inf) where |y| > r."""
    least = np.inf
    for d in wrist_points:
        across_sq = radius_m ** 2 - d[:, 1] ** 2
        within = across_sq >= 0.0
        if np.any(within):
            in_plane = np.hypot(d[within, 0], d[within, 2]) - np.sqrt(across_sq[within])
            least = min(least, float(np.maximum(in_plane, 0.0).min()))
    return least


def _wrist_from_station_com(scenario: Scenario, state: TargetState, step_s: float,
                            wrist: WristReach | None) -> tuple[Array, list[Array]]:
    """Start delays over the window (the ends included, at most ``step_s`` apart) [s] and, for each free-axis turn,
    the grasp's wrist point at the grasp of each from the chaser's centre of mass at θ_b(0) = 0 [m], ``(n, 3)``."""
    sc = scenario
    wrist = wrist_reach(sc.robot) if wrist is None else wrist
    earliest, latest = sc.phases.start_delay_window_s
    delays = np.linspace(earliest, latest, max(2, int(np.ceil((latest - earliest) / step_s)) + 1))
    grasp_s = delays + sc.phases.approach_s + sc.phases.tracking_s
    R_world_grasp, p_world_grasp = sc.target.motion(state, float(grasp_s[-1]) + 1.0).grasp_pose(grasp_s)
    p_wrist_from_com = p_world_grasp - centre_of_mass_m(sc.robot, sc.q_initial)  # θ_b(0) = 0
    return delays, [p_wrist_from_com + R_world_grasp @ (turn @ wrist.p_grasp_wrist_m) for turn in _free_axis_turns(sc)]


def _free_axis_turns(scenario: Scenario) -> list[Array]:
    """The grasp frame's turns about its free axis the gripper may hold it at (the identity alone without one)."""
    axis = scenario.target.grasp.free_axis
    if axis is None:
        return [np.eye(3)]
    return [axis_angle_to_matrix(axis, a) for a in np.linspace(0.0, 2 * np.pi, ANGLE_SAMPLES, endpoint=False)]


def _margin_m(scenario: Scenario, state: TargetState, wrist: WristReach, step_s: float) -> float:
    """How far the wrist point can be from every sample [m]: between start delays ``step_s`` apart, between free-axis
    angles, and within verify's grasp tolerances."""
    body = scenario.target.body()
    inertia = body.inertia_body_kg_m2
    rate_max = np.linalg.norm(inertia @ state.omega_body_rad_s) / np.linalg.eigvalsh(inertia)[0]  # |ω| ≤ |L|/I_min
    offset = float(np.linalg.norm(wrist.p_grasp_wrist_m))
    lever = float(np.linalg.norm(body.T_body_grasp[:3, 3])) + offset
    axis = scenario.target.grasp.free_axis
    across = 0.0 if axis is None else float(np.linalg.norm(np.cross(axis, wrist.p_grasp_wrist_m)))
    return (rate_max * lever * step_s / 2 + across * np.pi / ANGLE_SAMPLES
            + GRASP_POSITION_TOL_M + offset * GRASP_ORIENTATION_TOL_RAD)
