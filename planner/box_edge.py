"""Where the chaser waits against its base-offset box: a plan refused with θ_b(0) on a bound of the box (the
scenario's ``robot.base_offset_x_m`` / ``base_offset_z_m``) ended where the box stopped it, so the grasp it lacks may
lie beyond where the chaser may wait, not beyond what the planner can find."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

# IPOPT ends a solve whose bound is active within ~1e-6 m of it; a millimetre is on the bound, not merely near it
BOX_EDGE_TOL_M = 1e-3
BOX_EDGE_NOTE = "refused with the chaser on its base-offset box's edge"
AXIS_FIELDS = (("x", "robot.base_offset_x_m"), ("z", "robot.base_offset_z_m"))
Box = tuple[tuple[float, float], tuple[float, float]]  # the scenario's base_offset_bounds_m: x, z [m]


@dataclass(frozen=True)
class BoxEdge:
    """θ_b(0) on one bound of the box along one orbital-plane axis."""

    axis: str  # "x" or "z"
    offset_m: float  # θ_b(0) along the axis [m]
    bounds_m: tuple[float, float]  # the box along the axis [m]
    field: str  # the scenario field that sets those bounds

    def describe(self) -> str:
        lo, hi = self.bounds_m
        return f"θ_b(0) {self.axis} = {self.offset_m:+.3f} m, {self.field} = [{lo:g}, {hi:g}]"


def box_edges(bounds_m: Box, base_offset_m: ArrayLike) -> tuple[BoxEdge, ...]:
    """The bounds θ_b(0) (``base_offset_m``, (x, z) [m]) lies on, within :data:`BOX_EDGE_TOL_M`; an axis whose bounds
    coincide (θ_b(0) pinned: a re-plan keeps where the chaser already waits) has no edge to stop at."""
    offset = np.asarray(base_offset_m, dtype=float)
    edges = []
    for (axis, field), (lo, hi), value in zip(AXIS_FIELDS, bounds_m, offset, strict=True):
        if hi - lo > 2 * BOX_EDGE_TOL_M and min(abs(value - lo), abs(hi - value)) <= BOX_EDGE_TOL_M:
            edges.append(BoxEdge(axis, float(value), (float(lo), float(hi)), field))
    return tuple(edges)


def box_edge_note(bounds_m: Box, base_offset_m: ArrayLike) -> str | None:
    """The note a refused plan carries when θ_b(0) lies on the box's edge (None when it does not): which bound, and
    that a wider box is the scenario's to allow."""
    edges = box_edges(bounds_m, base_offset_m)
    if not edges:
        return None
    where = "; ".join(e.describe() for e in edges)
    return (f"{BOX_EDGE_NOTE} ({where}): the grasp may lie beyond where the chaser may wait; a wider box is the "
            "scenario's to allow (the bundled *_wide variants allow ±2 m)")
