"""A look-up table's grid config: which scenario, which kind of state family, and the axes over it.

A grid config (TOML, see ``configs/grids/*.toml``) names a scenario, a kind and axes
``{name, min, max, count}``; every axis the config omits is fixed (a single value) at the scenario
default state's coordinate (:class:`lut.table.grid.Grid`). Axis values are in degrees (``_deg``) and
degrees per second (``_deg_s``). What the axes mean: :mod:`lut.table.grid` and docs/table.md, Grid.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from planner.config.limits import MAX_GRID_POINTS
from planner.config.toml_table import TomlTable as _Table
from planner.config.toml_table import parse_toml
from planner.config.toml_table import read_toml as _read_toml

Array = NDArray[np.float64]

KINDS = ("flat_spin", "tumble")
AXIS_NAMES: dict[str, tuple[str, ...]] = {
    "flat_spin": ("spin_rate_deg_s", "spin_axis_angle_deg", "spin_phase_deg"),
    "tumble": ("omega_x_deg_s", "omega_y_deg_s", "omega_z_deg_s", "roll_deg", "pitch_deg", "yaw_deg"),
}
PHASE_AXIS = "spin_phase_deg"
# angles whose value is only defined modulo 360: a state's coordinate is taken in the axis' window
ANGLE_AXES = frozenset({"spin_axis_angle_deg", "spin_phase_deg", "roll_deg", "yaw_deg"})


@dataclass(frozen=True)
class Axis:
    """One grid axis: ``count`` evenly spaced values from ``min`` to ``max`` (count 1: ``min == max``)."""

    name: str
    min: float
    max: float
    count: int

    def values(self) -> Array:
        if self.count == 1:
            return np.array([float(self.min)])
        return np.linspace(self.min, self.max, self.count)

    @property
    def step(self) -> float:
        """Spacing of the values (0 for a single value)."""
        return 0.0 if self.count == 1 else (self.max - self.min) / (self.count - 1)

    @property
    def periodic(self) -> bool:
        """True when the axis wraps at 360° (the last value and the first one + 360° enclose a cell): the spin
        phase always (the flat spin's symmetry), any other angle when its values go round the whole turn, one
        step apart across the wrap."""
        if self.name == PHASE_AXIS:
            return True
        return self.name in ANGLE_AXES and self.count > 1 and abs(self.max + self.step - self.min - 360.0) <= 1e-9 * 360


@dataclass(frozen=True)
class GridConfig:
    """A validated grid config; ``axes`` as the file gives them (omitted axes are added by :class:`Grid`)."""

    source: str
    text: str
    name: str
    scenario_path: Path
    kind: str
    axes: tuple[Axis, ...]


def load_grid(path: str | Path) -> GridConfig:
    """Read and validate a grid config TOML file; its ``scenario`` is relative to the file's folder."""
    path = Path(path)
    data, text = _read_toml(path)
    return _parse_grid(data, text, str(path), path.parent, None)


def load_grid_text(text: str, source: str, scenario_path: str | Path | None = None) -> GridConfig:
    """Validate grid config ``text`` (e.g. stored in a table); ``source`` names it in errors.

    ``scenario_path`` overrides the config's ``scenario`` field (which is still validated); without
    it, a relative ``scenario`` is taken relative to the folder of ``source``.
    """
    data = parse_toml(text, source)
    override = None if scenario_path is None else Path(scenario_path)
    return _parse_grid(data, text, source, Path(source).parent, override)


def _parse_grid(data: dict, text: str, source: str, base_dir: Path, scenario_override: Path | None) -> GridConfig:
    t = _Table(data, source)
    name = t.string("name")
    if not name.strip():
        raise t.error("name", "must not be empty")
    scenario = t.string("scenario")
    if scenario_override is not None:
        scenario_path = scenario_override
    else:
        scenario_path = Path(os.path.normpath((base_dir / scenario).absolute()))
        if not scenario_path.is_file():
            raise t.error("scenario", f"file not found: {scenario_path}")
    kind = t.string("kind", choices=KINDS)
    allowed = AXIS_NAMES[kind]
    axes: list[Axis] = []
    seen: dict[str, str] = {}
    for a in t.tables("axes"):
        axis_name = a.string("name")
        if axis_name not in allowed:
            raise a.error("name", f"unknown axis {axis_name!r} for kind {kind!r}; expected one of {', '.join(allowed)}")
        if axis_name in seen:
            raise a.error("name", f"duplicate axis {axis_name!r} (also {seen[axis_name]})")
        seen[axis_name] = a.field("name")
        lo = a.number("min")
        hi = a.number("max")
        count = a.number("count", integer=True)
        a.finish()
        axes.append(_check_axis(a, Axis(axis_name, lo, hi, int(count))))
    t.finish()
    n_points = math.prod(ax.count for ax in axes)
    if n_points > MAX_GRID_POINTS:
        raise t.error("axes", f"the grid has {n_points} points, more than {MAX_GRID_POINTS} (sanity limit): "
                      "check the counts")
    return GridConfig(source, text, name, scenario_path, kind, tuple(axes))


def _check_axis(a: _Table, axis: Axis) -> Axis:
    if axis.count < 1:
        raise a.error("count", f"must be >= 1, got {axis.count}")
    if axis.min > axis.max:
        raise a.error("max", f"must be >= min ({axis.min:g}), got {axis.max:g}")
    if axis.count == 1 and axis.min != axis.max:
        raise a.error("count", f"count = 1 needs min == max, got min {axis.min:g}, max {axis.max:g}")
    if axis.count > 1 and axis.min == axis.max:
        raise a.error("count", f"count = {axis.count} needs max > min (the points would coincide)")
    if axis.name == "spin_rate_deg_s" and axis.min <= 0:
        raise a.error("min", f"a flat spin needs a spin rate > 0, got {axis.min:g}")
    if axis.name in ANGLE_AXES and axis.max - axis.min >= 360:
        raise a.error("max", f"max - min must be < 360 (an angle {360:g}° away is the same state), "
                             f"got {axis.max - axis.min:g}")
    if axis.name == "pitch_deg":
        for key, value in (("min", axis.min), ("max", axis.max)):
            if not -90 < value < 90:
                raise a.error(key, f"pitch must be inside (-90, 90) (roll-pitch-yaw is singular at ±90°), "
                                   f"got {value:g}")
    return axis
