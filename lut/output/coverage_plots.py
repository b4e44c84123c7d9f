"""Coverage maps of a look-up table: where on the grid plans are feasible, what they cost, how long they took.

One PNG per quantity, over the grid's *varying* axes (axes with one value are fixed and named in the
title): ``coverage_status.png`` (pending / feasible / infeasible / failed), ``coverage_min_distance_m.png``
(smallest collision distance, m), ``coverage_peak_grasp_torque_nm.png`` (N·m) when the table has it, and
``coverage_solve_time_s.png`` (s). The layout follows the number of varying axes:

* 0 or 1 — a line (numbers) or a strip of coloured squares (status) along the axis;
* 2 — a heatmap, cell values printed when the grid is small;
* 3 or more — small multiples: the two axes with the most values make each heatmap, one panel per
  combination of the other axes' values (columns: the last of them, at most :data:`MAX_COLUMNS` wide;
  rows: the rest), one colour scale for all panels; past :data:`MAX_PANELS` panels the figure continues
  in ``…_2.png``, ``…_3.png``.

Points are numbered in C order over ``table.axis_names`` (:mod:`lut.table.grid`). A value the table does not
hold for a point (NaN: pending, failed, …) is left hatched.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from numpy.typing import NDArray

from lut.output.plot_style import new_figure, save_figure
from lut.table.schema import STATUS_CODES
from lut.table.store import Table

Array = NDArray[np.float64]
MAX_PANELS = 48  # per figure: beyond it the panels get too small to read
MAX_COLUMNS = 9  # panels side by side
ANNOTATE_MAX_CELLS = 150  # print the cell values when a figure has at most this many cells
STATUS_COLORS = {"pending": "#bdbdbd", "feasible": "#2ca02c", "infeasible": "#ff7f0e", "failed": "#d62728"}
QUANTITIES = (  # (table field, file stem, label with unit)
    ("status", "status", "point status"),
    ("costs/min_distance_m", "min_distance_m", "min collision distance [m]"),
    ("costs/peak_grasp_torque_nm", "peak_grasp_torque_nm", "peak grasp torque [N·m]"),
    ("solve_time_s", "solve_time_s", "solve time [s]"),
    ("robustness/success_probability", "robust_success", "success probability (build --robust)"),
)


def axis_label(name: str) -> str:
    """``spin_rate_deg_s`` → ``spin rate [deg/s]``: the unit suffix of a grid axis name as a bracket."""
    for suffix, unit in (("_deg_s", "deg/s"), ("_deg", "deg")):
        if name.endswith(suffix):
            return f"{name[: -len(suffix)].replace('_', ' ')} [{unit}]"
    return name.replace("_", " ")


def _edges(values: Array) -> Array:
    """Cell edges around the axis values (midpoints; a lone value gets ±0.5)."""
    v = np.asarray(values, dtype=float)
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = (v[:-1] + v[1:]) / 2
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


class _Style:
    """How one quantity is coloured: the status categories, or a continuous scale over its finite values."""

    def __init__(self, field: str, values: Array) -> None:
        self.categorical = field == "status"
        if self.categorical:
            self.cmap = ListedColormap([STATUS_COLORS[name] for name in STATUS_CODES])
            self.norm = BoundaryNorm(np.arange(len(STATUS_CODES) + 1) - 0.5, len(STATUS_CODES))
        else:
            finite = values[np.isfinite(values)]
            lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
            self.cmap = "viridis"
            self.norm = None
            self.vmin, self.vmax = lo, hi if hi > lo else lo + 1e-12

    def kwargs(self) -> dict:
        if self.categorical:
            return {"cmap": self.cmap, "norm": self.norm}
        return {"cmap": self.cmap, "vmin": self.vmin, "vmax": self.vmax}

    def text(self, value: float) -> str:
        if not np.isfinite(value):
            return ""
        if self.categorical:
            return {code: name[:4] for name, code in STATUS_CODES.items()}[int(value)]
        return f"{value:.3g}"


def _status_legend(fig_or_ax: Figure | Axes) -> None:
    handles = [Patch(color=color, label=name) for name, color in STATUS_COLORS.items()]
    fig_or_ax.legend(handles=handles, loc="outside lower center" if hasattr(fig_or_ax, "subfigs") else "best",
                     ncols=4, fontsize=8)


def _heatmap(ax: Axes, x: Array, y: Array, grid: Array, style: _Style, annotate: bool) -> object:
    """``grid[i_y, i_x]`` as coloured cells over the axis values, values printed if ``annotate``.

    Cells without a value (NaN) show the hatched background.
    """
    ax.patch.set_facecolor("white")
    ax.patch.set_hatch("////")
    ax.patch.set_edgecolor("0.8")
    mesh = ax.pcolormesh(_edges(x), _edges(y), np.ma.masked_invalid(grid), shading="flat", **style.kwargs())
    if annotate:
        for (iy, ix), value in np.ndenumerate(grid):
            ax.text(x[ix], y[iy], style.text(value), ha="center", va="center", fontsize=7, color="white"
                    if style.categorical else "black", bbox=None if style.categorical else
                    {"facecolor": "white", "alpha": 0.6, "edgecolor": "none", "pad": 0.5})
    ax.set_xticks(x)
    ax.set_yticks(y)
    ax.tick_params(labelsize=7)
    return mesh


def _line(ax: Axes, x: Array, values: Array, style: _Style, ylabel: str) -> None:
    if style.categorical:
        colors = [STATUS_COLORS[name] for name in STATUS_CODES]
        ax.scatter(x, np.zeros_like(x), c=[colors[int(v)] for v in values], marker="s", s=140)
        ax.set_yticks([])
        ax.set_ylim(-1, 1)
        _status_legend(ax)
    else:
        ax.plot(x, values, "o-", color="tab:blue")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    ax.set_xticks(x)


def _coverage_figures(table: Table, field: str, stem: str, label: str, out_dir: Path) -> list[Path]:
    """The figure(s) of one quantity: a line for at most one varying axis, heatmap pages otherwise."""
    values = np.asarray(table.field(field), dtype=float)
    shape = tuple(len(v) for v in table.axis_values)
    cube = values.reshape(shape)
    varying = [i for i, n in enumerate(shape) if n > 1]
    fixed = [f"{table.axis_names[i]} = {table.axis_values[i][0]:g}" for i, n in enumerate(shape) if n == 1]
    title = f"Coverage: {label} — {table.path.name} ({table.n_points} points" + \
            (f"; fixed {', '.join(fixed)})" if fixed else ")")
    style = _Style(field, values)
    if len(varying) <= 1:
        i = varying[0] if varying else 0
        fig = new_figure(8, 3.6)
        ax = fig.add_subplot()
        _line(ax, table.axis_values[i], cube.reshape(-1), style, label)
        ax.set_xlabel(axis_label(table.axis_names[i]))
        return [save_figure(fig, out_dir / f"coverage_{stem}.png", title)]
    layout = _PanelLayout.of(shape, varying)
    pages = layout.pages()
    written = []
    for page_no, page in enumerate(pages, start=1):
        fig = _panel_page(table, cube, layout, page, style, label)
        name = f"coverage_{stem}.png" if page_no == 1 else f"coverage_{stem}_{page_no}.png"
        page_title = title if len(pages) == 1 else f"{title} [page {page_no}/{len(pages)}]"
        written.append(save_figure(fig, out_dir / name, page_title))
    return written


@dataclass(frozen=True)
class _PanelLayout:
    """Which grid axes make each heatmap (``ix``, ``iy``), its panel rows and its panel columns."""

    shape: tuple[int, ...]
    varying: list[int]
    ix: int
    iy: int
    row_axes: list[int]
    col_axes: list[int]

    @classmethod
    def of(cls, shape: tuple[int, ...], varying: list[int]) -> _PanelLayout:
        # the two axes with the most values make the heatmaps (ties: the later, faster-varying axis)
        ix, iy = sorted(varying, key=lambda i: (shape[i], i))[-2:][::-1]
        panel_axes = [i for i in varying if i not in (ix, iy)]
        # panel columns: the last panel axes, while at most MAX_COLUMNS panels wide; rows: the others
        col_axes: list[int] = []
        for i in reversed(panel_axes):
            if math.prod(shape[j] for j in [i, *col_axes]) > MAX_COLUMNS:
                break
            col_axes.insert(0, i)
        row_axes = [i for i in panel_axes if i not in col_axes]
        return cls(shape, varying, ix, iy, row_axes, col_axes)

    @property
    def single(self) -> bool:
        return not self.row_axes and not self.col_axes

    @property
    def cols(self) -> list[tuple[int, ...]]:
        return list(itertools.product(*[range(self.shape[i]) for i in self.col_axes]))

    def pages(self) -> list[list[tuple[int, ...]]]:
        """The panel rows (index tuples over :attr:`row_axes`), at most :data:`MAX_PANELS` panels a page."""
        rows = list(itertools.product(*[range(self.shape[i]) for i in self.row_axes]))
        rows_per_page = max(1, MAX_PANELS // len(self.cols))
        return [rows[k:k + rows_per_page] for k in range(0, len(rows), rows_per_page)]


def _panel_page(table: Table, cube: Array, layout: _PanelLayout, page: list[tuple[int, ...]], style: _Style,
                label: str) -> Figure:
    """One page of heatmap panels (rows of ``page`` × every column) with its legend or colour bar."""
    shape, ix, iy, cols = layout.shape, layout.ix, layout.iy, layout.cols
    nrows, ncols = len(page), len(cols)
    panel_in = 5.0 if layout.single else 2.7
    fig = new_figure(max(6.5, panel_in * 1.15 * ncols + 1.2), panel_in * nrows + 1.3)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    annotate = nrows * ncols * shape[ix] * shape[iy] <= ANNOTATE_MAX_CELLS
    mesh = None
    for r, row in enumerate(page):
        for c, col in enumerate(cols):
            ax = axes[r, c]
            index: list[object] = [slice(None) if i in layout.varying else 0 for i in range(len(shape))]
            chosen = list(zip(layout.row_axes, row, strict=True)) + list(zip(layout.col_axes, col, strict=True))
            for i, k in chosen:
                index[i] = k
            grid = cube[tuple(index)]  # remaining dims in axis order: (iy, ix) if iy < ix
            if iy > ix:
                grid = grid.T
            mesh = _heatmap(ax, table.axis_values[ix], table.axis_values[iy], grid, style, annotate)
            if chosen:
                ax.set_title(", ".join(f"{_short(table.axis_names[i])} = {table.axis_values[i][k]:g}"
                                       for i, k in chosen), fontsize=7)
            if r == nrows - 1:
                ax.set_xlabel(axis_label(table.axis_names[ix]), fontsize=8)
            if c == 0:
                ax.set_ylabel(axis_label(table.axis_names[iy]), fontsize=8)
    if style.categorical:
        _status_legend(fig)
    elif mesh is not None:
        fig.colorbar(mesh, ax=axes.ravel().tolist(), label=f"{label}  (hatched: no value)",
                     shrink=0.9 if nrows > 1 else 1.0)
    return fig


def _short(name: str) -> str:
    """Axis name without its unit suffix, for panel titles."""
    for suffix in ("_deg_s", "_deg"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def write_coverage_maps(table: Table, out_dir: str | Path) -> list[Path]:
    """Write the coverage maps of ``table`` into ``out_dir`` (created if missing); return the paths written.

    Quantities the table lacks (e.g. ``costs/peak_grasp_torque_nm``) are skipped.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for field, stem, label in QUANTITIES:
        if table.has_field(field):
            written += _coverage_figures(table, field, stem, label, out)
    return written
