"""A value made once per robot object: the same object returns it again, an equal copy of the robot does not (the
robot is kept by identity), and at the limit the oldest goes first."""

from __future__ import annotations

import copy

from planner.model.per_robot import PerRobot


def test_made_once_per_robot_object_and_the_oldest_dropped_at_the_limit(robot):
    made: list[int] = []

    def make(r):
        made.append(id(r))
        return object()

    kept = PerRobot(make, limit=2)
    first = kept(robot)
    assert kept(robot) is first and len(made) == 1
    twin = copy.copy(robot)  # equal in every field, another object
    assert kept(twin) is not first and len(made) == 2
    third = copy.copy(robot)  # the limit reached: the oldest (robot's) goes
    kept(third)
    assert kept(twin) is not None and len(made) == 3  # still kept
    assert kept(robot) is not first and len(made) == 4  # made again


def test_limit_one_keeps_only_the_last(robot):
    kept = PerRobot(lambda r: object(), limit=1)
    twin = copy.copy(robot)
    a = kept(robot)
    kept(twin)
    assert kept(robot) is not a
