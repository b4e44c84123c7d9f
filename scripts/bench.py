#!/usr/bin/env python3
"""lutgen benchmark: primitives next to pinocchio, table queries, build throughput, whole plans, the
approach NLP by IPOPT against a finite-difference SLSQP baseline (issue 6), and the envelope's coverage (issue 20).

Usage, from the repository root with the project's virtual environment::

    .venv/bin/python scripts/bench.py                  # full: ~30 min on 2 cores, plus refines and coverage (below)
    .venv/bin/python scripts/bench.py --quick          # minutes: one cold plan per scenario and kind, no refine
    .venv/bin/python scripts/bench.py --quick --trim   # every key, smallest sizes (tests/test_bench.py)

Writes JSON (``--out``, default ``out/bench.json``) and prints a digest table. Timings are
``{"median", "min", "max", "runs"}`` (plus ``"p95"`` for query latencies) in the unit the key names
(``_us`` µs, ``_ms`` ms, ``_s`` s). A part a mode does not measure keeps its keys, with null values and
``"skipped": reason``. Sections (one module each in ``scripts/bench_sections/``): ``machine``,
``primitives``, ``query``, ``build``, ``planner``, ``baseline``, ``coverage``, ``optimal``, ``reach``, ``carry``.
Seeds are fixed (``--seed``).

The full run refines every query state whose interpolated plan fails verification, each within
``--refine-budget-s`` (default 100 s): with a table that interpolates poorly that adds up to 50 × the budget.

``coverage`` (issue 20) runs ``--coverage-states`` seeded states (default 20; ``--quick`` 1) of each of four kinds
(scenario I / II × flat spin / general tumble) through one ``lutgen plan`` process each under the 100 s budget
(``--coverage-budget-s`` another; a process still running 30 s past it is killed), and the same states through
``lutgen query`` on the tables of ``--coverage-tables`` (default ``tables/``): up to 2 × 80 runs of up to 100 s, hours
on one core.
Alone: ``OMP_NUM_THREADS=1 .venv/bin/python scripts/bench.py --only coverage --coverage-states 5``. After building a
table, its queries alone: ``--coverage-queries-only --coverage-kinds scenario_II_flat_spin``. The same states planned
with each scenario's variant ``configs/scenarios/<scenario>_NAME.toml``: ``--coverage-variant NAME`` (e.g. ``wide``).
Each state's record keeps its reach slack (the reach proof's bound), and a failed plan's its reach windows (the
meeting times the scan reached); each kind counts the failures nearer the reach's edge than every feasible plan, and
``--reach-plot DIR`` draws the plans' outcomes against it and the failures' windows against when they answered.
``--coverage-offline-check`` plans each state whose live plan failed after reaching it (no grasp held, braking)
again with ``--offline``: a feasible offline plan makes the failure *held only too early* (its approach starts before
a cold live plan can) or *missed live* (later: the live search missed it). ``--coverage-variant-check NAME`` plans
each failed state (but a bug, a run over its budget or late) again live with the scenario's variant (e.g. ``wide``):
a feasible plan there says the failure is where the bundled scenario lets the chaser wait; each kind counts those,
and the failures whose refused plan left θ_b(0) on its box's edge.

``optimal`` (issue 21) queries ``--optimal-states`` seeded off-grid states (default 30) of the optimal table
``--optimal-table`` (default ``tables/flat_spin_I_energy.h5``) and plans each cold with a 600 s budget
(``--optimal-budget-s``), one process at a time: about a minute per state on one core (scenario I). Alone:
``scripts/bench.py --only optimal --optimal-states 10``. Another table of the same grid box, without planning the
optima again: ``--optimal-optima EARLIER.json`` (an earlier ``--out`` of the same seed and scenario).

``reach`` (issue 20) scans the coverage section's seeded states' meeting times only (seconds a state): how many
no meeting time brings within the arm's reach, at the scenario's settings and with two wider base-offset boxes (the
second the ``*_wide`` variants') or a longer window, and how many of them the reach proof settles (no plan exists);
``--reach-plot DIR`` draws the proof's slack over the window of each state out of reach.

``carry`` (issue 20) plans the coverage section's seeded states cold in process (default kinds: the two general
tumbles) and re-verifies each feasible plan at displaced states, a tumble's in attitude (2.5-45°) and body rate
(0.25-2 °/s), a flat spin's along its family, in spin axis (5-45°) and spin rate (0.125-1 °/s): how far a table's plan
carries, so what grid spacing a table needs and how far outside a grid its plans are tried. Alone:
``OMP_NUM_THREADS=1 .venv/bin/python scripts/bench.py --only carry --coverage-states 10``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from bench_sections.baseline import baseline
from bench_sections.builds import builds
from bench_sections.carry import carry
from bench_sections.common import (
    ROOT,
    SCENARIOS,
    CoverageSettings,
    Settings,
    coverage_settings,
    json_safe,
    optimal_settings,
    settings_for,
)
from bench_sections.coverage import KINDS, coverage
from bench_sections.machine import load_average, machine
from bench_sections.optimal import optimal
from bench_sections.plans import plans
from bench_sections.primitives import primitives
from bench_sections.queries import queries
from bench_sections.reach import reach
from bench_sections.report import print_report

# JSON key → section; the order they run in (the JSON lists them in the order)
SECTIONS: dict[str, Callable[[Settings], dict[str, Any]]] = {
    "primitives": primitives, "query": queries, "build": builds, "baseline": baseline, "planner": plans,
    "coverage": coverage, "optimal": optimal, "reach": reach, "carry": carry}
JSON_ORDER = ("machine", "primitives", "query", "build", "planner", "baseline", "coverage", "optimal", "reach",
              "carry")


def positive_int(text: str) -> int:
    """An argparse type: an integer ≥ 1."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def positive_float(text: str) -> float:
    """An argparse type: a finite number > 0."""
    value = float(text)
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a finite number above 0, got {text}")
    return value


def coverage_kinds(text: str) -> tuple[str, ...]:
    """An argparse type: coverage kind names, comma-separated, each one of :data:`KINDS`."""
    names = tuple(name.strip() for name in text.split(",") if name.strip())
    known = [k.name for k in KINDS]
    for name in names:
        if name not in known:
            raise argparse.ArgumentTypeError(f"unknown coverage kind {name!r} (one of {', '.join(known)})")
    return names


def coverage_variant(text: str) -> str:
    """An argparse type: a scenario variant suffix ``NAME`` for which both ``scenario_I_NAME.toml`` and
    ``scenario_II_NAME.toml`` exist in ``configs/scenarios``."""
    name = text.strip()
    missing = [f"{k}_{name}.toml" for k in dict.fromkeys(k.scenario for k in KINDS)
               if not name or not (SCENARIOS / f"{k}_{name}.toml").is_file()]
    if missing:
        raise argparse.ArgumentTypeError(f"no scenario {', '.join(missing)} in configs/scenarios")
    return name


def add_coverage_options(ap: argparse.ArgumentParser) -> None:
    """The coverage section's options (``--coverage-*``)."""
    ap.add_argument("--coverage-states", type=positive_int, default=None, metavar="N",
                    help="coverage: seeded states per kind (default 20; --quick 1; --trim 1 of one kind)")
    ap.add_argument("--coverage-budget-s", type=positive_float, default=None, metavar="S",
                    help="coverage: each plan's and query's --budget-s (default 100, issue 20's budget; --trim 2): a "
                         "smaller one shows what an answer within S seconds gives up")
    ap.add_argument("--coverage-jobs", type=positive_int, default=1, metavar="N",
                    help="coverage: processes at a time (default 1; more share the cores and inflate wall times)")
    ap.add_argument("--coverage-tables", type=Path, default=None, metavar="DIR",
                    help="coverage: folder of the tables the queries use, matched to each kind by the scenario "
                         "and grid kind they were built for (default: tables/; --trim: tests/data)")
    ap.add_argument("--coverage-kinds", type=coverage_kinds, default=None, metavar="KIND[,KIND]",
                    help=f"coverage: only these kinds ({', '.join(k.name for k in KINDS)}; default all)")
    ap.add_argument("--coverage-variant", type=coverage_variant, default=None, metavar="NAME",
                    help="coverage: plan (and match tables) with each scenario's variant "
                         "configs/scenarios/<scenario>_NAME.toml, e.g. wide (the chaser free within ±2 m); the same "
                         "seeded states")
    ap.add_argument("--coverage-offline-check", action="store_true",
                    help="coverage: plan each failed plan's state again with --offline (same budget): a feasible "
                         "offline plan tells whether its grasps hold only too early or the live search missed one")
    ap.add_argument("--coverage-variant-check", type=coverage_variant, default=None, metavar="NAME",
                    help="coverage: plan each failed plan's state again, live, with the scenario's variant NAME "
                         "(e.g. wide: the chaser free within ±2 m): a feasible plan there puts the failure on the box")
    ap.add_argument("--coverage-queries-only", action="store_true",
                    help="coverage: the queries on the tables alone, no cold plans (e.g. after building a table)")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smoke run (minutes): one cold plan per scenario, no refine")
    ap.add_argument("--trim", action="store_true",
                    help="implies --quick; the smallest run that still fills every key (fewest runs and states, tiny "
                         "build grid): what tests/test_bench.py runs, < 1 min")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench.json",
                    help="JSON output (default: out/bench.json in the repository)")
    ap.add_argument("--seed", type=int, default=7, help="seed of every random state and configuration")
    ap.add_argument("--refine-budget-s", type=float, default=100.0,
                    help="full mode: per-query budget (s) of the refine of an infeasible interpolated plan")
    ap.add_argument("--plan-runs", type=int, default=None,
                    help="cold plans per scenario and variant (default 1; --trim 0); for a median: --plan-runs 5")
    ap.add_argument("--plan-cap-s", type=float, default=300.0, help="IPOPT wall-time cap (s) per NLP of a plan")
    ap.add_argument("--plan-with-costs", action="store_true",
                    help="also plan with cost terms (the scenario's weights, or the paper's approach costs)")
    add_coverage_options(ap)
    ap.add_argument("--optimal-table", type=Path, default=None, metavar="PATH",
                    help="optimal: the table of optimal plans (default tables/flat_spin_I_energy.h5; --trim: the "
                         "golden table, feasibility-only, so the section only says so)")
    ap.add_argument("--optimal-states", type=positive_int, default=None, metavar="N",
                    help="optimal: seeded off-grid states, each a query and a cold offline optimum (default 30; "
                         "--quick 2; --trim 1)")
    ap.add_argument("--optimal-budget-s", type=positive_float, default=None, metavar="S",
                    help="optimal: each offline optimum's budget (default 600 s; a scenario II costed plan descends "
                         "to its budget, so its table's --point-timeout is the like-for-like choice)")
    ap.add_argument("--optimal-optima", type=Path, default=None, metavar="JSON",
                    help="optimal: take each state's offline optimum from an earlier run's --out JSON of the same "
                         "scenario, seed and grid box instead of planning it again (another table of that box "
                         "measured in minutes)")
    ap.add_argument("--reach-plot", type=Path, default=None, metavar="DIR",
                    help="the reach section also draws reach_slack.png here: how far beyond the arm's reach each "
                         "out-of-reach state's grasp stays over the start-delay window; the coverage section "
                         "coverage_reach.png: each plan's outcome against its state's reach slack, and "
                         "coverage_windows.png: each failure's reach windows against when its plan answered")
    ap.add_argument("--only", default=None, metavar="SECTION[,SECTION]",
                    help=f"run only these sections ({', '.join(SECTIONS)}); the other sections of an existing "
                         "--out file are kept, so one part can be re-measured after a change")
    args = ap.parse_args(argv)
    if args.coverage_variant is not None and args.coverage_variant_check is not None:
        ap.error("--coverage-variant-check plans the bundled scenarios' failures again: not with --coverage-variant")
    return args


def write_json(result: dict[str, Any], out: Path) -> None:
    """Strict JSON (NaN/inf as null), the sections in the issue's order."""
    ordered = {key: result[key] for key in (*JSON_ORDER, "wall_s") if key in result}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(json_safe(ordered), indent=1, allow_nan=False) + "\n", encoding="utf-8")


def run(settings: Settings, out: Path, only: tuple[str, ...] | None = None) -> dict[str, Any]:
    """Every section (or ``only`` these), each timed, the JSON rewritten after each (a long full run keeps
    what it measured).

    A section that raises is recorded as ``{"error", "skipped"}`` and the others still run. With ``only``,
    the other sections of an existing ``out`` are kept as they were measured.
    """
    t_start = time.perf_counter()
    result: dict[str, Any] = {}
    if only is not None and out.is_file():
        result = {k: v for k, v in json.loads(out.read_text(encoding="utf-8")).items() if k not in only}
    result["machine"] = machine(settings)
    for name, section in SECTIONS.items():
        if only is not None and name not in only:
            continue
        print(f"bench: {name} …", file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        try:
            result[name] = section(settings)
        except Exception as exc:  # noqa: BLE001 - one broken section must not cost the others' numbers
            traceback.print_exc()
            message = f"{type(exc).__name__}: {exc}".splitlines()[0]
            result[name] = {"error": message, "skipped": f"the section failed ({message})"}
        result[name]["section_wall_s"] = time.perf_counter() - t0
        write_json(result, out)
    result["machine"]["load_average_end"] = load_average()
    if only is None:  # a partial re-run keeps the full run's wall time; its sections carry their own
        result["wall_s"] = time.perf_counter() - t_start
    else:
        result["machine"]["sections_rerun"] = list(only)
    write_json(result, out)
    return result


def coverage_settings_of(args: argparse.Namespace) -> CoverageSettings:
    """The coverage section's settings from the command line's options."""
    return coverage_settings(args.quick, args.trim, args.coverage_states, args.coverage_jobs, args.coverage_tables,
                             args.coverage_kinds, not args.coverage_queries_only, args.coverage_variant,
                             args.coverage_offline_check, args.coverage_variant_check, args.coverage_budget_s)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    cov = coverage_settings_of(args)
    settings = replace(settings_for(args.quick, args.trim, args.seed, args.plan_runs, args.plan_cap_s,
                                    args.plan_with_costs, args.refine_budget_s, cov),
                       optimal=optimal_settings(args.quick, args.trim, args.optimal_table, args.optimal_states,
                                                        args.optimal_budget_s, args.optimal_optima),
                       reach_plot=args.reach_plot)
    only = None
    if args.only is not None:
        only = tuple(name.strip() for name in args.only.split(",") if name.strip())
        unknown = [name for name in only if name not in SECTIONS]
        if unknown or not only:
            print(f"bench.py: --only: unknown section(s) {', '.join(unknown) or '(none given)'}; "
                  f"choose from {', '.join(SECTIONS)}", file=sys.stderr)
            return 2
    result = run(settings, args.out, only)
    print_report(json_safe(result))
    print(f"wrote {args.out}")
    return 1 if any("error" in section for section in result.values() if isinstance(section, dict)) else 0


if __name__ == "__main__":
    raise SystemExit(main())
