"""The singular joint angles (neighbouring axes collinear) against pinocchio's Jacobian (the two neighbours' columns
equal: they move the end effector alike), and on hand-built chains where the angle is known, zero and not."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner.config.scenario import load_scenario
from planner.model.robot import ArmJoint
from planner.model.singular_joints import collinearity, singular_angles

SCENARIO_II = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_II.toml"


@pytest.fixture(scope="module")
def robot():
    return load_scenario(SCENARIO_II).robot


def _arm_jacobian(robot, q_arm: np.ndarray) -> np.ndarray:
    """The fixed-base ee Jacobian (6 × 7) by pinocchio, world-aligned: the base's columns left out."""
    model = robot.pin_model
    data = model.createData()
    q = np.concatenate([np.zeros(3), [0, 0, 0, 1], q_arm])
    frame = model.getFrameId(robot.ee_frame)
    return pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:, 6:]


def _neighbour_columns_gap(robot, q_arm: np.ndarray, j: int) -> float:
    """|J[:, j−1] − J[:, j+1]|: zero when joints j−1 and j+1 move the end effector alike (collinear axes)."""
    J = _arm_jacobian(robot, q_arm)
    return float(np.linalg.norm(J[:, j - 1] - J[:, j + 1]))


def test_the_chasers_singular_angles_are_its_pitch_joints_at_zero(robot):
    found = singular_angles(robot)
    assert [(s.joint_index, s.angle_rad) for s in found] == [(1, 0.0), (3, 0.0), (5, 0.0)]


def test_at_each_found_angle_pinocchio_moves_the_ee_alike_by_both_neighbours(robot):
    rng = np.random.default_rng(3)
    for s in singular_angles(robot):
        for _ in range(5):
            q = rng.uniform(robot.q_min, robot.q_max) * 0.8  # the other joints anywhere
            q[s.joint_index] = s.angle_rad
            assert _neighbour_columns_gap(robot, q, s.joint_index) < 1e-12
            q[s.joint_index] = s.angle_rad + 0.3
            assert _neighbour_columns_gap(robot, q, s.joint_index) > 1e-2


def test_joints_with_parallel_but_offset_neighbours_are_not_singular(robot):
    # joint 3 (about z) makes the y axes of joints 2 and 4 parallel at 0, 0.8 m apart: they move the ee differently
    q = np.array([0.3, 0.7, 0.0, 0.9, 0.4, 0.6, 0.2])
    assert _neighbour_columns_gap(robot, q, 2) > 1e-2
    assert 2 not in [s.joint_index for s in singular_angles(robot)]


def _joint(axis, rotation_about_x: float = 0.0, offset=(0.0, 0.0, 0.3), limits=(-2.5, 2.5)) -> ArmJoint:
    T = np.eye(4)
    c, s = np.cos(rotation_about_x), np.sin(rotation_about_x)
    T[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    T[:3, 3] = offset
    return ArmJoint("j", T, np.asarray(axis, dtype=float), *limits, 1.0)


def test_a_tilted_placement_moves_the_singular_angle_off_zero():
    # z-x-z chain whose third joint frame is tilted by 0.5 rad about x and placed along its own axis: its line is
    # the first's when the middle joint turns by −0.5
    along_tilted_z = (0.0, -0.3 * np.sin(0.5), 0.3 * np.cos(0.5))
    before, joint = _joint([0, 0, 1]), _joint([1, 0, 0])
    after = _joint([0, 0, 1], rotation_about_x=0.5, offset=along_tilted_z)
    assert collinearity(before, joint, after, -0.5) < 1e-24
    assert collinearity(before, joint, after, 0.0) > 1e-2

    class Chain:  # the fields singular_angles reads
        joints = (before, joint, after)

    found = singular_angles(Chain())
    assert len(found) == 1 and found[0].joint_index == 1
    assert found[0].angle_rad == pytest.approx(-0.5, abs=1e-9)


def test_a_joint_that_never_aligns_its_neighbours_has_none():
    # the third axis is offset sideways from the first's line: parallel at 0, never collinear
    before, joint, after = _joint([0, 0, 1]), _joint([1, 0, 0]), _joint([0, 0, 1], offset=(0.2, 0.0, 0.3))

    class Chain:
        joints = (before, joint, after)

    assert singular_angles(Chain()) == ()


class _Chain:
    """What singular_angles reads of a robot: its joints."""

    def __init__(self, *joints: ArmJoint) -> None:
        self.joints = joints


def _tilted_chain(middle_limits) -> _Chain:
    """The z-x-z chain above (singular at −0.5 rad), its middle joint limited to ``middle_limits``."""
    along_tilted_z = (0.0, -0.3 * np.sin(0.5), 0.3 * np.cos(0.5))
    return _Chain(_joint([0, 0, 1]), _joint([1, 0, 0], limits=middle_limits),
                  _joint([0, 0, 1], rotation_about_x=0.5, offset=along_tilted_z))


def test_a_singular_angle_at_a_joint_limit_is_found_and_one_beyond_it_is_not():
    at_limit = singular_angles(_tilted_chain((-0.5, 2.5)))
    assert len(at_limit) == 1 and at_limit[0].angle_rad == pytest.approx(-0.5, abs=1e-9)
    assert singular_angles(_tilted_chain((-0.5 + 1e-3, 2.5))) == ()  # a milliradian beyond the range: not reachable
    assert singular_angles(_tilted_chain((-2.5, -0.5 - 1e-3))) == ()
