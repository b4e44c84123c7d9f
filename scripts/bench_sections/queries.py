"""``query``: latency and quality of table queries over seeded in-grid states, and the peak memory of
one ``lutgen query`` process."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bench_sections.common import ROOT, Settings, relative, skipped, stats_p95, table_query

if TYPE_CHECKING:
    from lut.query.table_query import TableQuery
    from lut.table.grid import Grid
    from planner.model.target import TargetState

# lut.query.table_query starts no refine when less than MIN_REFINE_S is left after FINISH_RESERVE_S: a 1 s budget
# measures the table alone (lookup, interpolation, re-simulation, verification),
# as tests/lut/query/test_ci_table.py does
NO_REFINE_BUDGET_S = 1.0
REFINE_KEYS = ("refine_s", "query_with_refine_total_s", "fraction_feasible_after_refine", "refined_queries",
               "queries_over_budget", "budget_s")


def in_grid_states(grid: Grid, n: int, seed: int) -> list[TargetState]:
    """``n`` states drawn uniformly (seeded) from the box of the grid's axis values."""
    rng = np.random.default_rng(seed)
    coords = np.column_stack([rng.uniform(v.min(), v.max(), size=n) for v in grid.axis_values])
    return [grid.state_at(c) for c in coords]


def _interpolation_only(tq: TableQuery, states: list[TargetState]) -> tuple[dict[str, Any], list[TargetState]]:
    """Lookup + interpolation, simulate, verify per state; feasibility from the table alone."""
    lat: dict[str, list[float]] = {"lookup_interpolate_s": [], "simulate_s": [], "verify_s": [], "total_s": []}
    sources: dict[str, int] = {}
    infeasible = []
    for state in states:
        res = tq.query(state, budget_s=NO_REFINE_BUDGET_S)
        for key, samples in lat.items():
            samples.append(res.latency_s[key])
        sources[res.source.value] = sources.get(res.source.value, 0) + 1
        if not res.report.feasible:
            infeasible.append((state, res.report.violations))
    out = {"lookup_interpolate_ms": stats_p95([1e3 * t for t in lat["lookup_interpolate_s"]]),
           "simulate_s": stats_p95(lat["simulate_s"]), "verify_s": stats_p95(lat["verify_s"]),
           "query_total_s": stats_p95(lat["total_s"]),
           "fraction_feasible_interpolation": 1.0 - len(infeasible) / len(states), "sources": sources,
           "first_violations": infeasible[0][1][:3] if infeasible else []}
    return out, [s for s, _ in infeasible]


def _refine(tq: TableQuery, states: list[TargetState], n_states: int, n_interp_ok: int,
            budget_s: float) -> dict[str, Any]:
    """Re-query the infeasible states with a budget that allows the warm-started refine solve."""
    if not states:
        return skipped("every interpolated plan was feasible: nothing to refine", REFINE_KEYS) | {
            "fraction_feasible_after_refine": n_interp_ok / n_states, "refined_queries": 0, "budget_s": budget_s}
    refine, total, ok, over = [], [], 0, 0
    for state in states:
        res = tq.query(state, budget_s=budget_s)
        refine.append(res.latency_s.get("refine_s", 0.0))
        total.append(res.latency_s["total_s"])
        ok += bool(res.report.feasible)
        over += res.latency_s["total_s"] > budget_s
    return {"refine_s": stats_p95(refine), "query_with_refine_total_s": stats_p95(total),
            "fraction_feasible_after_refine": (n_interp_ok + ok) / n_states, "refined_queries": len(states),
            "queries_over_budget": over, "budget_s": budget_s}


def query_process_memory(table: Path, state: TargetState) -> dict[str, Any]:
    """Peak RSS (MiB) and wall time (s) of one ``lutgen query`` process, table alone (no refine).

    A small Python wrapper runs the CLI and reads ``getrusage(RUSAGE_CHILDREN)``: its only child is the
    query, so the figure is that process's own peak, whatever else this benchmark has spawned before.
    """
    att = ",".join(f"{x:.12f}" for x in state.attitude_wxyz)
    omega = ",".join(f"{x:.12f}" for x in np.degrees(state.omega_body_rad_s))
    wrapper = ("import resource, subprocess, sys; rc = subprocess.run(sys.argv[1:]).returncode; "
               "print('RUSAGE', rc, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    with tempfile.TemporaryDirectory(prefix="lutgen-bench-") as tmp:
        cli = [sys.executable, "-c", "from lut.cli.main import main; main()", "query", str(table), "--attitude", att,
               "--omega-deg-s", omega, "--budget-s", str(NO_REFINE_BUDGET_S), "--out", str(Path(tmp) / "plan.json")]
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", wrapper, *cli], capture_output=True, text=True, cwd=ROOT)
        wall = time.perf_counter() - t0
    last = proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else ""
    if proc.returncode != 0 or not last.startswith("RUSAGE"):
        raise RuntimeError(f"the query process wrapper failed: {proc.stderr[-2000:]}")
    _, rc, maxrss = last.split()
    if int(rc) not in (0, 2):  # 0 feasible, 2 infeasible: both are answered queries
        raise RuntimeError(f"lutgen query exited {rc}: {proc.stderr[-2000:]}")
    kib = int(maxrss) / (1024 if sys.platform == "darwin" else 1)  # ru_maxrss: bytes on macOS, KiB on Linux
    return {"peak_memory_query_process_mib": kib / 1024, "query_process_wall_s": wall,
            "query_process_exit_code": int(rc)}


def queries(settings: Settings) -> dict[str, Any]:
    """The whole section."""
    tq = table_query(settings.query_table)
    states = in_grid_states(tq.grid, settings.query_states, settings.seed)
    interp, infeasible = _interpolation_only(tq, states)
    n_ok = len(states) - len(infeasible)
    if settings.refine_budget_s is None:
        refine = skipped("no refine in quick mode (a refine solve takes minutes)", REFINE_KEYS)
    else:
        refine = _refine(tq, infeasible, len(states), n_ok, settings.refine_budget_s)
    return {"table": relative(settings.query_table), "states": len(states), "seed": settings.seed,
            "grid_axes": tq.grid.axis_names, "table_load_s": tq.load_time_s, **interp, "refine": refine,
            **query_process_memory(settings.query_table, states[0])}
