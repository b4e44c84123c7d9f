"""``planner``: whole plans of scenarios I and II (``Planner(scenario).plan(state)``, the default observed
state, one core): time per phase, IPOPT iterations, dense-verification verdict."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from bench_sections.common import Settings, load_scenario_named, skipped, stats, timed

if TYPE_CHECKING:
    from planner.config.scenario import Scenario

SCENARIO_NAMES = ("scenario_I", "scenario_II")
PHASE_KEYS = ("approach_s", "tracking_s", "stabilization_s", "total_s")
ENTRY_KEYS = (*PHASE_KEYS, "planner_build_s", "ipopt_iterations", "feasible", "solver_status", "cost_weights")
COST_NAMES = ("manipulability", "min_distance", "approach_energy", "attitude_disturbance", "peak_wrench")
# "with costs" when a scenario has no cost of its own: the paper's approach costs, manipulability (Eq. 14)
# and minimum distance (Eq. 15), at weight 1
PAPER_APPROACH_COSTS = {"manipulability": 1.0, "min_distance": 1.0}


def _cost_weights(scenario: Scenario, variant: str) -> dict[str, float]:
    """All-zero weights (feasibility only), or the scenario's own weights, or the paper's if it has none."""
    own = {name: float(getattr(scenario.costs, name)) for name in COST_NAMES}
    if variant == "feasibility":
        return dict.fromkeys(COST_NAMES, 0.0)
    return own if any(own.values()) else {**dict.fromkeys(COST_NAMES, 0.0), **PAPER_APPROACH_COSTS}


def _plan_runs(scenario: Scenario, runs: int) -> dict[str, Any]:
    """``runs`` plans of the default state with one Planner (problems built once, as a table build does)."""
    from planner.plan import Planner
    from planner.verify.verifier import verify

    planner, build_s = timed(lambda: Planner(scenario))
    state = scenario.target_state.as_state()
    phases: dict[str, list[float]] = {key: [] for key in PHASE_KEYS}
    iterations: dict[str, list[int]] = {"approach": [], "stabilization": []}
    feasible, status = [], []
    for _ in range(runs):
        plan = planner.plan(state)
        t = plan.timings_s
        phases["approach_s"].append(t["approach_s"])
        phases["stabilization_s"].append(t["stabilization_s"])
        # the planner times the two NLPs; the rest is the tracking IK and the dense re-simulations
        phases["tracking_s"].append(t["total_s"] - t["approach_s"] - t["stabilization_s"])
        phases["total_s"].append(t["total_s"])
        iterations["approach"].append(plan.approach.iterations)
        iterations["stabilization"].append(plan.stabilization.iterations)
        feasible.append(bool(verify(plan).feasible))
        status.append(f"approach {plan.approach.status}; stabilization {plan.stabilization.status}")
    return {**{key: stats(v) for key, v in phases.items()}, "planner_build_s": build_s,
            "ipopt_iterations": {key: stats(v) for key, v in iterations.items()}, "feasible": feasible,
            "solver_status": status}


def plans(settings: Settings) -> dict[str, Any]:
    """The whole section."""
    out: dict[str, Any] = {"runs": settings.plan_runs, "nlp_wall_cap_s": settings.plan_cap_s,
                           "notes": "tracking_s = total − approach − stabilization (tracking IK + dense "
                                    "re-simulation); one cold plan per scenario by default, --plan-runs N for "
                                    "more; the cap is IPOPT's max_wall_s per NLP"}
    for name in SCENARIO_NAMES:
        out[name] = {}
        for variant in ("feasibility", "with_costs"):
            if settings.plan_runs == 0:
                out[name][variant] = skipped("--trim (or --plan-runs 0): no whole plans", ENTRY_KEYS)
                continue
            if variant == "with_costs" and not settings.plan_with_costs:
                out[name][variant] = skipped("not asked for (--plan-with-costs)", ENTRY_KEYS)
                continue
            sc = load_scenario_named(name)
            weights = _cost_weights(sc, variant)
            sc = replace(sc, costs=replace(sc.costs, **weights),
                         solver=replace(sc.solver, max_wall_s=min(settings.plan_cap_s, sc.solver.max_wall_s)))
            out[name][variant] = {**_plan_runs(sc, settings.plan_runs), "cost_weights": weights}
    # plans are ~1.6× slower with interpreted inner Functions: say which ran (planner.nlp.compiled)
    from planner.nlp import compiled

    out["compiled_functions"] = {"enabled": compiled.compile_enabled(), "fallbacks": list(compiled.fallback_reasons)}
    return out
