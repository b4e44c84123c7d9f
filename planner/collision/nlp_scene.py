"""The NLPs' collision scene: a scenario's layout handed to their distance engine, and the frames' world poses."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from planner.collision.layout import TARGET_BODY, SceneLayout, scene_layout
from planner.collision.scene_distances import CollisionScene
from planner.config.scenario import Scenario
from planner.model.robot import RobotModel

Array = NDArray[np.float64]


def build_collision_scene(layout: SceneLayout, scale: float = 1.0) -> CollisionScene:
    """The NLPs' collision scene of ``layout``; ``scale`` enlarges the arm links' shapes."""
    return CollisionScene(layout.bodies, layout.pairs, scale=dict.fromkeys(layout.arm_bodies, scale))


def build_scene(scenario: Scenario, scale: float = 1.0, gripper_handle: bool = False) -> CollisionScene:
    """The NLPs' collision scene of a scenario; the gripper–handle pair only when ``gripper_handle`` (approach)."""
    layout = scene_layout(scenario.robot, scenario.target)
    return build_collision_scene(layout if gripper_handle else layout.without_gripper_handle(), scale)


def world_poses(robot: RobotModel, fk_out: Sequence, R_world_base: Array, p_world_base: Array,
                T_world_target: Array) -> dict[str, Array]:
    """(4, 4) world poses [m] of every scene frame from ``fk_function`` outputs and the base pose."""
    poses = {}
    for i, name in enumerate(robot.body_names):
        T = np.eye(4)
        T[:3, :3] = R_world_base @ np.asarray(fk_out[2 * i])
        T[:3, 3] = p_world_base + R_world_base @ np.asarray(fk_out[2 * i + 1]).ravel()
        poses[name] = T
    poses[TARGET_BODY] = T_world_target
    return poses
