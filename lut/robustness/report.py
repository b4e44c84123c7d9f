"""A robustness analysis' figures: success probability and interval, failure tally, sweep, worst run, cost;
as printed lines and as the ``lutgen.robustness/1`` JSON document (with how the runs flew the stabilization)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lut.robustness.error_model import ErrorModel
from lut.robustness.statistics import CONFIDENCE, CheckTally, SuccessEstimate
from lut.robustness.sweep import SUCCESS_TARGET, LargestScale, ScalePoint

SCHEMA = "lutgen.robustness/1"
Array = NDArray[np.float64]


@dataclass(frozen=True)
class WorstRun:
    """The run of scale 1 with the smallest collision margin: its index in the draws, verdict, clearance over time."""

    index: int
    feasible: bool
    failed: tuple[str, ...]
    t_s: Array  # (m,) [s since the observation]
    min_distance_m: Array  # (m,) [m]


@dataclass(frozen=True)
class RunRecord:
    """One run of scale 1: the true state it flew against, its verdict and every check's margin."""

    attitude_wxyz: tuple[float, ...]  # q_world_body of the true state at t = 0
    omega_body_rad_s: tuple[float, ...]  # [rad/s]
    feasible: bool
    failed: tuple[str, ...]  # earliest worst value first
    margins: dict[str, float]  # check → margin (its unit; ≥ 0 satisfied)


@dataclass(frozen=True)
class RunCost:
    """What the analysis cost: wall times [s], runs executed (identical states run once), per-run means [s]."""

    wall_s: float
    runs_executed: int
    planner_build_s: float  # summed over the worker processes that built one
    simulate_s_mean: float
    verify_s_mean: float
    main_wall_s: float  # the scale-1 runs alone


@dataclass(frozen=True)
class StabilizationMode:
    """How the runs flew the stabilization: the plan's spline as it is (``resolve_iterations`` None), or its NLP
    re-solved warm at each run's grasp within ``resolve_iterations`` IPOPT iterations (the planned spline flown where
    the solve failed); the re-solves' outcome at scale 1."""

    resolve_iterations: int | None
    resolved_runs: int = 0  # runs of scale 1 that flew a successful re-solve
    iterations_mean: float = 0.0  # of the re-solves at scale 1
    iterations_max: int = 0

    def line(self, runs: int) -> str:
        """The report's line on it (``runs``: of scale 1)."""
        if self.resolve_iterations is None:
            return "stabilization as planned: the plan's spline from each run's grasp state"
        return (f"stabilization re-solved warm at each run's grasp (≤ {self.resolve_iterations} IPOPT iterations): "
                f"solved in {self.resolved_runs}/{runs} runs (the others fly the planned spline), iterations mean "
                f"{self.iterations_mean:.1f}, max {self.iterations_max}")

    def document(self) -> dict[str, Any]:
        """Its JSON object."""
        return {"mode": "as_planned" if self.resolve_iterations is None else "resolved_warm",
                "max_iterations": self.resolve_iterations, "resolved_runs": self.resolved_runs,
                "iterations_mean": self.iterations_mean, "iterations_max": self.iterations_max}


@dataclass(frozen=True)
class RobustnessReport:
    """Everything ``lutgen robustness`` reports (module docstring)."""

    model: ErrorModel
    samples: int
    seed: int
    step_s: float
    success: SuccessEstimate  # at scale 1
    tally: list[CheckTally]  # at scale 1
    sweep: list[ScalePoint]
    largest: LargestScale
    worst: WorstRun | None
    cost: RunCost
    runs: list[RunRecord]  # scale 1, in draw order
    stabilization: StabilizationMode

    def lines(self) -> list[str]:
        """The printed report."""
        s = self.success
        sig = self.model.sigmas()
        out = [f"error model  1-σ attitude {np.degrees(sig[:3]).round(4).tolist()} deg (body axes), "
               f"rate {np.degrees(sig[3:]).round(5).tolist()} deg/s; {self.samples} samples, seed {self.seed}",
               self.stabilization.line(self.samples),
               f"success      {s.successes}/{s.runs} = {s.probability:.3f}, {CONFIDENCE:.0%} Wilson interval "
               f"[{s.low:.3f}, {s.high:.3f}]"]
        for t in self.tally:
            out.append(f"  fails      {t.check:<36} first in {t.first:4d} runs, failed in {t.failed:4d}")
        for p in self.sweep:
            e = p.estimate
            out.append(f"  scale {p.scale:<6g} success {e.successes:4d}/{e.runs:<4d} = {e.probability:.3f} "
                       f"[{e.low:.3f}, {e.high:.3f}]")
        out.append(f"largest scale with ≥ {SUCCESS_TARGET:.0%} success: {self._largest_text()}")
        if self.worst is not None:
            w = self.worst
            out.append(f"worst run    sample {w.index}: min distance {w.min_distance_m.min():.4f} m, "
                       + ("feasible" if w.feasible else "fails " + ", ".join(w.failed)))
        c = self.cost
        out.append(f"cost         {c.wall_s:.1f} s wall ({c.main_wall_s:.1f} s at scale 1), {c.runs_executed} runs; "
                   f"per run: simulate {c.simulate_s_mean:.2f} s + verify {c.verify_s_mean:.2f} s; "
                   f"Planner builds {c.planner_build_s:.1f} s")
        return out

    def _largest_text(self) -> str:
        """The largest 95 % scale in words."""
        if self.largest.scale is None:
            return "none of the tested scales"
        beyond = " (every tested scale; the limit lies beyond)" if self.largest.beyond_tested else ""
        return f"{self.largest.scale:g}{beyond}"

    def document(self) -> dict[str, Any]:
        """The ``lutgen.robustness/1`` JSON object (angles in rad, rates in rad/s, times in s)."""
        def estimate(e: SuccessEstimate) -> dict[str, Any]:
            return {"successes": e.successes, "runs": e.runs, "probability": e.probability,
                    "interval": [e.low, e.high], "interval_method": f"Wilson score, {CONFIDENCE:.0%}"}

        w = self.worst
        return {
            "schema": SCHEMA,
            "error_model": {"covariance": self.model.covariance.tolist(),
                            "sigma_attitude_rad": self.model.sigmas()[:3].tolist(),
                            "sigma_rate_rad_s": self.model.sigmas()[3:].tolist(),
                            "frame": "target body; attitude error is a rotation vector composed on the right"},
            "samples": self.samples, "seed": self.seed, "verify_step_s": self.step_s,
            "stabilization": self.stabilization.document(),
            "success": estimate(self.success),
            "failures": [{"check": t.check, "first": t.first, "failed": t.failed} for t in self.tally],
            "sweep": [{"scale": p.scale, **estimate(p.estimate)} for p in self.sweep],
            "largest_scale_95": {"scale": self.largest.scale, "beyond_tested": self.largest.beyond_tested,
                                 "target": SUCCESS_TARGET},
            "worst_run": None if w is None else {
                "index": w.index, "feasible": w.feasible, "failed": list(w.failed),
                "min_distance_m": float(w.min_distance_m.min()), "t_s": w.t_s.tolist(),
                "distance_m": w.min_distance_m.tolist()},
            "cost_s": {k: (v if math.isfinite(v) else None) for k, v in vars(self.cost).items()},
            "runs": [{"attitude_wxyz": list(r.attitude_wxyz), "omega_body_rad_s": list(r.omega_body_rad_s),
                      "feasible": r.feasible, "failed": list(r.failed),
                      "margins": {k: (v if math.isfinite(v) else None) for k, v in r.margins.items()}}
                     for r in self.runs],
        }
