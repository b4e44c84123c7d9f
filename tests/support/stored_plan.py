"""A stored plan's samples over one phase, and its pair distances on verify's engine from pinocchio's kinematics: the
independent reference the NLP engine's dense clearance checks are held to."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lut.output.plan_file import load_plan
from lut.output.preview_geometry import chaser_body_poses, pose_matrices
from planner.collision.layout import TARGET_BODY, scene_layout
from planner.config.scenario import Scenario
from planner.model.target import TargetMotion, TargetState
from planner.verify.collision import sweep_pairs

ROOT = Path(__file__).resolve().parents[2]
PLAN_II = ROOT / "tests" / "data" / "plan_II.json.gz"


@dataclass(frozen=True)
class StoredPhase:
    """One phase of a stored plan: times [s since the observation] ``(n,)``, joints ``(n, 7)``, base poses
    ``(n, 7)``, and the samples' dict (every sample of the plan, ``rows`` selecting the phase's)."""

    start_s: float
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    x_base: np.ndarray
    samples: dict[str, np.ndarray]
    rows: np.ndarray
    motion: TargetMotion


def stored_phase(sc: Scenario, phase: str, path: Path = PLAN_II) -> StoredPhase:
    """``phase`` (``approach``, ``tracking``) of the plan stored at ``path``, made for scenario ``sc``."""
    doc = load_plan(path)
    s = {k: np.asarray(v, dtype=float) for k, v in doc["samples"].items() if k != "closest_pair"}
    start, end = doc["phases"][phase]
    rows = (s["t"] >= start - 1e-9) & (s["t"] <= end + 1e-9)
    state = TargetState(np.asarray(doc["target"]["attitude_wxyz"]), np.asarray(doc["target"]["omega_body_rad_s"]))
    return StoredPhase(start, s["t"][rows], s["q"][rows], s["qd"][rows],
                       np.hstack([s["base_position"][rows], s["base_wxyz"][rows]]), s, rows,
                       sc.target.motion(state, end + 1.0))


def _homogeneous(T: np.ndarray) -> np.ndarray:
    out = np.zeros((*T.shape[:-2], 4, 4))
    out[..., :3, :] = T
    out[..., 3, 3] = 1.0
    return out


def verify_engine_distances(sc: Scenario, phase: StoredPhase, pairs: list[tuple[str, str]]) -> np.ndarray:
    """Every one of ``pairs``' distance [m] at every sample of ``phase`` ``(n, len(pairs))``, from the stored bodies'
    poses (pinocchio) on verify's engine."""
    s, rows = phase.samples, phase.rows
    chaser = _homogeneous(chaser_body_poses(sc.robot, s["base_position"][rows], s["base_wxyz"][rows], s["q"][rows]))
    frames = {name: chaser[:, i] for i, name in enumerate(sc.robot.body_names)}
    frames[TARGET_BODY] = _homogeneous(pose_matrices(s["target_position"][rows], s["target_wxyz"][rows]))
    layout = scene_layout(sc.robot, sc.target)
    order = [layout.pair_names().index(f"{a}-{b}") for a, b in pairs]
    return sweep_pairs(layout, frames).distance_m[:, order]
