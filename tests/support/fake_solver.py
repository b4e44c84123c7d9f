"""A fast, deterministic stand-in for the grid-point solver, for build tests (no NLP).

Its record is a fixed function of the target state and of the warm start (so continuation order
matters, as with the real planner). Fault injection through environment variables, read only here:
``LUTGEN_FAKE_RAISE=<point>`` raises, ``LUTGEN_FAKE_HANG=<point>`` sleeps far past any timeout,
``LUTGEN_FAKE_CRASH=<point>`` kills its own process, ``LUTGEN_FAKE_SLEEP_S`` slows every point.
:func:`solve_in_warm_minimum` stays in its warm start's minimum (its base offset, so its cost), and
``LUTGEN_FAKE_INFEASIBLE=<point>`` makes its warm plans there infeasible.
"""

from __future__ import annotations

import os
import signal
import time
from functools import cache

import numpy as np
from numpy.typing import NDArray

from lut.table.records import Record
from planner.config.scenario import load_scenario
from planner.phases.stabilization import stabilization_spline
from planner.plan_parameters import PlanParameters


@cache
def _stabilization_size(scenario_path: str) -> int:
    """How many stabilization parameters the scenario's plans have (its braking spline's free parameters)."""
    sc = load_scenario(scenario_path)
    return sc.robot.n_joints * stabilization_spline(sc).n_free_per_joint


def solve(scenario_path: str, point: int, attitude_wxyz: NDArray[np.float64], omega_body_rad_s: NDArray[np.float64],
          warm: PlanParameters | None, warm_shift_s: float, max_wall_s: float | None = None,
          deadline_at_s: float | None = None, cold_fallback: bool = False,
          observed_at_s: float | None = None) -> Record:
    """The solver protocol of :func:`lut.solve.point_worker.solve_point`, answered without an NLP."""
    if os.environ.get("LUTGEN_FAKE_RAISE") == str(point):
        raise RuntimeError(f"injected failure at point {point}")
    if os.environ.get("LUTGEN_FAKE_HANG") == str(point):
        time.sleep(3600)
    if os.environ.get("LUTGEN_FAKE_CRASH") == str(point):
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(float(os.environ.get("LUTGEN_FAKE_SLEEP_S", "0")))
    seed = np.concatenate([np.asarray(attitude_wxyz, float), np.asarray(omega_body_rad_s, float)])
    base = np.sin(np.arange(1, 36) * seed.sum())
    if warm is not None:
        base = base + 1e-3 * np.asarray(warm.approach.params, float)
    return {
        "point": point, "status": "feasible", "failure_reason": "", "solve_time_s": 0.0, "iterations": 7,
        "approach_params": base, "base_offset_m": seed[1:3].copy(), "start_delay_s": float(10 + point + warm_shift_s),
        "q_tracking": np.outer(np.arange(3), seed[:7]),
        "stabilization_params": np.resize(base[::-1], _stabilization_size(scenario_path)),
        "free_axis_angle_rad": 0.0, "costs/min_distance_m": 0.1, "costs/approach_energy_m2": 0.0,
        "costs/peak_grasp_torque_nm": 1.0, "margins/collision": 0.05,
    }


def solve_in_warm_minimum(scenario_path: str, point: int, attitude_wxyz: NDArray[np.float64],
                          omega_body_rad_s: NDArray[np.float64], warm: PlanParameters | None, warm_shift_s: float,
                          max_wall_s: float | None = None, deadline_at_s: float | None = None,
                          cold_fallback: bool = False, observed_at_s: float | None = None) -> Record:
    """:func:`solve`, but a warm-started plan keeps its warm start's base offset (it lands in the neighbour's
    minimum, so at its Eq. 16 cost), and is infeasible at the point ``LUTGEN_FAKE_INFEASIBLE`` names."""
    rec = solve(scenario_path, point, attitude_wxyz, omega_body_rad_s, warm, warm_shift_s)
    if warm is not None:
        rec["base_offset_m"] = np.asarray(warm.approach.base_offset_m, dtype=float).copy()
        if os.environ.get("LUTGEN_FAKE_INFEASIBLE") == str(point):
            rec["status"], rec["failure_reason"] = "infeasible", "stand-in: collision link 2 - panel"
    return rec
