"""``reach`` (issue 20): which of the coverage section's seeded states no meeting time brings within the arm's reach
— the scan of meeting times alone (seconds a state), at the scenario's own settings and under three what-ifs: two
wider base-offset boxes θ_b(0) (the second the ``*_wide`` variants') and a longer start-delay window.

An out-of-reach state is refused by ``lutgen plan`` at once (``out of reach: …``, exit 2): its failure is the
scenario's geometry (the handle never faces the chaser within reach from the admissible base offsets during the
window), not the planner's. The what-ifs say which setting would bring it within reach; the bundled scenarios keep
theirs.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from bench_sections.common import Settings, load_scenario_named
from bench_sections.coverage import KINDS, kind_states

WHAT_IFS = {  # name → how the scenario is changed
    "scenario": lambda sc: sc,
    "base_offset_x_-1_2_z_-2_2": lambda sc: replace(sc, base_offset_bounds_m=((-1.0, 2.0), (-2.0, 2.0))),
    # the box of the bundled ``*_wide`` scenario variants
    "base_offset_x_-2_2_z_-2_2": lambda sc: replace(sc, base_offset_bounds_m=((-2.0, 2.0), (-2.0, 2.0))),
    "start_delay_window_180_s": lambda sc: replace(sc, phases=replace(sc.phases, max_start_delay_s=180.0)),
}


def reach(settings: Settings) -> dict[str, Any]:
    """Per kind: how many of the coverage states are out of reach under each what-if, and which (indices)."""
    from planner.model.target_state import TargetState
    from planner.phases.approach import approach_spline
    from planner.phases.approach_guess import reach_scan

    c = settings.coverage
    out: dict[str, Any] = {"states_per_kind": c.states, "seed": settings.seed, "what_ifs": list(WHAT_IFS)}
    for kind in KINDS:
        if c.kinds is not None and kind.name not in c.kinds:
            continue
        base = load_scenario_named(kind.scenario)
        states = [TargetState(s.attitude_wxyz, np.radians(s.omega_body_deg_s))
                  for s in kind_states(kind, c.states, settings.seed)]
        entry: dict[str, Any] = {}
        for name, change in WHAT_IFS.items():
            sc = change(base)
            spline = approach_spline(sc)
            unreachable = [i for i, s in enumerate(states) if not reach_scan(sc, spline, s).reachable]
            entry[name] = {"out_of_reach": len(unreachable), "states": len(states), "indices": unreachable}
        out[kind.name] = entry
    return out
