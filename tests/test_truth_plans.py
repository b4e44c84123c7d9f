"""Stored plans (tests/data: the bundled ones and the seeded envelope states of scripts/make_truth_plans.py)
re-checked for collisions by verify's closed-form engine from their own samples, independently of the
metrics the plans carry: no plan called feasible may have a distance below what the contact rule asks."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lut.plan_file import load_plan
from planner.contact_rule import APPROACH, STABILIZATION, TRACKING
from planner.scenario import load_scenario
from planner.scene import TARGET_BODY, scene_layout
from planner.verify_collision import required_clearances, sweep_pairs
from planner.verify_kinematics import PinKinematics

ROOT = Path(__file__).resolve().parents[1]
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


def _slack(doc: dict, scenario_path: Path) -> tuple[np.ndarray, list[str]]:
    """(n, m) distance minus required clearance at every stored sample, and the pair names."""
    sc = load_scenario(scenario_path)
    s = {k: np.asarray(v, dtype=float) for k, v in doc["samples"].items() if k not in ("closest_pair",)}
    chaser = PinKinematics(sc.robot)
    frames: dict[str, list[np.ndarray]] = {name: [] for name in sc.robot.body_names}
    for q, p, wxyz in zip(s["q"], s["base_position"], s["base_wxyz"], strict=True):
        chaser.forward(np.concatenate([p, wxyz]), q)
        for name, T in chaser.body_poses().items():
            frames[name].append(T)
    T_target = np.tile(np.eye(4), (len(s["t"]), 1, 1))
    T_target[:, :3, 3] = s["target_position"]
    w, x, y, z = s["target_wxyz"].T
    T_target[:, :3, :3] = np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)
    layout = scene_layout(sc.robot, sc.target)
    sweep = sweep_pairs(layout, {name: np.array(Ts) for name, Ts in frames.items()} | {TARGET_BODY: T_target})
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
