"""The grid coordinates a table answers any valid target state at: on the grid, the state's own; off it, the nearest.

An estimator's state never lies exactly on a flat-spin family, and a target may spin a little faster than a
table's grid reaches: the table still gives its nearest parameters (the plan is then simulated and verified at
the observed state, and solved from there when it fails), and says how the state differs from what it holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from lut.table.grid import COORD_TOL, Grid
from planner.errors import TargetStateError
from planner.model.target import TargetState

Array = NDArray[np.float64]


@dataclass(frozen=True)
class GridProjection:
    """Where on the grid a state is answered: ``coords`` (n_axes,) [deg, deg/s], ``family`` the coordinates of the
    state's nearest family member before they were clamped into the grid, and why ``coords`` differ from the state's
    own coordinates (empty when the state is on the grid)."""

    coords: Array
    family: Array
    notes: tuple[str, ...] = ()


def project_to_grid(grid: Grid, state: TargetState) -> GridProjection:
    """The grid coordinates nearest ``state``: its family's nearest member, clamped into every bounded axis.

    A malformed state (shapes, NaN, inf) is still refused with ``TargetStateError``."""
    notes: list[str] = []
    try:
        coords = grid.coordinates_of_state(state)
    except TargetStateError as exc:
        coords = grid.family_coordinates(state)  # a malformed state raises here again
        notes.append(f"{exc}: the table answers at the nearest state of its family")
    clamped = np.array(coords, dtype=float)
    for i, ax in enumerate(grid.axes):
        if ax.periodic or ax.min - COORD_TOL <= coords[i] <= ax.max + COORD_TOL:
            continue
        clamped[i] = min(max(coords[i], ax.min), ax.max)
        notes.append(f"outside the grid: {ax.name} = {coords[i]:.10g} not in [{ax.min:.10g}, {ax.max:.10g}]; "
                     f"the table answers at {clamped[i]:.10g}")
    return GridProjection(clamped, np.array(coords, dtype=float), tuple(notes))
