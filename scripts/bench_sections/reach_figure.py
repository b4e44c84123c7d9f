"""The reach section's figure: per kind, how far beyond the arm's reach each out-of-reach state's grasp stays over the
start-delay window (the reach proof's wrist point, its distance from the nearest admissible centre of mass less the
reach radius). A curve above zero over the whole window is a state no plan can reach."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from lut.output.plot_style import LIMIT_STYLE, new_figure, save_figure

if TYPE_CHECKING:
    from bench_sections.reach import OutOfReachState


def draw_reach_slack(curves: dict[str, list[OutOfReachState]], folder: Path, seed: int) -> Path:
    """``reach_slack.png`` in ``folder`` (made if missing): one panel per kind, one curve per state, solid where proven
    out of reach, dashed where only the scan says so; the path."""
    from planner.phases.reach_proof import wrist_distance_over_window

    folder.mkdir(parents=True, exist_ok=True)
    fig = new_figure(11.0, 7.5)
    panels = fig.subplots(2, 2, sharey=True).ravel()
    for ax in panels[len(curves):]:
        ax.set_visible(False)
    for ax, (kind, states) in zip(panels, curves.items(), strict=False):
        for s in states:
            delays_s, distance_m = wrist_distance_over_window(s.scenario, s.state)
            ax.plot(delays_s, distance_m - s.proof.radius_m, linestyle="-" if s.proof.proven else "--",
                    label=f"state {s.index}" + (" (proven)" if s.proof.proven else ""))
        ax.axhline(0.0, **LIMIT_STYLE)
        ax.set_title(f"{kind}: {len(states)} out of reach", fontsize=10)
        ax.set_xlabel("start delay [s]")
        ax.set_ylabel("wrist point beyond reach [m]")
        if states:
            ax.legend(fontsize=7, ncol=2)
    return save_figure(fig, folder / "reach_slack.png",
                       f"Out of reach at the scenarios' settings (coverage states, seed {seed}): above 0 = no plan")
