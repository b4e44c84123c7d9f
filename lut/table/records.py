"""One grid point's result as a flat record (``"/"``-separated keys → numbers, arrays, strings).

Records travel from a point worker to the journal and into the HDF5 table; a feasible record is also
the warm start of its neighbours and the material a query interpolates. No pickles anywhere.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from planner.plan import GraspPlan
from planner.plan_parameters import ApproachParameters, PlanParameters
from planner.verify.verifier import VerifyReport

Record = dict[str, Any]

# fields a query interpolates between corner points (all numeric parameter arrays)
PARAMETER_KEYS = ("approach_params", "base_offset_m", "start_delay_s", "q_tracking", "stabilization_params")


def record_from_plan(point: int, plan: GraspPlan, report: VerifyReport) -> Record:
    """The table record of a solved, verified plan."""
    rec: Record = {
        "point": point,
        "status": "feasible" if report.feasible else "infeasible",
        "failure_reason": "; ".join(report.violations)[:2000],
        "solve_time_s": float(plan.timings_s.get("total_s", np.nan)),
        "iterations": int(plan.approach.iterations + plan.stabilization.iterations),
        "approach_params": np.asarray(plan.approach.params, dtype=float),
        "base_offset_m": np.asarray(plan.approach.base_offset_m, dtype=float),
        "start_delay_s": float(plan.approach.start_delay_s),
        "q_tracking": np.asarray(plan.approach.q_tracking, dtype=float),
        "stabilization_params": np.asarray(plan.stabilization.params, dtype=float),
        "free_axis_angle_rad": float(plan.tracking.free_axis_angle_rad),
        "costs/approach_energy_m2": float(np.dot(plan.approach.base_offset_m, plan.approach.base_offset_m)),
        "costs/min_distance_m": float(np.min(report.min_distance_m)),
        "costs/peak_grasp_torque_nm": float(np.abs(report.grasp_wrench[:, 3:]).max()),
    }
    for name, check in report.checks.items():
        rec[f"margins/{name}"] = float(check.margin)
    return rec


def failed_record(point: int, reason: str, solve_time_s: float = float("nan")) -> Record:
    """A point that crashed or timed out: no parameters, the reason kept."""
    return {"point": point, "status": "failed", "failure_reason": reason[:2000], "solve_time_s": float(solve_time_s),
            "iterations": 0}


def out_of_reach_record(point: int, reason: str, solve_time_s: float) -> Record:
    """A point the planner proved infeasible before solving (:class:`planner.plan.OutOfReach`): no parameters."""
    return {**failed_record(point, reason, solve_time_s), "status": "infeasible"}


def has_parameters(rec: Record) -> bool:
    """True when ``rec`` holds every parameter a plan can be re-simulated from."""
    return all(key in rec for key in PARAMETER_KEYS)


def parameters_from_record(rec: Record) -> PlanParameters:
    """The plan parameters a (feasible) record holds."""
    approach = ApproachParameters(params=np.asarray(rec["approach_params"], dtype=float),
                                  base_offset_m=np.asarray(rec["base_offset_m"], dtype=float),
                                  start_delay_s=float(rec["start_delay_s"]),
                                  q_tracking=np.asarray(rec["q_tracking"], dtype=float))
    return PlanParameters(approach, np.asarray(rec["stabilization_params"], dtype=float))
