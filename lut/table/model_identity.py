"""The model a table answers for: one hash of the robot URDF, the target and the scenario texts."""

from __future__ import annotations

import hashlib
from pathlib import Path

from planner.config.scenario import Scenario


def model_hash(urdf_text: str, target_text: str, scenario_text: str) -> str:
    """Hex SHA-256 identifying robot + target + scenario; each text is length-prefixed, so it is unambiguous."""
    h = hashlib.sha256()
    for text in (urdf_text, target_text, scenario_text):
        data = text.encode("utf-8")
        h.update(f"{len(data)}:".encode("ascii"))
        h.update(data)
    return h.hexdigest()


def table_hash(scenario: Scenario) -> str:
    """:func:`model_hash` of ``scenario``'s files: a table answers only for this model."""
    urdf = Path(scenario.robot.urdf_path).read_text(encoding="utf-8")
    target = Path(scenario.target.source).read_text(encoding="utf-8")
    return model_hash(urdf, target, scenario.text)
