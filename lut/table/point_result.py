"""One grid point's outcome, typed: its status, why it failed, what the solve cost, and its plan parameters."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

from planner.plan_parameters import PlanParameters


class PointStatus(StrEnum):
    """Where a grid point stands; the value is the name a record and the printed text use."""

    PENDING = "pending"  # not solved yet
    FEASIBLE = "feasible"  # solved, and its plan passed verification
    INFEASIBLE = "infeasible"  # solved (or proved out of reach), and its plan failed verification
    FAILED = "failed"  # the solve crashed or exceeded its time limit: no plan

    @property
    def code(self) -> int:
        """The status code the HDF5 table stores (``points/status``, int8)."""
        return STATUS_CODES[self.value]


# the table's codes, by name (stored with the table as JSON, so the names are plain str)
STATUS_CODES: dict[str, int] = {"pending": 0, "feasible": 1, "infeasible": 2, "failed": 3}


@dataclass(frozen=True)
class PointResult:
    """The result of solving one grid point (or a query's refine, point -1).

    ``parameters``: what the plan is re-simulated from, ``None`` when the solve gave no plan (failed, or
    proved out of reach). ``costs`` by name without the ``costs/`` prefix (e.g. ``min_distance_m`` [m],
    ``approach_energy_m2`` [m²], ``peak_grasp_torque_nm`` [N·m]); ``margins`` per verification check
    (positive: satisfied), in that check's unit. ``robustness``: the figure a build with ``--robust`` records
    for a feasible point (:func:`lut.robustness.point_figure.point_robustness`; empty otherwise).
    """

    point: int
    status: PointStatus
    failure_reason: str = ""
    solve_time_s: float = float("nan")  # [s]
    iterations: int = 0  # IPOPT iterations of the approach and stabilization NLPs
    parameters: PlanParameters | None = None
    free_axis_angle_rad: float | None = None  # the tracking's free rotation about the grasp axis [rad]
    costs: dict[str, float] = field(default_factory=dict)
    margins: dict[str, float] = field(default_factory=dict)
    robustness: dict[str, float] = field(default_factory=dict)
    # the plan's notes (its grasps, re-solves, budget): a solve's child process hands them to the query that asked
    # for it (:func:`lut.table.records.with_notes`); a journal or table does not store them
    notes: tuple[str, ...] = ()
