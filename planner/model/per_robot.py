"""A value made once per robot model object and kept, a bounded number of them per process (the oldest goes first).

A :class:`~planner.model.robot.RobotModel` holds arrays and is not hashable, so it is kept by identity: the robot is
held beside its value, so its ``id`` is not reused while the value is here.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

from planner.model.robot import RobotModel

T = TypeVar("T")


class PerRobot(Generic[T]):
    """``make(robot)`` made at the first call for each robot object and returned again after; at most ``limit``
    kept."""

    def __init__(self, make: Callable[[RobotModel], T], limit: int) -> None:
        self._make, self._limit = make, limit
        self._kept: dict[int, tuple[RobotModel, T]] = {}

    def __call__(self, robot: RobotModel) -> T:
        kept = self._kept.get(id(robot))
        if kept is not None and kept[0] is robot:
            return kept[1]
        while len(self._kept) >= self._limit:
            del self._kept[next(iter(self._kept))]
        value = self._make(robot)
        self._kept[id(robot)] = (robot, value)
        return value
