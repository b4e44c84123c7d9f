"""A table point's robustness figure, recorded by ``lutgen build --robust``: its plan executed against drawn true
states in the point's own process, with the Planner that solved it (seeded by the point index)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from lut.robustness.error_model import ErrorModel, perturbed_states, standard_draws
from lut.robustness.execution import register_planner, run_states
from lut.robustness.statistics import success_estimate

if TYPE_CHECKING:
    from planner.model.target import TargetState
    from planner.plan import Planner
    from planner.plan_parameters import PlanParameters


def point_robustness(planner: Planner, scenario_path: str, state: TargetState, parameters: PlanParameters,
                     attitude_sigma_deg: float, rate_sigma_deg_s: float, samples: int, seed: int) -> dict[str, float]:
    """``success_probability``, its Wilson 95 % ``wilson_low``/``wilson_high``, ``runs`` and the σ's it was drawn
    with (deg, deg/s) of ``parameters`` flown against ``samples`` true states around ``state``."""
    register_planner(scenario_path, planner)
    model = ErrorModel.from_sigmas(math.radians(attitude_sigma_deg), math.radians(rate_sigma_deg_s))
    states = perturbed_states(state, model, standard_draws(samples, seed), 1.0)
    outcomes, _ = run_states(scenario_path, parameters, states, 0.02, jobs=1)
    e = success_estimate(outcomes)
    return {"success_probability": e.probability, "wilson_low": e.low, "wilson_high": e.high, "runs": float(e.runs),
            "attitude_sigma_deg": float(attitude_sigma_deg), "rate_sigma_deg_s": float(rate_sigma_deg_s)}
