"""The scenario's settings sections, each with how it is read from its TOML table and its defaults.

Sections: phases, approach, tracking, stabilization, limits, costs, solver, and the default target state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from planner.config.toml_table import TomlTable
from planner.model.target import TargetState

Array = NDArray[np.float64]


@dataclass(frozen=True)
class TargetStateConfig:
    """Default observed target state at t = 0 (the CLI may override it)."""

    attitude_wxyz: Array  # (4,) q_world_body, unit
    omega_body_rad_s: Array  # (3,) [rad/s], body frame

    def as_state(self) -> TargetState:
        """This default as the planner's :class:`~planner.model.target.TargetState`."""
        return TargetState(np.asarray(self.attitude_wxyz, dtype=float), np.asarray(self.omega_body_rad_s, dtype=float))

    @staticmethod
    def read(s: TomlTable) -> TargetStateConfig:
        """The ``[target_state]`` table (degrees per second in the file)."""
        quat = s.vector("attitude_wxyz", 4)
        if abs(np.linalg.norm(quat) - 1.0) > 1e-6:
            raise s.error("attitude_wxyz", f"quaternion must have unit norm, got norm {np.linalg.norm(quat):.6g}",
                          quat.tolist())
        state = TargetStateConfig(quat, np.radians(s.vector("omega_body_deg_s", 3)))
        s.finish()
        return state


@dataclass(frozen=True)
class PhaseTimes:
    """Phase durations [s] and the admissible start delay along the target trajectory: the approach starts within
    [``min_start_delay_s``, ``max_start_delay_s``] after the observation [s]."""

    approach_s: float
    tracking_s: float
    stabilization_s: float
    max_start_delay_s: float
    min_start_delay_s: float = 0.0  # the earliest start: time to answer, look at the plan and move to θ_b(0)

    @staticmethod
    def read(p: TomlTable) -> PhaseTimes:
        """The ``[phases]`` table (every field required but ``min_start_delay_s``, 0 by default)."""
        phases = PhaseTimes(p.number("approach_s", positive=True), p.number("tracking_s", positive=True),
                            p.number("stabilization_s", positive=True),
                            p.number("max_start_delay_s", nonnegative=True),
                            p.number("min_start_delay_s", 0.0, nonnegative=True))
        if phases.min_start_delay_s > phases.max_start_delay_s:
            raise p.error("min_start_delay_s", f"must not exceed max_start_delay_s ({phases.max_start_delay_s:g} s), "
                          f"got {phases.min_start_delay_s:g}", phases.min_start_delay_s)
        p.finish()
        return phases

    @property
    def start_delay_window_s(self) -> tuple[float, float]:
        """When the approach may start, after the observation: (earliest, latest) [s]."""
        return self.min_start_delay_s, self.max_start_delay_s


@dataclass(frozen=True)
class ApproachSettings:
    """Discretisation of the approach NLP and the pre-grasp back-off [m] along the approach axis."""

    n_vertices: int  # B-spline control points
    via_points: int  # collision and limit checks along the phase
    rk4_steps: int  # integration steps of the base motion
    pregrasp_backoff_m: float

    @staticmethod
    def read(a: TomlTable) -> ApproachSettings:
        """The ``[approach]`` table (every field has a default)."""
        approach = ApproachSettings(
            n_vertices=a.number("n_vertices", 10, integer=True), via_points=a.number("via_points", 20, integer=True),
            rk4_steps=a.number("rk4_steps", 50, integer=True),
            pregrasp_backoff_m=a.number("pregrasp_backoff_m", 0.1, nonnegative=True))
        _check_discretisation(a, approach)
        a.finish()
        return approach


@dataclass(frozen=True)
class TrackingSettings:
    """The tracking IK's integration step [s] and gains (paper Eq. 7)."""

    step_s: float
    pose_gain_per_s: float  # [1/s]
    nullspace_gain: float

    @staticmethod
    def read(k: TomlTable) -> TrackingSettings:
        """The ``[tracking]`` table (every field has a default)."""
        tracking = TrackingSettings(k.number("step_s", 0.01, positive=True),
                                    k.number("pose_gain_per_s", 2.0, positive=True),
                                    k.number("nullspace_gain", 0.5, nonnegative=True))
        k.finish()
        return tracking


@dataclass(frozen=True)
class StabilizationSettings:
    """Discretisation of the stabilization NLP, its start acceleration and its coarse first solve."""

    n_vertices: int
    via_points: int
    rk4_steps: int
    # joint acceleration the Eq. 24 spline starts with: "continuous" = the tracking IK's at the grasp (C²
    # join: the gripper keeps accelerating with the free target, so the grasp wrench starts from zero);
    # "zero" = the paper's Eq. 24 (s̈(0) = 0; the wrench steps at the grasp by what the IK's acceleration
    # carried)
    start_acceleration: str = "continuous"
    # a cold solve first solves the same NLP with this many uniform via points (and RK4 steps), then starts
    # the full NLP from that answer; 0 solves the full NLP directly (planner.phases.stabilization)
    coarse_via_points: int = 20

    @staticmethod
    def read(b: TomlTable) -> StabilizationSettings:
        """The ``[stabilization]`` table (every field has a default)."""
        stab = StabilizationSettings(b.number("n_vertices", 10, integer=True), b.number("via_points", 20, integer=True),
                                     b.number("rk4_steps", 90, integer=True),
                                     b.string("start_acceleration", "continuous", choices=("continuous", "zero")),
                                     b.number("coarse_via_points", 20, integer=True, nonnegative=True))
        if 0 < stab.coarse_via_points < 2:
            raise b.error("coarse_via_points", f"must be 0 (off) or >= 2, got {stab.coarse_via_points}",
                          stab.coarse_via_points)
        _check_discretisation(b, stab)
        b.finish()
        return stab


def _check_discretisation(table: TomlTable, settings: ApproachSettings | StabilizationSettings) -> None:
    """At least 8 B-spline vertices, 2 via points and 2 RK4 steps."""
    for key in ("n_vertices", "via_points", "rk4_steps"):
        minimum = 8 if key == "n_vertices" else 2
        if getattr(settings, key) < minimum:
            raise table.error(key, f"must be >= {minimum}, got {getattr(settings, key)}", getattr(settings, key))


@dataclass(frozen=True)
class Limits:
    """Collision margin [m] every pair keeps, and the grasp-wrench limits per component."""

    collision_margin_m: float
    grasp_force_max_n: float  # inf = unconstrained
    grasp_torque_max_nm: float  # inf = unconstrained

    @staticmethod
    def read(lim: TomlTable) -> Limits:
        """The ``[limits]`` table (every field has a default; the wrench is unlimited by default)."""
        limits = Limits(lim.number("collision_margin_m", 0.02, nonnegative=True),
                        lim.number("grasp_force_max_n", math.inf, positive=True),
                        lim.number("grasp_torque_max_nm", math.inf, positive=True))
        lim.finish()
        return limits


@dataclass(frozen=True)
class CostWeights:
    """Weights of the scenario's weighted-sum cost (all 0: a pure feasibility solve)."""

    manipulability: float
    min_distance: float
    approach_energy: float
    attitude_disturbance: float
    peak_wrench: float
    overscale: float  # robot geometry scale for the distance cost (paper §5)

    @property
    def weights_arm_motion(self) -> bool:
        """True when a term that shapes the arm's motion is weighted: manipulability (Eq. 14) or clearance (Eq. 15)."""
        return self.manipulability > 0 or self.min_distance > 0

    @property
    def weights_approach(self) -> bool:
        """True when a cost term of the approach NLP (Eq. 14-16) is weighted."""
        return self.weights_arm_motion or self.approach_energy > 0

    def without_approach_terms(self) -> CostWeights:
        """These weights with the approach NLP's terms (Eq. 14-16) set to 0: a costed plan's feasibility stage."""
        return replace(self, manipulability=0.0, min_distance=0.0, approach_energy=0.0)

    @staticmethod
    def read(c: TomlTable) -> CostWeights:
        """The ``[costs]`` table (every weight 0 and ``overscale`` 1 by default)."""
        costs = CostWeights(*(c.number(key, 0.0, nonnegative=True) for key in (
            "manipulability", "min_distance", "approach_energy", "attitude_disturbance", "peak_wrench")),
            overscale=c.number("overscale", 1.0, positive=True))
        c.finish()
        return costs


@dataclass(frozen=True)
class SolverSettings:
    """IPOPT's iteration cap, wall-time cap [s] and tolerance."""

    max_iter: int
    max_wall_s: float
    tol: float

    @staticmethod
    def read(so: TomlTable) -> SolverSettings:
        """The ``[solver]`` table (every field has a default)."""
        solver = SolverSettings(so.number("max_iter", 300, integer=True, positive=True),
                                so.number("max_wall_s", 60.0, positive=True), so.number("tol", 1e-6, positive=True))
        so.finish()
        return solver
