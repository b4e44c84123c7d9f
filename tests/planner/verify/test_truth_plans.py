"""Stored plans (tests/data: the bundled ones and the seeded envelope states of scripts/make_truth_plans.py)
re-checked for collisions by verify's closed-form engine from their own samples, independently of the
metrics the plans carry: no plan called feasible may have a distance below what the contact rule asks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lut.output.plan_file import load_plan
from lut.output.preview_geometry import chaser_body_poses, pose_matrices
from planner.collision.contact_rule import APPROACH, STABILIZATION, TRACKING
from planner.collision.layout import TARGET_BODY, scene_layout
from planner.config.scenario import load_scenario
from planner.verify.collision import required_clearances, sweep_pairs

ROOT = Path(__file__).resolve().parents[3]
DATA = ROOT / "tests" / "data"
TRUTH = DATA / "truth"


def _stored_plans() -> list[tuple[str, Path, Path]]:
    """(name, plan file, scenario file) of every stored plan."""
    plans = [("plan_I", DATA / "plan_I.json.gz", ROOT / "configs/scenarios/scenario_I.toml"),
             ("plan_II", DATA / "plan_II.json.gz", ROOT / "configs/scenarios/scenario_II.toml")]
    index = json.loads((TRUTH / "index.json").read_text()) if (TRUTH / "index.json").is_file() else []
    for case in index:
        if "plan" in case:
            plans.append((case["name"], TRUTH / case["plan"], ROOT / case.get("scenario",
                                                                         "configs/scenarios/scenario_II.toml")))
    return plans


def _phase_index(t: np.ndarray, phases: dict[str, tuple[float, float]]) -> np.ndarray:
    """Phase of each sample; a sample on a join belongs to the earlier phase (the grasp instant is tracking)."""
    return np.where(t <= phases["approach"][1] + 1e-9, APPROACH,
                    np.where(t <= phases["tracking"][1] + 1e-9, TRACKING, STABILIZATION))


def _homogeneous(T: np.ndarray) -> np.ndarray:
    """(..., 3, 4) poses as (..., 4, 4)."""
    out = np.zeros((*T.shape[:-2], 4, 4))
    out[..., :3, :] = T
    out[..., 3, 3] = 1.0
    return out


def _slack(doc: dict, scenario_path: Path) -> tuple[np.ndarray, list[str]]:
    """(n, m) distance minus required clearance at every stored sample, and the pair names."""
    sc = load_scenario(scenario_path)
    s = {k: np.asarray(v, dtype=float) for k, v in doc["samples"].items() if k not in ("closest_pair",)}
    chaser = _homogeneous(chaser_body_poses(sc.robot, s["base_position"], s["base_wxyz"], s["q"]))
    frames = {name: chaser[:, i] for i, name in enumerate(sc.robot.body_names)}
    T_target = _homogeneous(pose_matrices(s["target_position"], s["target_wxyz"]))
    layout = scene_layout(sc.robot, sc.target)
    sweep = sweep_pairs(layout, frames | {TARGET_BODY: T_target})
    phases = {k: tuple(v) for k, v in doc["phases"].items()}
    required = required_clearances(layout, sc.limits.collision_margin_m, s["t"], _phase_index(s["t"], phases), phases,
                                   sc.approach.pregrasp_backoff_m)
    return sweep.distance_m - required, layout.pair_names()


@pytest.mark.parametrize(("name", "plan_path", "scenario_path"), _stored_plans(), ids=[p[0] for p in _stored_plans()])
def test_no_feasible_plan_violates_the_contact_rule(name: str, plan_path: Path, scenario_path: Path) -> None:
    doc = load_plan(plan_path)
    slack, names = _slack(doc, scenario_path)
    i, j = np.unravel_index(int(np.argmin(slack)), slack.shape)
    if doc["status"] == "feasible":
        assert slack[i, j] >= -1e-6, f"{name}: {names[j]} {slack[i, j]:.4g} m below its bound at t = " \
                                     f"{doc['samples']['t'][i]:.2f} s"


def test_the_stored_envelope_plans_exist_and_some_are_feasible() -> None:
    """The truth set is there: at least 20 seeded states, and feasible plans among them to check."""
    index = json.loads((TRUTH / "index.json").read_text())
    assert len(index) >= 20
    feasible = [c for c in index if c.get("exit_code") == 0]
    assert len(feasible) >= 10
    assert all((TRUTH / c["plan"]).is_file() for c in feasible)
