"""A table's parameter datasets checked against the scenario a query plans for, before anything is read."""

from __future__ import annotations

import numpy as np

from lut.table.point_result import PointStatus
from lut.table.schema import TableError
from lut.table.store import Table
from planner.config.scenario import Scenario
from planner.phases.approach import approach_spline
from planner.phases.stabilization import stabilization_spline
from planner.phases.tracking_profile import TRACKING_NODES


def parameter_shapes(scenario: Scenario) -> dict[str, tuple[int, ...]]:
    """Per-point shape of every parameter a query interpolates, for ``scenario``'s plans."""
    n = scenario.robot.n_joints
    approach = approach_spline(scenario)
    return {"approach_params": (n * approach.n_free_per_joint,), "base_offset_m": (2,), "start_delay_s": (),
            "q_tracking": (len(TRACKING_NODES), n),
            "stabilization_params": (n * stabilization_spline(scenario).n_free_per_joint,)}


def check_parameters(table: Table, shapes: dict[str, tuple[int, ...]]) -> None:
    """Raise :class:`TableError` unless every parameter dataset has the scenario's shape, holds floats, and is
    finite at every feasible point (what a query interpolates and re-simulates)."""
    feasible = table.status == PointStatus.FEASIBLE.code
    if not feasible.any():
        return  # nothing will be read from it: the query solves from scratch
    for key, shape in shapes.items():
        if not table.has_field(key):
            raise TableError(f"{table.path}: missing dataset points/{key}, which a query interpolates")
        data = table.field(key)
        if data.shape[1:] != shape:
            raise TableError(f"{table.path}: points/{key} has per-point shape {data.shape[1:]}; this scenario's "
                             f"plans have {shape}")
        if data.dtype.kind != "f":
            raise TableError(f"{table.path}: points/{key} must hold floats, got dtype {data.dtype}")
        bad = np.flatnonzero(~np.isfinite(data[feasible].reshape(int(feasible.sum()), -1)).all(axis=1))
        if bad.size:
            raise TableError(f"{table.path}: points/{key} is not finite at feasible point "
                             f"{int(np.flatnonzero(feasible)[bad[0]])}")
