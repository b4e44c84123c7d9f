"""Fixtures shared by the phase tests: scenario II's approach problem's dense clearance check (built once a module),
and the bundled scenario II plan's tracking start."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lut.output.plan_file import load_plan
from planner.config.scenario import load_scenario
from planner.model.freefloating import FreeFloatingModel
from planner.model.target import TargetState
from planner.phases.approach import ApproachProblem
from planner.phases.approach_clearance import ApproachClearance
from planner.phases.tracking import TrackingController
from planner.phases.tracking_profile import TRACKING_NODES

ROOT = Path(__file__).resolve().parents[3]
SCENARIO_II = ROOT / "configs" / "scenarios" / "scenario_II.toml"


@pytest.fixture(scope="module")
def clearance() -> ApproachClearance:
    """Scenario II's approach NLP's dense clearance check."""
    return ApproachClearance(ApproachProblem(load_scenario(SCENARIO_II)))


@pytest.fixture(scope="module")
def tracking_start():
    """The tracking phase's start in the bundled scenario II plan (tests/data/plan_II.json.gz, feasible): its
    controller, target motion, start time [s], joints, base pose and the plan's configurations at the tracking nodes."""
    scenario = load_scenario(SCENARIO_II)
    doc = load_plan(ROOT / "tests" / "data" / "plan_II.json.gz")
    s = doc["samples"]
    t_start = doc["phases"]["tracking"][0]
    i = int(np.argmin(np.abs(np.asarray(s["t"]) - t_start)))
    x_base = np.concatenate([s["base_position"][i], s["base_wxyz"][i]])
    state = TargetState(np.asarray(doc["target"]["attitude_wxyz"]), np.asarray(doc["target"]["omega_body_rad_s"]))
    motion = scenario.target.motion(state, doc["phases"]["stabilization"][1] + 1.0)
    controller = TrackingController(scenario, FreeFloatingModel(scenario.robot))
    # the posture the null space is pulled toward: the plan's own configurations at the tracking nodes
    t = np.asarray(s["t"])
    T = scenario.phases.tracking_s
    q_nodes = np.array([s["q"][int(np.argmin(np.abs(t - (t_start + f * T))))] for f in TRACKING_NODES])
    return controller, motion, float(t[i]), np.asarray(s["q"][i]), x_base, q_nodes
