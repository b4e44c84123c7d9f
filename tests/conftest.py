"""Shared fixtures: the bundled default robot and scenarios, loaded once per test session."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


@pytest.fixture(scope="session")
def robot():
    from planner.robot import load_robot

    return load_robot(CONFIGS / "robots" / "chaser7.urdf")


@pytest.fixture(scope="session")
def ff_model(robot):
    from planner.freefloating import FreeFloatingModel

    return FreeFloatingModel(robot)
