"""A scenario file: the robot, the target, their default state and every setting of one plan (TOML, SI).

Every user mistake — unknown or missing field, wrong type, negative mass, inertia that is not
symmetric positive definite, a range with min > max — raises a :class:`~planner.errors.ConfigError`
naming the file and the dotted field (``scenario_I.toml: phases.approach_s: must be > 0, got -1``).

Degrees appear only in the files, in field names ending in ``_deg``/``_deg_s``; the loaded objects are SI.
Relative paths inside a file are relative to that file's folder.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from planner.config.settings import (
    ApproachSettings,
    CostWeights,
    Limits,
    PhaseTimes,
    SolverSettings,
    StabilizationSettings,
    TargetStateConfig,
    TrackingSettings,
)
from planner.config.target import TargetConfig, load_target
from planner.config.toml_table import TomlTable, read_toml
from planner.config.variant import resolve_variant
from planner.errors import ConfigError
from planner.model.robot import RobotModel
from planner.model.urdf import load_robot

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Scenario:
    """Everything one plan needs, loaded and validated (SI units)."""

    source: str
    text: str  # the scenario file's text, its base's first for a variant (stored in tables for provenance)
    name: str
    robot: RobotModel
    target: TargetConfig
    target_state: TargetStateConfig
    q_initial: Array  # (n_joints,) [rad]
    base_offset_bounds_m: tuple[tuple[float, float], tuple[float, float]]  # orbital-plane x, z
    base_offset_guess_m: Array  # (2,) [m], orbital-plane x, z
    phases: PhaseTimes
    approach: ApproachSettings
    tracking: TrackingSettings
    stabilization: StabilizationSettings
    limits: Limits
    costs: CostWeights
    solver: SolverSettings
    base_source: str | None = None  # the scenario a variant extends (planner.config.variant), None for a plain one

    @property
    def input_files(self) -> list[str]:
        """Every file this scenario was read from: itself, its base, the robot URDF, the target file."""
        files = [self.source, *([self.base_source] if self.base_source else [])]
        return [*files, str(self.robot.urdf_path), self.target.source]

    def starting_from(self, earliest_s: float) -> Scenario:
        """This scenario with the approach's start-delay window beginning at ``earliest_s`` [s after the observation]
        (its end kept; not checked against it)."""
        return replace(self, phases=replace(self.phases, min_start_delay_s=float(earliest_s)))


@dataclass(frozen=True)
class _ChaserStart:
    """The ``[robot]`` table: the arm's joints at t = 0 [rad] and the admissible base offsets [m]."""

    q_initial: Array
    bounds_m: tuple[tuple[float, float], tuple[float, float]]
    guess_m: Array


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario TOML file, its robot URDF and its target file, and validate all of them."""
    path = Path(path)
    resolved = resolve_variant(path, *read_toml(path))
    data, text = resolved.data, resolved.text
    src = str(path)
    t = TomlTable(data, src)
    name = t.string("name")
    robot = _read_robot(t, path.parent)
    target = _read_target(t, path.parent)
    state = TargetStateConfig.read(t.table("target_state"))
    start = _read_chaser_start(t.table("robot"), robot)
    phases = PhaseTimes.read(t.table("phases"))
    approach = ApproachSettings.read(t.table("approach", default={}))
    tracking = TrackingSettings.read(t.table("tracking", default={}))
    stab = StabilizationSettings.read(t.table("stabilization", default={}))
    limits = Limits.read(t.table("limits", default={}))
    costs = CostWeights.read(t.table("costs", default={}))
    solver = SolverSettings.read(t.table("solver", default={}))
    t.finish()
    return Scenario(src, text, name, robot, target, state, start.q_initial, start.bounds_m, start.guess_m, phases,
                    approach, tracking, stab, limits, costs, solver,
                    None if resolved.base_path is None else str(resolved.base_path))


def _read_robot(t: TomlTable, base_dir: Path) -> RobotModel:
    """The robot of ``robot_urdf`` with its end-effector frame ``ee_frame`` (an ee_frame error names this file)."""
    urdf = t.string("robot_urdf")
    ee_frame = t.string("ee_frame", default="grasp_frame")
    if not (base_dir / urdf).is_file():
        raise t.error("robot_urdf", f"file not found: {base_dir / urdf}", urdf)
    try:
        return load_robot(base_dir / urdf, ee_frame=ee_frame)
    except ConfigError as exc:
        if exc.field != "ee_frame":
            raise
        raise t.error("ee_frame", f"{exc.problem} ({exc.source})", ee_frame) from None


def _read_target(t: TomlTable, base_dir: Path) -> TargetConfig:
    """The target file the ``target`` field names."""
    target_file = t.string("target")
    if not (base_dir / target_file).is_file():
        raise t.error("target", f"file not found: {base_dir / target_file}", target_file)
    return load_target(base_dir / target_file)


def _read_chaser_start(r: TomlTable, robot: RobotModel) -> _ChaserStart:
    """The ``[robot]`` table: initial joints inside the URDF limits, base-offset ranges and a guess inside them."""
    q0 = np.radians(r.vector("initial_joints_deg", robot.n_joints))
    bad = np.flatnonzero((q0 < robot.q_min) | (q0 > robot.q_max))
    if bad.size:
        raise r.error("initial_joints_deg", f"joint {bad[0] + 1} outside its URDF limits", np.degrees(q0).tolist())
    bx = r.range_("base_offset_x_m")
    bz = r.range_("base_offset_z_m")
    guess = r.vector("base_offset_guess_m", 2, default=[0.0, 0.0])
    if not (bx[0] <= guess[0] <= bx[1] and bz[0] <= guess[1] <= bz[1]):
        raise r.error("base_offset_guess_m", "guess must lie inside base_offset_x_m / base_offset_z_m",
                      guess.tolist())
    r.finish()
    return _ChaserStart(q0, (bx, bz), guess)
