"""``reach`` (issue 20): which of the coverage section's seeded states no meeting time brings within the arm's reach
— the scan of meeting times alone (seconds a state), at the scenario's own settings and under three what-ifs: two
wider base-offset boxes θ_b(0) (the second the ``*_wide`` variants') and a longer start-delay window.

An out-of-reach state is refused by ``lutgen plan`` at once (``out of reach: …``, exit 2): its failure is the
scenario's geometry (the handle never faces the chaser within reach from the admissible base offsets during the
window), not the planner's. Where the reach proof holds (:mod:`planner.phases.reach_proof`: the grasp's wrist point
beyond the chaser's reach at every meeting time) no plan exists at all; elsewhere it is the scan's verdict. The
what-ifs say which setting would bring a state within reach; the bundled scenarios keep theirs. With ``--reach-plot
DIR`` the section draws, per kind, the proof's slack over the window of each state out of reach at the scenario's
settings (:mod:`bench_sections.reach_figure`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from bench_sections.common import Settings, load_scenario_named, relative
from bench_sections.coverage import KINDS, kind_states

WHAT_IFS = {  # name → how the scenario is changed
    "scenario": lambda sc: sc,
    "base_offset_x_-1_2_z_-2_2": lambda sc: replace(sc, base_offset_bounds_m=((-1.0, 2.0), (-2.0, 2.0))),
    # the box of the bundled ``*_wide`` scenario variants
    "base_offset_x_-2_2_z_-2_2": lambda sc: replace(sc, base_offset_bounds_m=((-2.0, 2.0), (-2.0, 2.0))),
    "start_delay_window_180_s": lambda sc: replace(sc, phases=replace(sc.phases, max_start_delay_s=180.0)),
}


@dataclass(frozen=True)
class OutOfReachState:
    """One coverage state out of reach at its scenario's settings: its index, scenario, target state and the scan's
    reach proof (what the figure draws)."""

    index: int
    scenario: Any  # planner.config.scenario.Scenario
    state: Any  # planner.model.target_state.TargetState
    proof: Any  # planner.phases.reach_proof.ReachProof


def reach(settings: Settings) -> dict[str, Any]:
    """Per kind: how many of the coverage states are out of reach under each what-if, which (indices), how many of
    them the reach proof settles, each one's certified slack [m], and how far from its station the chaser would have
    to wait for each proven one's grasp to come within reach at all [m] (inf, null in the JSON: no base offset
    brings it)."""
    from planner.phases.approach import approach_spline
    from planner.phases.approach_guess import reach_scan

    c = settings.coverage
    out: dict[str, Any] = {"states_per_kind": c.states, "seed": settings.seed, "what_ifs": list(WHAT_IFS)}
    curves: dict[str, list[OutOfReachState]] = {}
    for kind in KINDS:
        if c.kinds is not None and kind.name not in c.kinds:
            continue
        base = load_scenario_named(kind.scenario)
        states = [s.target_state() for s in kind_states(kind, c.states, settings.seed)]
        entry: dict[str, Any] = {}
        for name, change in WHAT_IFS.items():
            sc = change(base)
            spline = approach_spline(sc)
            scans = {i: reach_scan(sc, spline, s) for i, s in enumerate(states)}
            unreachable = [i for i, scan in scans.items() if not scan.reachable]
            if name == "scenario":  # the figure draws the states out of reach at the scenario's own settings
                curves[kind.name] = [OutOfReachState(i, base, states[i], scans[i].proof) for i in unreachable]
            entry[name] = {"out_of_reach": len(unreachable), "states": len(states), "indices": unreachable,
                           "proven": sum(scans[i].proven_out_of_reach for i in unreachable),
                           "proven_indices": [i for i in unreachable if scans[i].proven_out_of_reach],
                           "slack_m": [scans[i].proof.slack_m for i in unreachable],
                           "proven_least_offset_m": [scans[i].proof.least_offset_m
                                                     for i in unreachable if scans[i].proven_out_of_reach]}
        out[kind.name] = entry
    if settings.reach_plot is not None:
        from bench_sections.reach_figure import draw_reach_slack

        out["figure"] = relative(draw_reach_slack(curves, settings.reach_plot, settings.seed))
    return out
