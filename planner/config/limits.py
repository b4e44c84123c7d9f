"""Sanity limits of configuration values: beyond them a value is surely a typo.

Such a value would cost hours or gigabytes before the first answer (``stabilization_s = 1e9``,
``via_points = 1e8``, a 10⁷-point grid).

Keys are dotted field paths without list indices (``shapes.size_m`` covers ``shapes[2].size_m``); a number
must lie in ``[low, high]``, every element of a vector in ``[-high, high]`` (``low`` applies to numbers
only). The bounds are generous: the paper's scenarios sit far inside every one of them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Limit:
    """Sanity range of one field: a number in ``[low, high]``, every element of a vector in ``[-high, high]``."""

    high: float
    low: float = float("-inf")
    unit: str = ""


LIMITS: dict[str, Limit] = {
    # scenario: durations [s] — a plan samples them at 0.01 s and the NLPs integrate over them
    "phases.approach_s": Limit(300.0, unit="s"),
    "phases.tracking_s": Limit(60.0, unit="s"),
    "phases.stabilization_s": Limit(600.0, unit="s"),
    "phases.max_start_delay_s": Limit(3600.0, unit="s"),
    "phases.min_start_delay_s": Limit(3600.0, unit="s"),
    "tracking.step_s": Limit(1.0, low=1e-4, unit="s"),
    "solver.max_wall_s": Limit(86400.0, unit="s"),
    # scenario: discretisation counts — each adds NLP variables or constraints
    "approach.n_vertices": Limit(100), "approach.via_points": Limit(500), "approach.rk4_steps": Limit(5000),
    "stabilization.n_vertices": Limit(100), "stabilization.via_points": Limit(500),
    "stabilization.rk4_steps": Limit(5000), "stabilization.coarse_via_points": Limit(500),
    "solver.max_iter": Limit(100_000),
    "solver.tol": Limit(1.0, low=1e-14),
    # scenario: gains, weights, limits
    "tracking.pose_gain_per_s": Limit(1000.0, unit="1/s"), "tracking.nullspace_gain": Limit(1000.0),
    "costs.manipulability": Limit(1e6), "costs.min_distance": Limit(1e6), "costs.approach_energy": Limit(1e6),
    "costs.attitude_disturbance": Limit(1e6), "costs.peak_wrench": Limit(1e6), "costs.overscale": Limit(10.0),
    "limits.collision_margin_m": Limit(1.0, unit="m"), "limits.grasp_force_max_n": Limit(1e6, unit="N"),
    "limits.grasp_torque_max_nm": Limit(1e6, unit="N·m"),
    "approach.pregrasp_backoff_m": Limit(2.0, unit="m"),
    "target_state.omega_body_deg_s": Limit(360.0, unit="°/s"),
    "robot.base_offset_x_m": Limit(100.0, unit="m"), "robot.base_offset_z_m": Limit(100.0, unit="m"),
    "robot.base_offset_guess_m": Limit(100.0, unit="m"),
    # target: sizes [m] and mass [kg]
    "mass_kg": Limit(1e6, unit="kg"), "com_position_m": Limit(1000.0, unit="m"),
    "shapes.size_m": Limit(100.0, unit="m"), "shapes.radius_m": Limit(50.0, unit="m"),
    "shapes.length_m": Limit(100.0, unit="m"), "shapes.position_m": Limit(1000.0, unit="m"),
    "grasp.position_m": Limit(1000.0, unit="m"),
    # grid: axis bounds (deg, deg/s) and counts; the product of the counts is limited in lut.table.grid
    "axes.min": Limit(3600.0), "axes.max": Limit(3600.0), "axes.count": Limit(10_000),
}
MAX_SHAPES = 100  # target collision shapes (each adds 7+ body pairs to every collision check)
MAX_CONFIG_BYTES = 1 << 20  # a config file is a few kB; a larger one is not a config
MAX_GRID_POINTS = 100_000  # ~5 days of a 1000-core cluster at ~20 points/h per core


def limit_of(field: str) -> Limit | None:
    """The :class:`Limit` of a dotted field (list indices ignored), or None when it has none."""
    return LIMITS.get(re.sub(r"\[\d+\]", "", field))


def violation(field: str, value: float) -> str | None:
    """Why ``value`` of ``field`` is out of its limit (one phrase), or None when it is within it."""
    limit = limit_of(field)
    if limit is None:
        return None
    unit = f" {limit.unit}" if limit.unit else ""
    if value > limit.high:
        return f"must be <= {limit.high:g}{unit} (sanity limit), got {value:g}"
    if value < limit.low:
        return f"must be >= {limit.low:g}{unit} (sanity limit), got {value:g}"
    return None
