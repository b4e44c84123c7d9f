"""``lutgen build --reuse``: other tables' feasible plans at the points a grid shares with them, and the warm-start
tree that grows the rest of the grid from them (the cheapest of a point's nearest reused neighbours first).

A warm-started build keeps each point in its parent's local minimum, so a grid refined in the build (an axis
value added between two solved ones) inherits whatever minimum its own continuation tree happens to reach from its
seed. With ``--reuse`` the points the grid shares with a table already built (same robot, target, scenario and
grid kind; coordinates equal within :data:`lut.table.grid.COORD_TOL`) take that table's feasible plans as they
are (the cheapest where several tables hold a point: a point solved from more than one start), and every other
point starts from an adjacent reused point, the one with the lowest weighted approach cost (paper Eq. 14–16) where
several are adjacent; points further away grow from those, breadth first.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from lut.table.grid import Grid
from lut.table.point_result import PointResult, PointStatus
from lut.table.provenance import ReusedSource, provenance_text
from lut.table.records import from_record, parameter_fields
from lut.table.schema import TableError
from lut.table.store import Table
from planner.config.scenario import Scenario
from planner.errors import LutgenError

Continuation = list[tuple[int, int | None]]  # (point, its warm-start parent or None), in solving order
CostOf = Callable[[PointResult], float]


@dataclass(frozen=True)
class ReusedPlans:
    """The plans ``--reuse`` takes: ``results`` (this grid's point → result) and ``sources`` (point → the index of
    the table it came from in ``tables``, the paths as given, built at ``built_utc``); empty without ``--reuse``."""

    tables: tuple[str, ...] = ()
    built_utc: tuple[str, ...] = ()
    results: dict[int, PointResult] = field(default_factory=dict)
    sources: dict[int, int] = field(default_factory=dict)

    def kept_in(self, done: dict[int, PointResult]) -> ReusedPlans:
        """These plans less those the build replaced (``--polish`` found a cheaper one): what the table keeps."""
        kept = {p for p, r in self.results.items() if p in done and same_plan(done[p], r)}
        return replace(self, results={p: r for p, r in self.results.items() if p in kept},
                       sources={p: k for p, k in self.sources.items() if p in kept})

    def provenance(self, table_dir: Path) -> str:
        """The table attribute ``reused_from`` (:mod:`lut.table.provenance`): per reused table, in the order given,
        its path relative to ``table_dir`` (the new table's folder), when it was built and the points taken from it."""
        return provenance_text([ReusedSource(os.path.relpath(Path(path).absolute(), table_dir.absolute()),
                                             built, tuple(sorted(p for p, i in self.sources.items() if i == k)))
                                for k, (path, built) in enumerate(zip(self.tables, self.built_utc, strict=True))])


def same_plan(a: PointResult, b: PointResult) -> bool:
    """Whether two results hold the same plan parameters, bit for bit (or neither holds any)."""
    if a.parameters is None or b.parameters is None:
        return a.parameters is None and b.parameters is None
    fa, fb = parameter_fields(a.parameters), parameter_fields(b.parameters)
    return fa.keys() == fb.keys() and all(np.array_equal(fa[k], fb[k]) for k in fa)


def cheapest_reused(table_paths: Sequence[str | Path], grid: Grid, grid_kind: str, model_hash: str,
                    cost_of: CostOf) -> ReusedPlans:
    """:func:`reused_points` of every table; where several hold a point, the plan with the lowest ``cost_of`` (a
    NaN cost loses; a tie keeps the table given first)."""
    chosen: dict[int, PointResult] = {}
    sources: dict[int, int] = {}
    tables = [_opened(path) for path in table_paths]
    for k, table in enumerate(tables):
        for point, result in reused_points(table, grid, grid_kind, model_hash).items():
            if point not in chosen or cost_or_inf(result, cost_of) < cost_or_inf(chosen[point], cost_of):
                chosen[point] = result
                sources[point] = k
    return ReusedPlans(tuple(str(p) for p in table_paths), tuple(str(t.attrs["created_utc"]) for t in tables),
                       chosen, sources)


def _opened(table_path: str | Path) -> Table:
    """The table ``--reuse`` names, or :class:`LutgenError` naming ``--reuse`` when it cannot be read."""
    try:
        return Table.open(table_path)
    except TableError as exc:
        raise LutgenError(f"--reuse: {exc}") from None


def reused_points(table: Table, grid: Grid, grid_kind: str, model_hash: str) -> dict[int, PointResult]:
    """The feasible results of ``table`` at this grid's points, re-indexed to this grid (point → result).

    :class:`LutgenError` naming ``--reuse`` when the table answers for another model or grid kind, has other
    axes, or shares no feasible point with the grid.
    """
    table_path = table.path
    if table.model_hash != model_hash:
        raise LutgenError(f"--reuse {table_path}: built for another robot, target or scenario (model hash "
                          f"{table.model_hash[:12]}… against {model_hash[:12]}…); its plans are not this grid's")
    kind = table.attrs.get("grid_kind")
    if kind != grid_kind or table.axis_names != grid.axis_names:
        raise LutgenError(f"--reuse {table_path}: a {kind} table over ({', '.join(table.axis_names)}); this grid "
                          f"is {grid_kind} over ({', '.join(grid.axis_names)})")
    shape = tuple(len(v) for v in table.axis_values)
    found: dict[int, PointResult] = {}
    for p in np.flatnonzero(table.status == PointStatus.FEASIBLE.code):
        coords = [float(v[i]) for v, i in zip(table.axis_values, np.unravel_index(p, shape), strict=True)]
        point = grid.point_at(coords)
        if point is not None:
            found[point] = replace(from_record(table.record(int(p))), point=point)
    if not found:
        raise LutgenError(f"--reuse {table_path}: none of its feasible points lies on this grid (axes "
                          f"{', '.join(grid.axis_names)})")
    return found


def reuse_continuation(grid: Grid, reused: dict[int, PointResult], cost_of: CostOf) -> Continuation:
    """Every point once as ``(point, parent)``: the reused points first (no parent), then breadth first from all of
    them at once; a point's parent is its adjacent point of the layer before with the lowest ``cost_of`` (a point
    solved in this build has no cost yet: the lowest index among those)."""
    order: Continuation = [(p, None) for p in sorted(reused)]
    seen = set(reused)
    layer = sorted(reused)
    while layer:
        in_layer = set(layer)
        nxt = sorted({nb for p in layer for nb in grid.neighbours(p) if nb not in seen})
        for point in nxt:
            parents = [p for p in grid.neighbours(point) if p in in_layer]
            order.append((point, min(parents, key=lambda p: (cost_or_inf(reused.get(p), cost_of), p))))
        seen.update(nxt)
        layer = nxt
    return order


def cost_or_inf(result: PointResult | None, cost_of: CostOf) -> float:
    """The result's cost, +inf where there is none to compare (no result, no feasible plan, or a NaN cost)."""
    if result is None or result.status is not PointStatus.FEASIBLE:
        return math.inf
    value = cost_of(result)
    return value if math.isfinite(value) else math.inf


def weighted_cost(scenario: Scenario) -> CostOf:
    """The scenario's weighted approach cost (Eq. 14–16) of a feasible result's stored plan (0 for a
    feasibility-only scenario)."""
    from lut.table.plan_costs import CostScorer
    from planner.model.freefloating import FreeFloatingModel
    from planner.phases.approach import approach_spline

    scorer = CostScorer(scenario, FreeFloatingModel(scenario.robot), approach_spline(scenario))

    return lambda result: scorer.score_stored(f"point {result.point}", result).total
