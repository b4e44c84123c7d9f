"""A robustness analysis end to end: draw true states, run them at scale 1 and at every sweep scale, tally.

The runs at scale 1 (``samples`` of them) give the success probability, the failure tally and the worst run;
the sweep's other scales use the first ``sweep_samples`` of the same draws. Same request, same seed ⇒ same
figures (the draws come from the seed alone; every run is deterministic).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from lut.robustness.error_model import ErrorModel, perturbed_states, standard_draws
from lut.robustness.execution import BatchCost, RunOutcome, run_states
from lut.robustness.report import RobustnessReport, RunCost, RunRecord, StabilizationMode, WorstRun
from lut.robustness.statistics import failure_tally, success_estimate
from lut.robustness.sweep import ScalePoint, largest_scale
from planner.model.target_state import TargetState
from planner.plan_parameters import PlanParameters


@dataclass(frozen=True)
class RobustnessRequest:
    """What to analyse: a plan (observed state + parameters + scenario file) under an error model."""

    scenario_path: str
    state: TargetState
    parameters: PlanParameters
    model: ErrorModel
    samples: int
    seed: int
    scales: tuple[float, ...]  # error scales of the sweep (1 included)
    sweep_samples: int  # runs per sweep scale other than 1
    step_s: float  # verify's step [s]
    jobs: int
    resolve_iterations: int | None = None  # the stabilization re-solved warm within this many iterations (None: not)


def analyse(request: RobustnessRequest, on_done: Callable[[int], None] | None = None) -> RobustnessReport:
    """Run the request (``on_done(k)`` after every k finished runs, for a progress bar) and build its report."""
    z = standard_draws(max(request.samples, request.sweep_samples), request.seed)
    batches: dict[float, tuple[list[RunOutcome], BatchCost]] = {}
    main_states: list[TargetState] = []
    for scale in request.scales:
        n = request.samples if scale == 1.0 else min(request.sweep_samples, request.samples)
        states = perturbed_states(request.state, request.model, z[:n], scale)
        main_states = states if scale == 1.0 else main_states
        batches[scale] = run_states(request.scenario_path, request.parameters, states, request.step_s,
                                    request.jobs, on_done, request.resolve_iterations)
    main, main_cost = batches[1.0]
    sweep = [ScalePoint(scale, success_estimate(outcomes)) for scale, (outcomes, _) in batches.items()]
    executed = [o for outcomes, _ in batches.values() for o in outcomes]
    cost = RunCost(wall_s=sum(c.wall_s for _, c in batches.values()),
                   runs_executed=sum(c.executed for _, c in batches.values()),
                   planner_build_s=sum(c.planner_build_s for _, c in batches.values()),
                   simulate_s_mean=float(np.mean([o.simulate_s for o in executed])),
                   verify_s_mean=float(np.mean([o.verify_s for o in executed])),
                   main_wall_s=main_cost.wall_s)
    runs = [RunRecord(tuple(map(float, s.attitude_wxyz)), tuple(map(float, s.omega_body_rad_s)), o.feasible, o.failed,
                      o.margins) for s, o in zip(main_states, main, strict=True)]
    return RobustnessReport(request.model, request.samples, request.seed, request.step_s, success_estimate(main),
                            failure_tally(main), sweep, largest_scale(sweep), worst_run(main), cost, runs,
                            stabilization_mode(request.resolve_iterations, main))


def stabilization_mode(resolve_iterations: int | None, outcomes: list[RunOutcome]) -> StabilizationMode:
    """How ``outcomes`` (of scale 1) flew the stabilization, with the re-solves' iteration counts."""
    if resolve_iterations is None:
        return StabilizationMode(None)
    iterations = [o.resolve_iterations for o in outcomes if o.error == ""] or [0]
    return StabilizationMode(resolve_iterations, sum(o.resolved for o in outcomes), float(np.mean(iterations)),
                             int(max(iterations)))


def worst_run(outcomes: list[RunOutcome]) -> WorstRun | None:
    """The run that came closest to (or deepest into) collision: smallest collision margin (None: no run made)."""
    made = [(i, o) for i, o in enumerate(outcomes) if o.min_distance_m.size]
    if not made:
        return None
    i, o = min(made, key=lambda io: (io[1].margins.get("collision", np.inf), float(io[1].min_distance_m.min())))
    return WorstRun(i, o.feasible, o.failed, o.t_s, o.min_distance_m)
