"""``coverage`` (issue 20): how much of the paper's envelope gets a verified plan on time — seeded states of four
kinds through cold ``lutgen plan`` and ``lutgen query`` processes on one core; feasible fractions, p50/p95 wall
times, failure reasons tallied, each run's record, and the issue's done-when bars."""

from __future__ import annotations

import sys
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench_sections.common import Settings, cli_path, load_scenario_named, relative, skipped, stats_p95
from bench_sections.coverage_runs import OVER_BUDGET, plan_takes_budget, run_cli, run_record, state_args
from bench_sections.coverage_tables import find_tables
from bench_sections.envelope import (
    FLAT_SPIN_RATE_DEG_S,
    TUMBLE_RATE_MAX_DEG_S,
    EnvelopeState,
    flat_spin_state,
    major_axis_body,
    tumble_state,
)
from bench_sections.failure_kinds import cut_by_the_budget, record_failure_kind
from bench_sections.offline_check import with_offline
from bench_sections.reach_windows import with_windows
from bench_sections.variant_check import KEY as VARIANT_PLAN
from bench_sections.variant_check import with_variant
from planner.box_edge import BOX_EDGE_NOTE

SEED_SALT = 20  # the coverage states' seed is (--seed, issue 20, kind)
SUMMARY_KEYS = ("states", "feasible_on_time", "feasible_fraction", "wall_s", "reasons", "failures_by_first_reason",
                "failures_by_kind", "failures_at_box_edge", "failures_planned_by_variant", "cut_by_the_budget",
                "over_budget", "killed", "reach_edge", "runs")
PLAN_P95_BAR_S, QUERY_P95_BAR_S, QUERY_FEASIBLE_BAR = 60.0, 30.0, 0.98
BAR_STATES = 20  # the issue measures its bars on ≥ 20 states per kind


@dataclass(frozen=True)
class Kind:
    """One of the issue's four kinds of states: a scenario and a motion (``flat_spin`` or ``tumble``)."""

    scenario: str
    motion: str
    feasible_bar: float  # the cold plans' feasible fraction the issue asks of this kind

    @property
    def name(self) -> str:
        return f"{self.scenario}_{self.motion}"


KINDS = (Kind("scenario_I", "flat_spin", 0.95), Kind("scenario_II", "flat_spin", 0.90),
         Kind("scenario_I", "tumble", 0.95), Kind("scenario_II", "tumble", 0.90))


def kind_states(kind: Kind, n: int, seed: int) -> list[EnvelopeState]:
    """The first ``n`` seeded states of ``kind`` (the first ``n`` of a longer run are the same states)."""
    rng = np.random.default_rng([seed, SEED_SALT, KINDS.index(kind)])
    if kind.motion == "tumble":
        return [tumble_state(rng) for _ in range(n)]
    axis = major_axis_body(load_scenario_named(kind.scenario).target.inertia_body_kg_m2)
    return [flat_spin_state(rng, axis) for _ in range(n)]


def summary(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Feasible-on-time fraction, wall-time statistics with p95 (s), reasons tallied (every failing check; and one
    per failed run, its first: out of reach, budget ran out, or the first failing check), the failures by kind
    (:mod:`bench_sections.failure_kinds`) and how many of them the plan's deadline cut short, and the records."""
    ok = sum(r["feasible_on_time"] for r in records)
    tally = Counter(reason["reason"] for r in records for reason in r["reasons"])
    first = Counter(r["reasons"][0]["reason"] for r in records if r["reasons"])
    return {"states": len(records), "feasible_on_time": ok, "feasible_fraction": ok / len(records),
            "wall_s": stats_p95([r["wall_s"] for r in records]), "reasons": dict(tally.most_common()),
            "failures_by_first_reason": dict(first.most_common()),
            "failures_by_kind": dict(Counter(record_failure_kind(r).value for r in records
                                             if r["reasons"]).most_common()),
            "failures_at_box_edge": sum(at_box_edge(r) for r in records if r["reasons"]),
            "failures_planned_by_variant": planned_by_variant(records),
            "cut_by_the_budget": sum(cut_by_the_budget(r["reasons"]) for r in records),
            "over_budget": sum(any(x["reason"] == OVER_BUDGET for x in r["reasons"]) for r in records),
            "killed": sum(r["exit_code"] is None for r in records), "reach_edge": reach_edge(records),
            "runs": records}


def at_box_edge(record: dict[str, Any]) -> bool:
    """True when the run's refused plan left θ_b(0) on its base-offset box's edge (its note, planner.box_edge)."""
    return any(note.startswith(BOX_EDGE_NOTE) for note in record.get("notes") or ())


def planned_by_variant(records: list[dict[str, Any]]) -> dict[str, int] | None:
    """Of the failures planned again with the scenario variant (:mod:`bench_sections.variant_check`), how many of
    each kind its plan verified feasible on time, with ``checked``: how many were planned; None: none checked."""
    checked = [r for r in records if VARIANT_PLAN in r]
    if not checked:
        return None
    planned = Counter(record_failure_kind(r).value for r in checked if r[VARIANT_PLAN]["exit_code"] == 0)
    return {"checked": len(checked), **dict(planned.most_common())}


def reach_slacks(states: list[EnvelopeState], scenario: str) -> list[float]:
    """Each state's reach slack [m] (:class:`planner.phases.reach_proof.ReachProof`): how far the grasp's wrist point
    stays beyond the arm's reach at best over the window; negative, how deep within it it comes (milliseconds a
    state)."""
    from planner.phases.reach_proof import reach_proof

    sc = load_scenario_named(scenario)
    return [reach_proof(sc, s.target_state()).slack_m for s in states]


def reach_edge(records: list[dict[str, Any]]) -> dict[str, Any] | None:
    """Where the failures lie against the feasible plans' reach: the largest (nearest the reach's edge) slack [m] of
    a feasible plan, and how many failures lie nearer the edge still (or beyond it); None without slacks."""
    if not records or "reach_slack_m" not in records[0]:
        return None
    feasible = [r["reach_slack_m"] for r in records if r["feasible_on_time"]]
    edge = max(feasible) if feasible else None
    failed = [r["reach_slack_m"] for r in records if not r["feasible_on_time"]]
    nearer = sum(s > edge for s in failed) if edge is not None else len(failed)
    return {"feasible_nearest_m": edge, "failures": len(failed), "failures_nearer_the_edge": nearer}


def with_slacks(records: list[dict[str, Any]], slacks: list[float]) -> list[dict[str, Any]]:
    """``records`` (one per state, in order), each with its state's reach slack [m] (``reach_slack_m``)."""
    return [{**r, "reach_slack_m": s} for r, s in zip(records, slacks, strict=True)]


def run_all(jobs: list[list[str]], settings: Settings) -> list[dict[str, Any]]:
    """Each command line as its own process, ``settings.coverage.jobs`` at a time, in order."""
    c = settings.coverage

    def one(args: list[str]) -> dict[str, Any]:
        record = run_record(args, run_cli(args, c.budget_s + c.kill_margin_s), c.budget_s)
        reasons = ", ".join(r["reason"] for r in record["reasons"]) or "feasible"
        print(f"coverage: {args[0]} {args[1]} exit {record['exit_code']} {record['wall_s']:.1f} s: {reasons}",
              file=sys.stderr, flush=True)  # a long section shows its progress
        return record

    with ThreadPoolExecutor(max(1, c.jobs)) as pool:
        return list(pool.map(one, jobs))


def _plan_records(jobs: list[list[str]], states: list[EnvelopeState], scenario: str, slacks: list[float],
                  settings: Settings) -> list[dict[str, Any]]:
    """The cold plans' records with their states' reach slacks and windows, and their offline and variant plans if
    asked for (the variant's after the offline check, which can change a failure's kind)."""
    records = with_windows(with_slacks(run_all(jobs, settings), slacks), states, scenario)
    records = with_offline(records, jobs, settings) if settings.coverage.offline_check else records
    return with_variant(records, jobs, settings) if settings.coverage.variant_check else records


def plan_args(scenario: str, state: EnvelopeState, budget_s: float) -> list[str]:
    budget = ["--budget-s", f"{budget_s:g}"] if plan_takes_budget() else []
    return ["plan", f"configs/scenarios/{scenario}.toml", *state_args(state), *budget]


def query_args(table: str, state: EnvelopeState, budget_s: float) -> list[str]:
    return ["query", table, *state_args(state), "--budget-s", f"{budget_s:g}"]


def _bar(value: float | None, bar: float, at_most: bool, enough_states: bool) -> dict[str, Any]:
    met = None if value is None else (value <= bar if at_most else value >= bar)
    return {"value": value, "bar": bar, "at_most": at_most, "met": met, "enough_states": enough_states}


def bars(plans: dict[str, Any], queries: dict[str, Any], states: int) -> dict[str, Any]:
    """The issue's done-when bars: value, bar, met (None: not measured), and whether ≥ 20 states per kind."""
    enough = states >= BAR_STATES
    out: dict[str, Any] = {}
    for kind in KINDS:
        p = plans[kind.name]
        out[f"plan_feasible_{kind.name}"] = _bar(p["feasible_fraction"], kind.feasible_bar, False, enough)
        p95 = p["wall_s"]["p95"] if p["wall_s"] else None
        out[f"plan_p95_wall_s_{kind.name}"] = _bar(p95, PLAN_P95_BAR_S, True, enough)
    measured = [plans[k.name] for k in KINDS if plans[k.name]["runs"]]
    out["plans_over_budget"] = _bar(sum(p["over_budget"] for p in measured) if measured else None, 0, True, enough)
    answered = [r for k in KINDS if queries[k.name]["runs"] for r in queries[k.name]["runs"]]
    fraction = sum(r["feasible_on_time"] for r in answered) / len(answered) if answered else None
    p95 = float(np.percentile([r["wall_s"] for r in answered], 95)) if answered else None
    all_kinds = all(queries[k.name]["runs"] for k in KINDS)
    out["query_feasible_all_kinds"] = _bar(fraction, QUERY_FEASIBLE_BAR, False, enough and all_kinds)
    out["query_p95_wall_s_all_kinds"] = _bar(p95, QUERY_P95_BAR_S, True, enough and all_kinds)
    return out


def coverage(settings: Settings) -> dict[str, Any]:
    """The whole section."""
    c = settings.coverage
    tables, table_notes = find_tables(c.tables, [(k.name, c.scenario_of(k.scenario), k.motion) for k in KINDS])
    plans: dict[str, Any] = {}
    queries: dict[str, Any] = {"tables_dir": relative(c.tables), "tables": table_notes}
    for kind in KINDS:
        if c.kinds is not None and kind.name not in c.kinds:
            reason = f"only {', '.join(c.kinds)} (--trim or --coverage-kinds)"
            plans[kind.name] = queries[kind.name] = skipped(reason, SUMMARY_KEYS)
            continue
        states, scenario = kind_states(kind, c.states, settings.seed), c.scenario_of(kind.scenario)
        slacks = reach_slacks(states, scenario)
        plan_jobs = [plan_args(scenario, s, c.budget_s) for s in states]
        plans[kind.name] = (summary(_plan_records(plan_jobs, states, scenario, slacks, settings))
                            if c.plans else skipped("--coverage-queries-only", SUMMARY_KEYS))
        table = tables.get(kind.name)
        if table is None:
            queries[kind.name] = skipped(f"no table for {kind.name} in {relative(c.tables)}/", SUMMARY_KEYS)
            continue
        queries[kind.name] = {"table": relative(table), **summary(with_slacks(
            run_all([query_args(cli_path(table), s, c.budget_s) for s in states], settings), slacks))}
    return {"states_per_kind": c.states, "seed": [settings.seed, SEED_SALT], "variant": c.variant,
            "offline_check": c.offline_check, "variant_check": c.variant_check,
            "budget_s": c.budget_s,
            "kill_after_s": c.budget_s + c.kill_margin_s, "jobs": c.jobs, "plan_budget_option": plan_takes_budget(),
            "envelope": {"flat_spin": f"spin about the target's major axis (from its inertia) along (cos α, 0, sin α) "
                                      f"in O, α and phase uniform over the full turn, |ω| uniform in "
                                      f"{FLAT_SPIN_RATE_DEG_S[0]:g}–{FLAT_SPIN_RATE_DEG_S[1]:g} °/s",
                         "tumble": f"uniformly random attitude, body rates uniform in ±{TUMBLE_RATE_MAX_DEG_S:g} °/s "
                                   "per body axis"},
            "notes": "one process per state (planner build and verification inside its wall time), OMP_NUM_THREADS=1; "
                     "feasible on time = exit 0 within the budget; a run still going at kill_after_s is killed and "
                     "counted over budget; jobs > 1 runs processes side by side and inflates wall times",
            "plans": plans, "queries": queries, "bars": bars(plans, queries, c.states),
            **_figures(plans, settings)}


def _figures(plans: dict[str, Any], settings: Settings) -> dict[str, str | None]:
    """With ``--reach-plot DIR``: the plans' outcomes against their states' reach slacks (``figure``) and the failures'
    reach windows against when their plans answered (``windows_figure``), drawn there; their paths."""
    measured = {name: p["runs"] for name, p in plans.items() if p.get("runs")}
    if settings.reach_plot is None or not measured:
        return {"figure": None, "windows_figure": None}
    from bench_sections.reach_figure import draw_outcomes_by_reach
    from bench_sections.reach_windows import draw_failure_windows

    windows = draw_failure_windows(measured, settings.reach_plot, str(settings.seed))
    return {"figure": relative(draw_outcomes_by_reach(measured, settings.reach_plot, str(settings.seed))),
            "windows_figure": None if windows is None else relative(windows)}
