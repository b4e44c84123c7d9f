"""Shared helpers of the benchmark: repository paths, per-mode settings, timing statistics, JSON hygiene."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # imported lazily at run time: a TableQuery builds a planner
    from lut.query.table_query import TableQuery
    from planner.config.scenario import Scenario

ROOT = Path(__file__).resolve().parents[2]
GOLDEN_TABLE = ROOT / "tests" / "data" / "ci_golden.h5"
DEMO_TABLE = ROOT / "out" / "demo.h5"  # what scripts/demo builds
SCENARIOS = ROOT / "configs" / "scenarios"
FAKE_SOLVER = "tests.support.fake_solver:solve"
COVERAGE_TABLES = ROOT / "tables"  # where the README's workflow 1 builds the bundled grids' tables
COVERAGE_BUDGET_S = 100.0  # issue 20: an operator has 100 s from observation to motion
OPTIMAL_TABLE = ROOT / "tables" / "flat_spin_I_energy.h5"  # configs/grids/flat_spin_I_energy.toml, built by hand


@dataclass(frozen=True)
class CoverageSettings:
    """The coverage section's sizes: seeded states per kind, which kinds (None: all four), the budget (s) of
    each plan and query, the hard kill after budget + ``kill_margin_s`` (s), processes at a time, the tables,
    whether the cold plans run (False: the queries alone, e.g. after a new table), the scenario variant they
    plan with (None: the bundled scenarios; ``NAME``: ``<scenario>_NAME.toml``), whether a failed plan's state is
    planned offline too (:mod:`bench_sections.offline_check`), and the variant it is planned with too (None: not;
    :mod:`bench_sections.variant_check`)."""

    states: int
    kinds: tuple[str, ...] | None
    budget_s: float
    kill_margin_s: float
    jobs: int
    tables: Path
    plans: bool = True
    variant: str | None = None
    offline_check: bool = False
    variant_check: str | None = None

    def scenario_of(self, scenario: str) -> str:
        """The scenario file's stem the section plans ``scenario``'s kinds with."""
        return scenario if self.variant is None else f"{scenario}_{self.variant}"


@dataclass(frozen=True)
class OptimalSettings:
    """The optimal section's sizes (issue 21): the optimal table, its seeded off-grid states, the query's budget
    and the offline optimum's (s)."""

    table: Path
    states: int
    query_budget_s: float
    optimum_budget_s: float
    optima: Path | None = None  # an earlier run's JSON whose offline optima are taken instead of planned again


@dataclass(frozen=True)
class Settings:
    """How much of everything one benchmark run measures (see :func:`settings_for`)."""

    mode: str  # "full" or "quick"
    trim: bool
    seed: int
    # primitives: µs per call over ``repeats`` batches of ≥ ``min_calls`` calls and ≥ ``min_batch_s`` s
    repeats: int
    min_calls: int
    min_batch_s: float
    verify_runs: int
    # query
    query_table: Path
    query_states: int
    refine_budget_s: float | None  # None: no refine
    # build (fake solver)
    build_grid: tuple[int, int]  # (rate count, phase count) of a generated flat-spin grid
    fake_point_s: float
    build_runs: int
    # planner (whole plans)
    plan_runs: int
    plan_cap_s: float
    plan_with_costs: bool
    # baseline (approach NLP)
    baseline_cap_s: float
    baseline_max_iter: int
    baseline_max_delay_s: float | None  # None: the scenario's own start-delay window
    coverage: CoverageSettings
    optimal: OptimalSettings | None = None  # None: the section is skipped
    reach_plot: Path | None = None  # the reach section's figure goes here (None: no figure)


OPTIMUM_BUDGET_S = 600.0  # the offline optimum's default budget: scenario I's optima end far inside it


def optimal_settings(quick: bool, trim: bool, table: Path | None, states: int | None,
                     optimum_budget_s: float | None = None, optima: Path | None = None) -> OptimalSettings:
    """Full: 30 states (the issue's bar); quick: 2; trim: 1 on the golden table (feasibility-only: the section
    proves its code path and says there is no optimum to compare). ``optimum_budget_s`` [s] (default
    :data:`OPTIMUM_BUDGET_S`) bounds each offline optimum; ``optima``: an earlier run's JSON to take them from."""
    default_table, default_states = (GOLDEN_TABLE, 1) if trim else (OPTIMAL_TABLE, 2 if quick else 30)
    return OptimalSettings(default_table if table is None else table, default_states if states is None else states,
                           COVERAGE_BUDGET_S, OPTIMUM_BUDGET_S if optimum_budget_s is None else optimum_budget_s,
                           optima)


def coverage_settings(quick: bool, trim: bool, states: int | None, jobs: int, tables: Path | None,
                      kinds: tuple[str, ...] | None = None, plans: bool = True,
                      variant: str | None = None, offline_check: bool = False,
                      variant_check: str | None = None, budget_s: float | None = None) -> CoverageSettings:
    """Full: 20 states of each kind (the issue's bar); quick: 1 of each; trim: 1 of one kind, a 2 s budget, the
    golden table (it proves the code path in seconds: the plan ends over budget). ``kinds`` (None: all four, or
    trim's one) and ``plans`` (False: queries only) narrow any mode; ``offline_check`` plans each failure's state
    offline as well, ``variant_check`` with that scenario variant as well; ``budget_s`` [s] is each plan's and
    query's budget (None: :data:`COVERAGE_BUDGET_S`, trim's 2 s)."""
    if trim:
        return CoverageSettings(1 if states is None else states, kinds or ("scenario_II_flat_spin",),
                                2.0 if budget_s is None else budget_s, 10.0, jobs,
                                GOLDEN_TABLE.parent if tables is None else tables, plans, variant, offline_check,
                                variant_check)
    default_states = 1 if quick else 20
    return CoverageSettings(default_states if states is None else states, kinds,
                            COVERAGE_BUDGET_S if budget_s is None else budget_s, 30.0, jobs,
                            COVERAGE_TABLES if tables is None else tables, plans, variant, offline_check,
                            variant_check)


def settings_for(quick: bool, trim: bool, seed: int, plan_runs: int | None, plan_cap_s: float,
                 plan_with_costs: bool, refine_budget_s: float, coverage: CoverageSettings) -> Settings:
    """Settings of a full, ``--quick`` or ``--trim`` run (trim implies quick: everything as small as it gets)."""
    full = not (quick or trim)
    table = DEMO_TABLE if full and DEMO_TABLE.is_file() else GOLDEN_TABLE
    # a 30 s start-delay window scans a third of the meeting times and, for scenario II's default state,
    # leads IPOPT to the same solution as the scenario's 90 s window
    common = {"seed": seed, "query_table": table, "plan_cap_s": plan_cap_s, "plan_with_costs": plan_with_costs,
              "coverage": coverage}
    if full:
        return Settings("full", False, repeats=5, min_calls=1000, min_batch_s=0.5, verify_runs=5, query_states=50,
                        refine_budget_s=refine_budget_s, build_grid=(4, 4), fake_point_s=2.0, build_runs=3,
                        plan_runs=1 if plan_runs is None else plan_runs, baseline_cap_s=300.0,
                        baseline_max_iter=1000, baseline_max_delay_s=None, **common)
    if not trim:
        return Settings("quick", False, repeats=5, min_calls=200, min_batch_s=0.1, verify_runs=3, query_states=10,
                        refine_budget_s=None, build_grid=(2, 3), fake_point_s=0.5, build_runs=1,
                        plan_runs=1 if plan_runs is None else plan_runs, baseline_cap_s=60.0,
                        baseline_max_iter=200, baseline_max_delay_s=30.0, **common)
    # trim: 2 query states, not 3: each costs ~7 s and the test that runs this should stay under a minute
    return Settings("quick", True, repeats=3, min_calls=50, min_batch_s=0.02, verify_runs=1, query_states=2,
                    refine_budget_s=None, build_grid=(1, 2), fake_point_s=0.0, build_runs=1,
                    plan_runs=0 if plan_runs is None else plan_runs, baseline_cap_s=20.0, baseline_max_iter=1,
                    baseline_max_delay_s=30.0, **common)


# ---- statistics ----------------------------------------------------------------------------------------


def stats(samples: Sequence[float]) -> dict[str, float | int]:
    """``{"median", "min", "max", "runs"}`` of ``samples`` (same unit as the samples)."""
    a = np.asarray(samples, dtype=float)
    return {"median": float(np.median(a)), "min": float(a.min()), "max": float(a.max()), "runs": int(a.size)}


def stats_p95(samples: Sequence[float]) -> dict[str, float | int]:
    """:func:`stats` plus the 95th percentile (latency distributions)."""
    return {**stats(samples), "p95": float(np.percentile(np.asarray(samples, dtype=float), 95))}


def skipped(reason: str, keys: Sequence[str] = ()) -> dict[str, Any]:
    """A part not measured in this mode: its keys with null values and the reason."""
    return {**dict.fromkeys(keys), "skipped": reason}


def time_per_call_us(fn: Callable[[], object], settings: Settings) -> dict[str, float | int]:
    """µs per call of ``fn``: median over ``settings.repeats`` batches of equal size, each batch at least
    ``settings.min_calls`` calls and ``settings.min_batch_s`` long (one batch is timed as a whole, so
    the timer's own cost and resolution do not enter a µs-scale call)."""
    fn()  # lazy initialisation (CasADi buffers, FCL objects) is not a per-call cost
    n, t0 = 0, time.perf_counter()
    while n < 10 or time.perf_counter() - t0 < settings.min_batch_s / 10:
        fn()
        n += 1
    per_call_s = (time.perf_counter() - t0) / n
    batch = max(settings.min_calls, math.ceil(settings.min_batch_s / per_call_s))
    per_call_us = []
    for _ in range(settings.repeats):
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        per_call_us.append((time.perf_counter() - t0) / batch * 1e6)
    return {**stats(per_call_us), "calls_per_run": batch}


def timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    """``(fn(), wall seconds)``."""
    t0 = time.perf_counter()
    result = fn()
    return result, time.perf_counter() - t0


# ---- shared objects --------------------------------------------------------------------------------------


@lru_cache(maxsize=2)
def table_query(path: Path) -> TableQuery:
    """One opened table per path for the whole run (primitives and queries share the golden table)."""
    from lut.query.table_query import TableQuery

    return TableQuery(path)


def load_scenario_named(name: str) -> Scenario:
    """``configs/scenarios/<name>.toml``."""
    from planner.config.scenario import load_scenario

    return load_scenario(SCENARIOS / f"{name}.toml")


@contextmanager
def environment(**variables: str) -> Iterator[None]:
    """Set environment variables for the block (child processes inherit them), then restore them."""
    saved = {k: os.environ.get(k) for k in variables}
    os.environ.update(variables)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def cli_path(path: Path) -> str:
    """A file as a command line of the bench names it: relative to the repository (where its processes run) if inside
    it, else absolute (a table built elsewhere, and the scenario it names)."""
    path = Path(path).resolve()
    return path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else str(path)


def relative(path: Path) -> str:
    """``path`` relative to the repository (JSON carries no machine paths)."""
    path = Path(path).resolve()
    return path.relative_to(ROOT).as_posix() if path.is_relative_to(ROOT) else path.name


def json_safe(value: Any) -> Any:
    """Plain JSON types; NaN and ±inf become null (strict JSON has neither)."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_safe(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
