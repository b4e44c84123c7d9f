"""The collision scene's layout: which bodies, which shapes, which pairs (pure data, paper §4.4, §5).

Bodies: the chaser's 8 bodies, ``target`` (the target's shapes but the handle) and ``handle`` (the shapes
marked ``handle = true``), which moves with the target's frame. Pairs: all non-adjacent chaser pairs (21
for the 8-body chaser) + each chaser body against the target (8) and against the handle (8) = 37. Which
clearance each pair must keep, phase by phase, is the handle-contact rule of :mod:`planner.collision.contact_rule`;
the stabilization's scene leaves out the one pair it exempts (gripper–handle: the gripper holds it).
Overscaling (paper §5, Eq. 15 cost) applies to the arm links only: scaling the base box as well would
make it swallow the shoulder and the target's neighbourhood, which says nothing about arm clearance.

The layout is shared by the NLPs (:mod:`planner.collision.nlp_scene` hands it to their distance engine) and
by verify (its own engine): both read the same specification, neither reads the other's engine.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

from planner.config.target import TargetConfig
from planner.model.robot import RobotModel
from planner.model.shapes import PlacedShape

TARGET_BODY = "target"
HANDLE_BODY = "handle"


@dataclass(frozen=True)
class CollisionBody:
    """A rigid body of the collision model: shapes placed in the body frame (``T_body_shape``, m).

    ``frame`` names the pose the body moves with (default: its own name); e.g. the target's grasp handle is
    a body of its own, so that pairs can treat it apart, that moves with the target's frame.
    """

    name: str
    shapes: tuple[PlacedShape, ...]
    frame: str | None = None

    @property
    def frame_name(self) -> str:
        """The name of the pose this body moves with."""
        return self.frame or self.name


@dataclass(frozen=True)
class SceneLayout:
    """Which bodies the scene has and which pairs are queried; pure data, shared by the NLPs and verify."""

    bodies: tuple[CollisionBody, ...]
    pairs: tuple[tuple[str, str], ...]
    gripper_handle: tuple[str, str] | None  # the one pair allowed to touch, at the grasp (None: no handle)
    arm_bodies: tuple[str, ...]  # the bodies overscaling enlarges

    def pair_names(self) -> list[str]:
        """``"A-B"`` per pair, in pair order."""
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


def default_pairs(chaser_bodies: Sequence[str], adjacent: Collection[tuple[str, str]],
                  target_bodies: Sequence[str]) -> list[tuple[str, str]]:
    """Collision pairs: all non-adjacent chaser body pairs, then every chaser body against every target body.

    Adjacency is unordered. Chaser pairs are ``(chaser_bodies[i], chaser_bodies[j])`` with ``i < j``; target
    pairs are ``(chaser, target)``, the target bodies in the given order, chaser-major.
    With 8 chained chaser bodies (7 adjacent pairs) and 2 target bodies (the target and its handle):
    28 - 7 + 16 = 37 pairs.

    Raises:
        ValueError: duplicate names, a body both chaser and target, an adjacent pair naming an unknown body.
    """
    chaser = list(chaser_bodies)
    target = list(target_bodies)
    if len(set(chaser)) != len(chaser) or len(set(target)) != len(target):
        raise ValueError("duplicate body names in default_pairs")
    if set(chaser) & set(target):
        raise ValueError(f"bodies both chaser and target: {sorted(set(chaser) & set(target))}")
    adj = set()
    for a, b in adjacent:
        if a not in chaser or b not in chaser:
            raise ValueError(f"adjacent pair ({a!r}, {b!r}) names a body not in chaser_bodies")
        adj.add(frozenset((a, b)))
    pairs = [(chaser[i], chaser[j]) for i in range(len(chaser)) for j in range(i + 1, len(chaser))
             if frozenset((chaser[i], chaser[j])) not in adj]
    return pairs + [(c, t) for c in chaser for t in target]
