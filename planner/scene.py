"""The collision scene of a scenario: chaser bodies + the target as one body (paper §4.4, §5).

Default pairs: all non-adjacent chaser pairs (21 for the 8-body chaser) + each chaser body vs the
target (8) = 29, the paper's m. The target's handle shapes (``handle = true``) are excluded from the
pair (last link, target): only the gripper touches them, and at the grasp it must.
Overscaling (paper §5, Eq. 15 cost) applies to the arm links only: scaling the base box as well would
make it swallow the shoulder and the target's neighbourhood, which says nothing about arm clearance.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from planner.collision import CollisionBody, CollisionScene, default_pairs
from planner.robot import RobotModel
from planner.scenario import Scenario, TargetConfig

Array = NDArray[np.float64]
TARGET_BODY = "target"


def chaser_adjacent_pairs(robot: RobotModel) -> list[tuple[str, str]]:
    """Consecutive bodies of the serial chain (they touch at their joint by design)."""
    return list(zip(robot.body_names[:-1], robot.body_names[1:], strict=True))


def build_collision_scene(robot: RobotModel, target: TargetConfig, scale: float = 1.0) -> CollisionScene:
    """The default scene of ``robot`` and ``target``; ``scale`` enlarges the arm links' shapes."""
    bodies = [CollisionBody(name, shapes) for name, shapes in zip(robot.body_names, robot.collision_shapes,
                                                                 strict=True)]
    bodies.append(CollisionBody(TARGET_BODY, target.shapes))
    pairs = default_pairs(robot.body_names, chaser_adjacent_pairs(robot), [TARGET_BODY])
    scales = {name: (scale if i > 0 else 1.0) for i, name in enumerate(robot.body_names)}
    excluded = {(robot.body_names[-1], TARGET_BODY): set(target.handle_shapes)}
    return CollisionScene(bodies, pairs, scale=scales, excluded_shapes=excluded)


def build_scene(scenario: Scenario, scale: float = 1.0) -> CollisionScene:
    """:func:`build_collision_scene` for a scenario's robot and target."""
    return build_collision_scene(scenario.robot, scenario.target, scale)


def world_poses(robot: RobotModel, fk_out: Sequence, R_world_base: Array, p_world_base: Array,
                T_world_target: Array) -> dict[str, Array]:
    """4×4 world poses of every scene body from ``fk_function`` outputs and the base pose."""
    poses = {}
    for i, name in enumerate(robot.body_names):
        T = np.eye(4)
        T[:3, :3] = R_world_base @ np.asarray(fk_out[2 * i])
        T[:3, 3] = p_world_base + R_world_base @ np.asarray(fk_out[2 * i + 1]).ravel()
        poses[name] = T
    poses[TARGET_BODY] = T_world_target
    return poses
