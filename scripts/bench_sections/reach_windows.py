"""When each failed coverage state's grasp is within reach: the start delays [s] at which the approach's scan of
meeting times reached a pre-grasp and tracking poses, as intervals, recorded beside the run. A plan must answer before
its approach starts, so a state reachable only in the first seconds after the observation, or only in a few seconds of
the window, fails for its timing, however sound the planner; the figure (:func:`draw_failure_windows`) sets each
failure's windows against when its plan answered."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from bench_sections.common import load_scenario_named
from bench_sections.envelope import EnvelopeState
from bench_sections.failure_kinds import EARLIEST_COLD_START_S, FailureKind, offline_start_s, record_failure_kind
from lut.output.plot_style import new_figure, save_figure

if TYPE_CHECKING:
    from planner.config.scenario import Scenario
    from planner.nlp.bspline import UniformCubicBSpline

WITHOUT_WINDOWS = (FailureKind.OUT_OF_REACH, FailureKind.OUT_OF_REACH_PROVEN)  # no window: nothing to draw


def reach_windows_s(scenario: Scenario, spline: UniformCubicBSpline, state: EnvelopeState) -> list[list[float]]:
    """The start-delay intervals [s] at which the scan of ``state`` under ``scenario`` (its approach ``spline``)
    reached a meeting time (the scenario's whole window, no live floor)."""
    from planner.phases.approach_guess import reach_scan

    scan = reach_scan(scenario, spline, state.target_state(), 1, held_angles=False)
    return [[first, last] for first, last in scan.reached_start_delays_s()]


def with_windows(records: list[dict[str, Any]], states: list[EnvelopeState], scenario: str) -> list[dict[str, Any]]:
    """``records`` (one per state, in order), each failure's with its state's reach windows (``reach_windows_s``)
    under the scenario named ``scenario`` (loaded once)."""
    from planner.phases.approach import approach_spline

    sc = load_scenario_named(scenario)
    spline = approach_spline(sc)
    return [{**r, "reach_windows_s": reach_windows_s(sc, spline, s)} if not r["feasible_on_time"] else r
            for r, s in zip(records, states, strict=True)]


def draw_failure_windows(runs: dict[str, list[dict[str, Any]]], folder: Path, seeds: str) -> Path | None:
    """``coverage_windows.png`` in ``folder``: one row per failure whose grasp comes within reach, its reach windows
    as bars over the start-delay window, a tick where its plan answered (the wall time: the approach must start
    after it), a dot where its answer's approach started, a diamond where its feasible offline plan's starts, and a
    dashed line at the earliest start a cold live plan can take; None when there is no such failure."""
    rows = [(kind, i, r) for kind, records in runs.items() for i, r in enumerate(records)
            if "reach_windows_s" in r and record_failure_kind(r) not in WITHOUT_WINDOWS]
    if not rows:
        return None
    folder.mkdir(parents=True, exist_ok=True)
    fig = new_figure(11.0, 1.4 + 0.28 * len(rows))
    ax = fig.subplots()
    for y, (_, _, r) in enumerate(rows):
        for first, last in r["reach_windows_s"]:
            ax.barh(y, max(last - first, 0.5), left=first, height=0.5, color="0.75")
        ax.plot([r["wall_s"]], [y], marker="|", markersize=12, color="black")
        if r.get("start_delay_s") is not None:
            ax.plot([r["start_delay_s"]], [y], marker="o", markersize=5, color="tab:red")
        if (offline_start := offline_start_s(r.get("offline"))) is not None:
            ax.plot([offline_start], [y], marker="D", markersize=5, color="tab:green")
    ax.axvline(EARLIEST_COLD_START_S, color="0.4", linestyle="--", linewidth=0.8)
    labels = [f"{kind} {i}: {record_failure_kind(r).value}" for kind, i, r in rows]
    ax.set_yticks(range(len(rows)), labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("after the observation [s]: grey, the meeting times the scan reached; |, the plan's answer; "
                  "red, its approach's start;\ngreen, a feasible offline plan's approach's start; dashed, the earliest "
                  "start a cold live plan can take")
    return save_figure(fig, folder / "coverage_windows.png",
                       f"Coverage failures within reach (seed {seeds}): when the grasp is reachable against when the "
                       "plan answered")
