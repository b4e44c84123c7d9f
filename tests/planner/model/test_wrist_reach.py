"""The wrist point and the reach radius about the chaser's centre of mass, against pinocchio's frames and centre of
mass."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin

from planner.model.robot import pin_configuration
from planner.model.wrist_reach import centre_of_mass_m, wrist_reach


def _random_pose(rng: np.random.Generator, robot) -> np.ndarray:
    quat = rng.normal(size=4)
    return pin_configuration(rng.uniform(-2, 2, size=3), quat / np.linalg.norm(quat), rng.uniform(robot.q_min,
                                                                                                   robot.q_max))


def _wrist_and_com(robot, index: int, q_pin: np.ndarray) -> tuple[pin.SE3, pin.SE3, np.ndarray]:
    """Body ``index``'s origin frame, the end-effector frame and the centre of mass, by pinocchio (world)."""
    model, data = robot.pin_model, robot.pin_model.createData()
    com = pin.centerOfMass(model, data, q_pin).copy()
    pin.forwardKinematics(model, data, q_pin)
    pin.updateFramePlacements(model, data)
    body = data.oMf[model.getFrameId(robot.body_names[index])]
    return body, data.oMf[model.getFrameId(robot.ee_frame)], com


def test_the_wrist_point_is_joint_6_origin_half_a_metre_behind_the_grasp(robot):
    wrist = wrist_reach(robot)
    # joint 7 turns about link 6's z, along which it sits 0.25 m out; the grasp frame is 0.25 m further along it;
    # joint 6 turns about y with joint 5's origin 0.35 m along z: not on its axis, so link 5's origin moves
    assert wrist.body_index == 6
    np.testing.assert_allclose(wrist.p_grasp_wrist_m, [0.0, 0.0, -0.5], atol=1e-15)


def test_the_wrist_point_stays_put_in_the_grasp_frame_and_the_next_origin_does_not(robot):
    wrist = wrist_reach(robot)
    rng = np.random.default_rng(3)
    below = []
    for q_pin in [_random_pose(rng, robot) for _ in range(200)] + [
            pin_configuration(np.zeros(3), np.array([1.0, 0, 0, 0]), limit) for limit in (robot.q_min, robot.q_max)]:
        body, ee, _ = _wrist_and_com(robot, wrist.body_index, q_pin)
        np.testing.assert_allclose(ee.actInv(body.translation), wrist.p_grasp_wrist_m, atol=1e-12)
        lower, ee, _ = _wrist_and_com(robot, wrist.body_index - 1, q_pin)
        below.append(ee.actInv(lower.translation))
    assert np.ptp(np.array(below), axis=0).max() > 0.3  # link 5's origin swings with joints 6 and 7


def test_the_centre_of_mass_is_pinocchios(robot):
    rng = np.random.default_rng(4)
    for _ in range(50):
        q = rng.uniform(robot.q_min, robot.q_max)
        _, _, com = _wrist_and_com(robot, 0, pin_configuration(np.zeros(3), np.array([1.0, 0, 0, 0]), q))
        np.testing.assert_allclose(centre_of_mass_m(robot, q), com, atol=1e-12)


def test_no_configuration_or_base_pose_holds_the_wrist_beyond_the_radius(robot):
    wrist = wrist_reach(robot)
    rng = np.random.default_rng(5)
    farthest = 0.0
    for _ in range(2000):
        body, _, com = _wrist_and_com(robot, wrist.body_index, _random_pose(rng, robot))
        farthest = max(farthest, float(np.linalg.norm(body.translation - com)))
    assert farthest <= wrist.radius_m


def test_the_arm_stretched_out_attains_the_radius_but_for_the_links_beyond_the_wrist(robot):
    # at q = 0 the arm points straight out along the base's x from the base's centre of mass, every body's centre of
    # mass on that line: each segment of the bound is attained, links 6 and 7 (beyond the wrist) counting against it
    wrist = wrist_reach(robot)
    body, _, com = _wrist_and_com(robot, wrist.body_index,
                                  pin_configuration(np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(7)))
    m6, m7 = robot.inertias[6].mass_kg, robot.inertias[7].mass_kg
    beyond = m6 * 0.125 + m7 * (0.25 + 0.075)  # link 6's and 7's centres of mass out from the wrist point
    np.testing.assert_allclose(np.linalg.norm(body.translation - com),
                               wrist.radius_m - 2 * beyond / robot.total_mass_kg, atol=1e-12)


def test_a_last_joint_off_its_axis_leaves_the_last_link_as_the_wrist(robot):
    joints = list(robot.joints)
    T = joints[-1].T_parent_joint.copy()
    T[:3, 3] = [0.05, 0.0, 0.25]  # joint 7 moved off its own axis: turning it moves link 6's origin
    joints[-1] = replace(joints[-1], T_parent_joint=T)
    wrist = wrist_reach(replace(robot, joints=tuple(joints)))
    assert wrist.body_index == 7
    np.testing.assert_allclose(wrist.p_grasp_wrist_m, -robot.T_last_ee[:3, 3], atol=1e-15)
