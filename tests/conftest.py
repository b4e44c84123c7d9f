"""Shared fixtures: the bundled default robot and scenarios, loaded once per test session."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"

# Compiled NLP Functions (planner.nlp.compiled) go to the repository's own ignored cache, not the user's: a fresh
# clone compiles them once in its first test session (~15 s), later sessions load them. Subprocesses the
# tests start (the CLI, build workers) inherit it.
os.environ.setdefault("LUTGEN_CACHE_DIR", str(ROOT / ".lutgen-cache"))


@pytest.fixture(scope="session")
def robot():
    from planner.model.urdf import load_robot

    return load_robot(CONFIGS / "robots" / "chaser7.urdf")


@pytest.fixture(scope="session")
def ff_model(robot):
    from planner.model.freefloating import FreeFloatingModel

    return FreeFloatingModel(robot)
