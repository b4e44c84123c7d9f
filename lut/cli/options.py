"""Parsing the command line's values: comma-separated numbers, the observed target state, ``--cost`` terms,
and the output paths a plan may be written to (checked before anything is solved)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported lazily at run time: `lutgen --help` must not load the planner
    from planner.config.scenario import Scenario
    from planner.config.settings import CostWeights
    from planner.model.target import TargetState

MAX_BUDGET_S = 86400.0  # a plan's or query's time budget beyond a day is a typo [s]
COST_NAMES = ("manipulability", "min_distance", "approach_energy", "attitude_disturbance", "peak_wrench")


def parse_floats(text: str, count: int, option: str) -> list[float]:
    """``count`` comma-separated numbers of ``option`` (:class:`TargetStateError` naming it otherwise)."""
    from planner.errors import TargetStateError

    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise TargetStateError(f"{option}: expected {count} comma-separated numbers, got {text!r}") from None
    if len(values) != count:
        raise TargetStateError(f"{option}: expected {count} comma-separated numbers, got {text!r}")
    return values


def check_budget(budget_s: float) -> float:
    """``--budget-s`` [s], checked: in (0, :data:`MAX_BUDGET_S`]."""
    from planner.errors import LutgenError

    if not 0 < budget_s <= MAX_BUDGET_S:
        raise LutgenError(f"--budget-s: must be in (0, {MAX_BUDGET_S:g}] s, got {budget_s}")
    return budget_s


def with_earliest_start(scenario: Scenario, earliest_s: float | None) -> Scenario:
    """``scenario`` whose approach starts no earlier than ``--earliest-start-s`` [s] after the observation (as it is
    without the option), checked: within [0, its latest start]."""
    import math

    from planner.errors import LutgenError

    if earliest_s is None:
        return scenario
    latest = scenario.phases.max_start_delay_s
    if not (math.isfinite(earliest_s) and 0 <= earliest_s <= latest):
        raise LutgenError(f"--earliest-start-s: must be in [0, {latest:g}] s (the scenario's "
                          f"phases.max_start_delay_s), got {earliest_s}")
    return scenario.starting_from(earliest_s)


def cost_weights(base: CostWeights, specs: tuple[str, ...]) -> CostWeights:
    """Scenario cost weights with ``--cost name[=weight]`` overrides; ``--cost none`` = feasibility only."""
    from dataclasses import replace

    from planner.errors import ConfigError

    if not specs:
        return base
    weights = {name: 0.0 for name in COST_NAMES}
    overscale = base.overscale
    for spec in specs:
        if spec == "none":
            continue
        name, _, value = spec.partition("=")
        name = name.replace("-", "_")
        if name == "overscale":
            if not value:
                raise ConfigError("--cost", name, "needs a value: overscale=FACTOR")
            overscale = _cost_number(name, value)
            if overscale <= 0:
                raise ConfigError("--cost", name, f"must be > 0, got {value!r}")
            continue
        if name not in weights:
            raise ConfigError("--cost", name, f"unknown cost; choose from none, {', '.join(COST_NAMES)}, overscale")
        weights[name] = _cost_number(name, value) if value else 1.0
    return replace(base, **weights, overscale=overscale)


def _cost_number(name: str, text: str) -> float:
    """A finite, non-negative ``--cost`` value within the scenario file's sanity limit for ``costs.<name>``."""
    import math

    from planner.config.limits import violation
    from planner.errors import ConfigError

    try:
        value = float(text)
    except ValueError:
        raise ConfigError("--cost", name, f"must be a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise ConfigError("--cost", name, f"must be a finite number >= 0, got {text!r}")
    problem = violation(f"costs.{name}", value)
    if problem:
        raise ConfigError("--cost", name, problem)
    return value


def target_state_from_options(scenario: Scenario, attitude: str | None, omega_deg_s: str | None,
                              spin_rate_deg_s: float | None) -> TargetState:
    """The observed target state: the scenario's default, overridden by the CLI options."""
    import numpy as np

    from planner.errors import TargetStateError
    from planner.model.target import TargetState

    quat = np.asarray(scenario.target_state.attitude_wxyz)
    omega = np.asarray(scenario.target_state.omega_body_rad_s)
    if attitude is not None:
        quat = np.asarray(parse_floats(attitude, 4, "--attitude"))
    if omega_deg_s is not None:
        omega = np.radians(parse_floats(omega_deg_s, 3, "--omega-deg-s"))
    if spin_rate_deg_s is not None:
        if not np.isfinite(spin_rate_deg_s) or np.linalg.norm(omega) == 0:
            raise TargetStateError("--spin-rate-deg-s: needs a finite rate and a non-zero spin axis")
        omega = omega / np.linalg.norm(omega) * np.radians(spin_rate_deg_s)
    return TargetState(quat, omega)


def check_plan_outputs(inputs: list[str | Path], out_path: str | None, csv_path: str | None) -> None:
    """Refuse (before solving) a plan JSON or CSV path that is an input, a table, or in a missing folder."""
    from lut.output.paths import Output, check_outputs

    outputs = [Output(option, Path(path)) for option, path in (("--out", out_path), ("--csv", csv_path)) if path]
    check_outputs(inputs, outputs)

