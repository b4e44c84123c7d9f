"""Figures of a robustness analysis: success probability against error scale, and the worst run's clearance."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lut.output.plot_style import LIMIT_STYLE, mark_phases, new_figure, save_figure
from lut.robustness.report import RobustnessReport
from lut.robustness.sweep import SUCCESS_TARGET


def success_figure(report: RobustnessReport, path: Path) -> Path:
    """Success probability (Wilson 95 % bars) against the error scale, with the 95 % target line."""
    fig = new_figure(6.4, 4.0)
    ax = fig.add_subplot()
    points = sorted(report.sweep, key=lambda p: p.scale)
    x = np.array([p.scale for p in points])
    y = np.array([p.estimate.probability for p in points])
    err = np.array([[p.estimate.probability - p.estimate.low, p.estimate.high - p.estimate.probability]
                    for p in points]).T
    ax.errorbar(x, y, yerr=err, marker="o", capsize=4, label="success (Wilson 95 %)")
    for p in points:
        ax.annotate(f"n={p.estimate.runs}", (p.scale, p.estimate.probability), textcoords="offset points",
                    xytext=(4, -12), fontsize=7, color="0.4")
    ax.axhline(SUCCESS_TARGET, **LIMIT_STYLE, label=f"{SUCCESS_TARGET:.0%}")
    ax.set_xlabel("error scale (× the 1-σ attitude and rate errors)")
    ax.set_ylabel("P(success)")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left")
    return save_figure(fig, path, "Success probability vs observation error")


def worst_run_figure(report: RobustnessReport, phases: dict[str, tuple[float, float]], margin_m: float,
                     path: Path) -> Path | None:
    """The worst run's smallest signed distance [m] over time, with the collision margin (None: no run made)."""
    w = report.worst
    if w is None:
        return None
    fig = new_figure(7.2, 3.8)
    ax = fig.add_subplot()
    ax.plot(w.t_s, w.min_distance_m, label=f"sample {w.index} ({'feasible' if w.feasible else 'infeasible'})")
    ax.axhline(margin_m, **LIMIT_STYLE, label=f"margin {margin_m:g} m")
    ax.set_xlabel("t [s since the observation]")
    ax.set_ylabel("min distance [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    mark_phases(ax, phases)
    return save_figure(fig, path, "Worst run: smallest distance over the held pairs")


def write_robustness_plots(report: RobustnessReport, phases: dict[str, tuple[float, float]], margin_m: float,
                           out_dir: str | Path) -> list[Path]:
    """``success_vs_scale.png`` and ``worst_run_distance.png`` in ``out_dir`` (created if missing)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [success_figure(report, out / "success_vs_scale.png"),
             worst_run_figure(report, phases, margin_m, out / "worst_run_distance.png")]
    return [p for p in paths if p is not None]
