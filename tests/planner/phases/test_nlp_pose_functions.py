"""The NLPs' one-call pose and base-step Functions against pinocchio and the model's own RK4 step.

The approach and stabilization NLPs take a via point's body poses from one SX Function each, and the approach
integrates its base with the zero-momentum twist split from the RK4 step (:func:`pose_rk4_step`). These are
checked here at the degenerate configurations (joints at zero, at their limits, elbow and wrist straight) where a
hand-written kinematic chain goes wrong first, and at seeded random ones.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.collision.layout import TARGET_BODY
from planner.config.scenario import load_scenario
from planner.model.compound import grasp_geometry
from planner.model.freefloating import pose_rk4_step
from planner.model.robot import fk_function, pin_configuration
from planner.model.rotation import quat_to_matrix
from planner.phases.approach_constraints import ScenePoses
from planner.phases.stabilization_dynamics import compound_poses_function
from tests.conftest import CONFIGS
from tests.planner.verify.test_verify_degenerate import CONFIG_NAMES, configurations

TOL = 1e-12  # rounding only: the same products in another order
BASE_P = np.array([0.3, -1.2, 0.7])
BASE_QUAT = np.array([0.8, 0.2, -0.5, 0.3]) / np.linalg.norm([0.8, 0.2, -0.5, 0.3])
X_BASE = np.concatenate([BASE_P, BASE_QUAT])


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(CONFIGS / "scenarios" / "scenario_II.toml")


def _pinocchio_world_poses(robot, q):
    """Every body's world pose (R, p) and the ee's, from pinocchio's frame placements with the free-flyer base."""
    model, data = robot.pin_model, robot.pin_model.createData()
    pin.framesForwardKinematics(model, data, pin_configuration(BASE_P, BASE_QUAT, q))
    ids = [model.getFrameId(b, pin.BODY) for b in robot.body_names] + [model.getFrameId(robot.ee_frame)]
    return [(data.oMf[i].rotation.copy(), data.oMf[i].translation.copy()) for i in ids]


def _blocks(stacked, n_frames):
    """Stacked ``[vec(R) column-major, p]`` blocks as a list of (R, p)."""
    b = np.asarray(stacked).ravel().reshape(n_frames, 12)
    return [(blk[:9].reshape(3, 3, order="F"), blk[9:]) for blk in b]


@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_approach_scene_poses_equal_pinocchio_world_placements(robot, name):
    q = configurations(robot)[name]
    R_target = quat_to_matrix(np.array([0.5, -0.5, 0.5, 0.5]))
    com = np.array([2.0, 0.1, -0.4])
    poses, R_ee, p_ee = ScenePoses(robot, fk_function(robot), com)(X_BASE, q, R_target)
    reference = _pinocchio_world_poses(robot, q)
    got = _blocks(poses, len(robot.body_names) + 1)
    for (R, p), (R_ref, p_ref), body in zip(got, [*reference[:-1], (R_target, com)],
                                             [*robot.body_names, TARGET_BODY], strict=True):
        np.testing.assert_allclose(R, R_ref, rtol=0, atol=TOL, err_msg=body)
        np.testing.assert_allclose(p, p_ref, rtol=0, atol=TOL * 10, err_msg=body)
    np.testing.assert_allclose(np.asarray(R_ee), reference[-1][0], rtol=0, atol=TOL)
    np.testing.assert_allclose(np.asarray(p_ee).ravel(), reference[-1][1], rtol=0, atol=TOL * 10)


@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_stabilization_poses_carry_the_target_on_the_gripper(scenario_II, name):
    """The compound's bodies where pinocchio puts them, the target at the grasp geometry's offset from the ee."""
    robot = scenario_II.robot
    q = configurations(robot)[name]
    T_ee_target = np.eye(4)
    T_ee_target[:3, :3] = quat_to_matrix(np.array([0.9, 0.1, 0.3, -0.2]) / np.linalg.norm([0.9, 0.1, 0.3, -0.2]))
    T_ee_target[:3, 3] = [0.05, -0.3, 0.8]
    reference = _pinocchio_world_poses(robot, q)
    R_ee, p_ee = reference[-1]
    poses = compound_poses_function(robot, fk_function(robot))(X_BASE, q, R_ee, p_ee,
                                                                grasp_geometry(scenario_II, T_ee_target))
    got = _blocks(poses, len(robot.body_names) + 1)
    target = (R_ee @ T_ee_target[:3, :3], p_ee + R_ee @ T_ee_target[:3, 3])
    for (R, p), (R_ref, p_ref) in zip(got, [*reference[:-1], target], strict=True):
        np.testing.assert_allclose(R, R_ref, rtol=0, atol=TOL)
        np.testing.assert_allclose(p, p_ref, rtol=0, atol=TOL * 10)


@pytest.mark.parametrize("name", [*CONFIG_NAMES, "random"])
def test_zero_momentum_split_step_is_the_rk4_step(robot, ff_model, name):
    """Twists at the step's start, midpoint and end, then the pose step: :meth:`rk4_step` at h_world = 0 (both
    RK4 stages at the midpoint take the same twist, which at zero momentum depends on the joints alone)."""
    rng = np.random.default_rng(3)
    q0 = configurations(robot)[name] if name != "random" else rng.uniform(robot.q_min, robot.q_max)
    qd0, qdm, qd1 = (rng.uniform(-1, 1, robot.n_joints) * robot.qd_max for _ in range(3))
    qm, q1 = q0 + 0.05 * qd0, q0 + 0.1 * qdm
    twist = ff_model.zero_momentum_twist
    for dt in (0.1, 1.0):
        split = pose_rk4_step()(X_BASE, twist(q0, qd0), twist(qm, qdm), twist(q1, qd1), dt)
        whole = ff_model.rk4_step(X_BASE, q0, qd0, qm, qdm, q1, qd1, np.zeros(6), dt)
        np.testing.assert_allclose(np.asarray(split).ravel(), np.asarray(whole).ravel(), rtol=0, atol=TOL)
        assert np.abs(np.asarray(split).ravel() - X_BASE).max() > 1e-4  # the base does move


@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_zero_momentum_twist_has_zero_pinocchio_momentum(robot, ff_model, name):
    """The twist the split step integrates gives the whole chaser zero momentum (pinocchio's centroidal map), and
    none at rest."""
    q = configurations(robot)[name]
    qd = np.random.default_rng(5).uniform(-1, 1, robot.n_joints) * robot.qd_max
    model, data = robot.pin_model, robot.pin_model.createData()
    A_g = pin.computeCentroidalMap(model, data, pin_configuration(BASE_P, BASE_QUAT, q))
    nu = np.asarray(ff_model.zero_momentum_twist(q, qd)).ravel()
    assert np.abs(A_g @ np.concatenate([nu, qd])).max() <= 1e-9 * np.abs(A_g).max()
    assert np.abs(nu).max() > 1e-4
    assert np.abs(np.asarray(ff_model.zero_momentum_twist(q, np.zeros(robot.n_joints)))).max() == 0.0
