"""A grid point's result as a flat record (``"/"``-separated keys → numbers, arrays, strings), and back.

The flat record is the storage form of a :class:`~lut.table.point_result.PointResult`: a point's child
process writes it as .npz, the build journal appends it, the HDF5 table stores one dataset per key
(docs/table.md, Store). Everything else handles the typed form; these functions are the only crossing.
No pickles anywhere.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from lut.table.point_result import PointResult, PointStatus
from planner.plan_parameters import ApproachParameters, PlanParameters

if TYPE_CHECKING:  # a record is read and written far from the planner (journal, table, a point's .npz)
    from planner.plan import GraspPlan
    from planner.verify.verifier import VerifyReport

Record = dict[str, Any]

# the plan parameters' keys, in record order (all numeric arrays or numbers a query interpolates)
PARAMETER_KEYS = ("approach_params", "base_offset_m", "start_delay_s", "q_tracking", "stabilization_params")
MAX_REASON_CHARS = 2000  # a failure reason is cut here: a record stays small
NOTES_KEY = "notes"  # a solve's notes, one per line, in the record a child process returns (never journaled)


def plan_costs(plan: GraspPlan, report: VerifyReport) -> dict[str, float]:
    """The verified costs a table stores (and a plan file shows): Eq. 16's approach energy [m²], the smallest
    distance [m], the peak grasp torque [N·m]."""
    from planner.nlp.costs import approach_energy  # only where a plan exists: a record is read far from CasADi

    return {"approach_energy_m2": approach_energy(plan.approach.base_offset_m),
            "min_distance_m": float(np.min(report.min_distance_m)),
            "peak_grasp_torque_nm": float(np.abs(report.grasp_wrench[:, 3:]).max())}


def result_from_plan(point: int, plan: GraspPlan, report: VerifyReport) -> PointResult:
    """The result of a solved, verified plan."""
    approach = ApproachParameters(params=np.asarray(plan.approach.params, dtype=float),
                                  base_offset_m=np.asarray(plan.approach.base_offset_m, dtype=float),
                                  start_delay_s=float(plan.approach.start_delay_s),
                                  q_tracking=np.asarray(plan.approach.q_tracking, dtype=float))
    return PointResult(point=point, status=PointStatus.FEASIBLE if report.feasible else PointStatus.INFEASIBLE,
                       failure_reason="; ".join(report.violations)[:MAX_REASON_CHARS],
                       solve_time_s=float(plan.timings_s.get("total_s", np.nan)),
                       iterations=int(plan.approach.iterations + plan.stabilization.iterations),
                       parameters=PlanParameters(approach, np.asarray(plan.stabilization.params, dtype=float)),
                       free_axis_angle_rad=float(plan.tracking.free_axis_angle_rad),
                       costs=plan_costs(plan, report),
                       margins={name: float(check.margin) for name, check in report.checks.items()},
                       notes=tuple(plan.notes))


def failed_result(point: int, reason: str, solve_time_s: float = float("nan")) -> PointResult:
    """A point that crashed or timed out: no parameters, the reason kept."""
    return PointResult(point, PointStatus.FAILED, reason[:MAX_REASON_CHARS], float(solve_time_s))


def out_of_reach_result(point: int, reason: str, solve_time_s: float) -> PointResult:
    """A point the planner proved infeasible before solving (:class:`planner.plan.OutOfReach`): no parameters."""
    return PointResult(point, PointStatus.INFEASIBLE, reason[:MAX_REASON_CHARS], float(solve_time_s))


def to_record(result: PointResult) -> Record:
    """The flat record of ``result`` (keys in the order the journal has always stored them)."""
    rec: Record = {"point": result.point, "status": result.status.value, "failure_reason": result.failure_reason,
                   "solve_time_s": result.solve_time_s, "iterations": result.iterations}
    if result.parameters is not None:
        rec.update(parameter_fields(result.parameters))
    if result.free_axis_angle_rad is not None:
        rec["free_axis_angle_rad"] = result.free_axis_angle_rad
    rec.update({f"costs/{name}": value for name, value in result.costs.items()})
    rec.update({f"margins/{name}": value for name, value in result.margins.items()})
    rec.update({f"robustness/{name}": value for name, value in result.robustness.items()})
    return rec


def from_record(rec: Record) -> PointResult:
    """The typed form of a flat record (of a journal, a point's .npz, or :meth:`lut.table.store.Table.record`).

    A table holds every field at every point (the missing value where a point has none, docs/table.md), so
    a table record of a failed point carries NaN parameters; only feasible points' are ever read. Keys
    outside the record schema (:func:`to_record`) are not carried.
    """
    free = rec.get("free_axis_angle_rad")
    return PointResult(point=int(rec["point"]), status=PointStatus(rec["status"]),
                       failure_reason=str(rec.get("failure_reason", "")),
                       solve_time_s=float(rec.get("solve_time_s", float("nan"))),
                       iterations=int(rec.get("iterations", 0)), parameters=parameters_from_fields(rec),
                       free_axis_angle_rad=None if free is None else float(free),
                       costs=_prefixed(rec, "costs/"), margins=_prefixed(rec, "margins/"),
                       robustness=_prefixed(rec, "robustness/"),
                       notes=tuple(line for line in str(rec.get(NOTES_KEY, "")).split("\n") if line))


def with_notes(rec: Record, result: PointResult) -> Record:
    """``rec`` (:func:`to_record` of ``result``) with the plan's notes, as a solve's child process returns it to the
    query or re-plan that asked (:func:`from_record` reads them back); the journal and table keep :func:`to_record`'s
    schema, without them."""
    notes = [note.replace("\n", " ") for note in result.notes]
    return {**rec, NOTES_KEY: "\n".join(notes)} if notes else rec


def _prefixed(rec: Record, prefix: str) -> dict[str, float]:
    return {key[len(prefix):]: float(value) for key, value in rec.items() if key.startswith(prefix)}


def parameter_fields(parameters: PlanParameters) -> Record:
    """The plan parameters as record fields (:data:`PARAMETER_KEYS`; no stabilization key when it has none)."""
    a = parameters.approach
    fields: Record = {"approach_params": a.params, "base_offset_m": a.base_offset_m,
                      "start_delay_s": a.start_delay_s, "q_tracking": a.q_tracking}
    if parameters.stabilization_params is not None:
        fields["stabilization_params"] = parameters.stabilization_params
    return fields


def parameters_from_fields(rec: Record) -> PlanParameters | None:
    """The plan parameters ``rec`` holds, ``None`` unless it holds every one of :data:`PARAMETER_KEYS`."""
    if not all(key in rec for key in PARAMETER_KEYS):
        return None
    approach = ApproachParameters(params=np.asarray(rec["approach_params"], dtype=float),
                                  base_offset_m=np.asarray(rec["base_offset_m"], dtype=float),
                                  start_delay_s=float(rec["start_delay_s"]),
                                  q_tracking=np.asarray(rec["q_tracking"], dtype=float))
    return PlanParameters(approach, np.asarray(rec["stabilization_params"], dtype=float))
