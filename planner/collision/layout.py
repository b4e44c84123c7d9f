"""The collision scene of a scenario: chaser bodies, the target and its grasp handle (paper §4.4, §5).

Bodies: the chaser's 8 bodies, ``target`` (the target's shapes but the handle) and ``handle`` (the shapes
marked ``handle = true``), which moves with the target's frame. Pairs: all non-adjacent chaser pairs (21
for the 8-body chaser) + each chaser body against the target (8) and against the handle (8) = 37. Which
clearance each pair must keep, phase by phase, is the handle-contact rule of :mod:`planner.collision.contact_rule`;
the stabilization's scene leaves out the one pair it exempts (gripper–handle: the gripper holds it).
Overscaling (paper §5, Eq. 15 cost) applies to the arm links only: scaling the base box as well would
make it swallow the shoulder and the target's neighbourhood, which says nothing about arm clearance.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.collision.scene_distances import CollisionBody, CollisionScene, default_pairs
from planner.config.scenario import Scenario, TargetConfig
from planner.model.robot import RobotModel

Array = NDArray[np.float64]
TARGET_BODY = "target"
HANDLE_BODY = "handle"


@dataclass(frozen=True)
class SceneLayout:
    """Which bodies the scene has and which pairs are queried; pure data, shared by the NLPs and verify."""

    bodies: tuple[CollisionBody, ...]
    pairs: tuple[tuple[str, str], ...]
    gripper_handle: tuple[str, str] | None  # the one pair allowed to touch, at the grasp (None: no handle)
    arm_bodies: tuple[str, ...]  # the bodies overscaling enlarges

    def pair_names(self) -> list[str]:
        return [f"{a}-{b}" for a, b in self.pairs]

    def without_gripper_handle(self) -> SceneLayout:
        """The layout without the gripper–handle pair (the stabilization's scene)."""
        pairs = tuple(p for p in self.pairs if p != self.gripper_handle)
        return SceneLayout(self.bodies, pairs, None, self.arm_bodies)


def chaser_adjacent_pairs(robot: RobotModel) -> list[tuple[str, str]]:
    """Consecutive bodies of the serial chain (they touch at their joint by design)."""
    return list(zip(robot.body_names[:-1], robot.body_names[1:], strict=True))


def scene_layout(robot: RobotModel, target: TargetConfig) -> SceneLayout:
    """The default bodies and pairs of ``robot`` and ``target`` (module docstring)."""
    chaser = [CollisionBody(name, shapes) for name, shapes in zip(robot.body_names, robot.collision_shapes,
                                                                 strict=True)]
    rest = tuple(s for s in target.shapes if s.name not in target.handle_shapes)
    handle = tuple(s for s in target.shapes if s.name in target.handle_shapes)
    target_bodies = []
    if rest:
        target_bodies.append(CollisionBody(TARGET_BODY, rest))
    if handle:
        target_bodies.append(CollisionBody(HANDLE_BODY, handle, frame=TARGET_BODY))
    pairs = default_pairs(robot.body_names, chaser_adjacent_pairs(robot), [b.name for b in target_bodies])
    gripper_handle = (robot.body_names[-1], HANDLE_BODY) if handle else None
    return SceneLayout((*chaser, *target_bodies), tuple(pairs), gripper_handle, tuple(robot.body_names[1:]))


def build_collision_scene(layout: SceneLayout, scale: float = 1.0) -> CollisionScene:
    """The NLPs' collision scene of ``layout``; ``scale`` enlarges the arm links' shapes."""
    return CollisionScene(layout.bodies, layout.pairs, scale=dict.fromkeys(layout.arm_bodies, scale))


def build_scene(scenario: Scenario, scale: float = 1.0, gripper_handle: bool = False) -> CollisionScene:
    """The NLPs' collision scene of a scenario; the gripper–handle pair only when ``gripper_handle`` (approach)."""
    layout = scene_layout(scenario.robot, scenario.target)
    return build_collision_scene(layout if gripper_handle else layout.without_gripper_handle(), scale)


def world_poses(robot: RobotModel, fk_out: Sequence, R_world_base: Array, p_world_base: Array,
                T_world_target: Array) -> dict[str, Array]:
    """4×4 world poses of every scene frame from ``fk_function`` outputs and the base pose."""
    poses = {}
    for i, name in enumerate(robot.body_names):
        T = np.eye(4)
        T[:3, :3] = R_world_base @ np.asarray(fk_out[2 * i])
        T[:3, 3] = p_world_base + R_world_base @ np.asarray(fk_out[2 * i + 1]).ravel()
        poses[name] = T
    poses[TARGET_BODY] = T_world_target
    return poses
