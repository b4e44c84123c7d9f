"""Fixtures shared by the phase tests: scenario II's approach problem's dense clearance check (built once a module)."""

from __future__ import annotations

from pathlib import Path

import pytest

from planner.config.scenario import load_scenario
from planner.phases.approach import ApproachProblem
from planner.phases.approach_clearance import ApproachClearance

SCENARIO_II = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_II.toml"


@pytest.fixture(scope="module")
def clearance() -> ApproachClearance:
    """Scenario II's approach NLP's dense clearance check."""
    return ApproachClearance(ApproachProblem(load_scenario(SCENARIO_II)))
