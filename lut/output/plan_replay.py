"""What a plan file needs to be executed again: its decision parameters, its scenario and the model it was made for.

The writer (:func:`replay_block`, used by :mod:`lut.output.export`) adds to a ``lutgen.plan/1`` document
``parameters`` (:class:`planner.plan_parameters.PlanParameters`, numbers written exactly: JSON keeps a
float's repr), ``scenario_file`` (relative to the folder lutgen ran in, like ``robot_urdf``) and
``model_hash`` (:func:`lut.table.model_identity.table_hash` of the scenario's files). The reader
(:func:`replay_inputs`) turns them back into the observed target state, the parameters and the scenario;
a plan written before these fields existed gets one line saying to re-export it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lut.output.plan_file import PlanFileError
from planner.plan_parameters import ApproachParameters, PlanParameters

if TYPE_CHECKING:
    from planner.config.scenario import Scenario
    from planner.model.target_state import TargetState
    from planner.plan import GraspPlan

REPO_ROOT = Path(__file__).resolve().parents[2]  # a stored relative scenario path is also tried from here
REEXPORT_HINT = "re-export it with this lutgen (lutgen plan or lutgen query --out)"


def parameters_block(plan: GraspPlan) -> dict[str, Any]:
    """The plan's decision parameters as JSON (angles [rad], times [s], offsets [m]); ``free_axis_angle_rad``
    is what the tracking IK chose at the observed state (informative: a re-execution computes its own)."""
    p = plan.parameters
    a = p.approach
    stab = p.stabilization_params
    return {
        "approach_params": np.asarray(a.params, dtype=float).tolist(),
        "base_offset_m": np.asarray(a.base_offset_m, dtype=float).tolist(),
        "start_delay_s": float(a.start_delay_s),
        "q_tracking_rad": np.asarray(a.q_tracking, dtype=float).tolist(),
        "stabilization_params": None if stab is None else np.asarray(stab, dtype=float).tolist(),
        "free_axis_angle_rad": float(plan.tracking.free_axis_angle_rad),
    }


def replay_block(plan: GraspPlan, scenario_file: str) -> dict[str, Any]:
    """``parameters``, ``scenario_file`` (as given: the caller makes it portable) and ``model_hash``."""
    from lut.table.model_identity import table_hash

    return {"parameters": parameters_block(plan), "scenario_file": scenario_file,
            "model_hash": table_hash(plan.scenario)}


@dataclass(frozen=True)
class ReplayInputs:
    """A plan file's inputs to re-execute it: observed state, decision parameters, scenario file and model hash."""

    state: TargetState
    parameters: PlanParameters
    scenario_file: str  # as stored (relative to the folder lutgen ran in)
    model_hash: str


def _array(block: dict[str, Any], key: str, source: str, ndim: int) -> np.ndarray:
    """``block[key]`` as a finite float array of ``ndim`` dimensions, else :class:`PlanFileError`."""
    try:
        arr = np.asarray(block[key], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise PlanFileError(f"{source}: parameters.{key}: missing or not numbers") from None
    if arr.ndim != ndim or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise PlanFileError(f"{source}: parameters.{key}: expected a finite {ndim}-D array, got shape {arr.shape}")
    return arr


def replay_inputs(doc: dict[str, Any], source: str) -> ReplayInputs:
    """The replay fields of a checked plan document (:func:`lut.output.plan_file.load_plan`)."""
    from planner.errors import TargetStateError
    from planner.model.target_state import TargetState

    block = doc.get("parameters")
    if not isinstance(block, dict) or not isinstance(doc.get("scenario_file"), str) \
            or not isinstance(doc.get("model_hash"), str):
        raise PlanFileError(f"{source}: the plan carries no decision parameters or scenario (an older plan file); "
                            + REEXPORT_HINT)
    delay = block.get("start_delay_s")
    if not isinstance(delay, int | float) or not math.isfinite(delay):
        raise PlanFileError(f"{source}: parameters.start_delay_s: expected a finite number of seconds")
    stab = block.get("stabilization_params")
    approach = ApproachParameters(_array(block, "approach_params", source, 1),
                                  _array(block, "base_offset_m", source, 1), float(delay),
                                  _array(block, "q_tracking_rad", source, 2))
    parameters = PlanParameters(approach, None if stab is None else _array(block, "stabilization_params", source, 1))
    target = doc.get("target") if isinstance(doc.get("target"), dict) else {}
    try:
        state = TargetState(np.asarray(target["attitude_wxyz"], dtype=float),
                            np.asarray(target["omega_body_rad_s"], dtype=float))
    except (KeyError, TypeError, ValueError, TargetStateError) as exc:
        raise PlanFileError(f"{source}: target.attitude_wxyz / omega_body_rad_s: not a valid state ({exc})") from None
    return ReplayInputs(state, parameters, doc["scenario_file"], doc["model_hash"])


def resolve_scenario(inputs: ReplayInputs, source: str, override: str | Path | None = None) -> Scenario:
    """The plan's scenario (``override`` if given; else as stored, against the current dir, then the repository
    root), loaded and checked to be the model the plan was made for."""
    from lut.table.model_identity import table_hash
    from planner.config.scenario import load_scenario

    if override is not None:
        path = Path(override)
    else:
        stored = Path(inputs.scenario_file)
        candidates = [stored] if stored.is_absolute() else [Path.cwd() / stored, REPO_ROOT / stored]
        path = next((c for c in candidates if c.is_file()), stored)
        if not path.is_file():
            raise PlanFileError(f"{source}: its scenario {inputs.scenario_file} is not there "
                                "(relative to this folder or the repository); pass --scenario")
    scenario = load_scenario(path)
    if table_hash(scenario) != inputs.model_hash:
        raise PlanFileError(f"{source}: the plan was made for another model than {path} (robot, target or scenario "
                            "changed since); plan again")
    return scenario
