"""The reach figures. The reach section's: per kind, how far beyond the arm's reach each out-of-reach state's grasp
stays over the start-delay window (the reach proof's wrist point, its distance from the nearest admissible centre of
mass less the reach radius); a curve above zero over the whole window is a state no plan can reach. The coverage
section's: every state's best slack over the window against its plan's outcome, per kind: where the failures lie
against the feasible plans' reach."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

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


def draw_outcomes_by_reach(runs: dict[str, list[dict[str, Any]]], folder: Path, seeds: str) -> Path:
    """``coverage_reach.png`` in ``folder`` (made if missing): one row per kind, each state at its reach slack [m]
    (``reach_slack_m``), marked by its outcome (feasible, or its failure kind); ``seeds`` names the states' seeds in
    the title; the path."""
    folder.mkdir(parents=True, exist_ok=True)
    fig = new_figure(11.0, 1.2 + 1.1 * len(runs))
    ax = fig.subplots()
    found = {_outcome(r) for records in runs.values() for r in records}
    outcomes = sorted(found, key=lambda o: (o != "feasible", o))  # one marker and colour each, feasible first
    labelled: set[str] = set()
    for k, records in enumerate(runs.values()):
        for j, outcome in enumerate(outcomes):
            slack = [r["reach_slack_m"] for r in records if _outcome(r) == outcome]
            if not slack:
                continue
            row = k + 0.6 * (j / max(1, len(outcomes) - 1) - 0.5)  # one lane per outcome within the kind's row
            ax.scatter(slack, [row] * len(slack), s=22, marker=MARKERS[j % len(MARKERS)],
                       color=COLOURS[j % len(COLOURS)], label=None if outcome in labelled else outcome)
            labelled.add(outcome)
    ax.axvline(0.0, **LIMIT_STYLE)
    ax.set_yticks(range(len(runs)), list(runs))
    ax.set_xlabel("reach slack: the grasp's wrist point beyond the arm's reach at best over the window [m] "
                  "(negative: inside it)")
    ax.legend(fontsize=8, ncol=len(outcomes), loc="lower center", bbox_to_anchor=(0.5, 1.0))
    return save_figure(fig, folder / "coverage_reach.png",
                       f"Coverage states (seed {seeds}): outcome against how far within reach the grasp comes")


MARKERS = ("o", "x", "^", "s", "v", "D", "P")
COLOURS = ("0.55", "tab:red", "tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown")


def _outcome(record: dict[str, Any]) -> str:
    """``feasible`` or the run's failure kind."""
    from bench_sections.failure_kinds import record_failure_kind

    if record["feasible_on_time"]:
        return "feasible"
    kind = record_failure_kind(record)
    return "failed" if kind is None else kind.value
