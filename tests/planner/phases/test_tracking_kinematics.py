"""The tracking IK's one-call kinematics (planner.phases.tracking_kinematics) against independent references.

References: pinocchio's centroidal momentum map for the zero-momentum base twist and the generalized Jacobian
(a free-floating robot at zero momentum: A_b ν_b + A_m q̇ = 0), the manipulability's central differences for
its gradient, and the quaternion kinematics ``q̇ = ½ q ⊗ [0, ω]`` written out here. Configurations: q = 0, the
joint limits exactly, a wrist-singular pose and seeded random ones, at a turned, translated base.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import pin_configuration
from planner.model.rotation import quat_to_matrix
from planner.nlp.costs import manipulability
from planner.phases.tracking_kinematics import TrackingKinematics, tracking_kinematics_function


@pytest.fixture(scope="module")
def kinematics(robot):
    return TrackingKinematics.of(FreeFloatingModel(robot))


def _configurations(robot) -> list[np.ndarray]:
    rng = np.random.default_rng(23)
    wrist_singular = rng.uniform(0.5 * robot.q_min, 0.5 * robot.q_max)
    wrist_singular[5] = 0.0  # q6 = 0: axes 5 and 7 on one line
    return [np.zeros(robot.n_joints), robot.q_min.copy(), robot.q_max.copy(), wrist_singular,
            *rng.uniform(robot.q_min, robot.q_max, size=(4, robot.n_joints))]


def _base_pose(rng) -> np.ndarray:
    quat = rng.normal(size=4)
    return np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat)])


def _pinocchio_reference(robot, q: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(base twist per unit q̇ in the base frame (6, n), ee twist per unit q̇ in world (6, n), p_world_ee (3,))
    at zero momentum, from pinocchio's centroidal map of the free-flyer model."""
    model, data = robot.pin_model, robot.pin_model.createData()
    config = pin_configuration(x[:3], x[3:], q)
    A = pin.computeCentroidalMap(model, data, config)  # (6, 6 + n), world frame, about the CoM
    pin.computeJointJacobians(model, data, config)
    pin.framesForwardKinematics(model, data, config)
    fid = model.getFrameId(robot.ee_frame)
    J_ee = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)  # (6, 6 + n), [v; ω] world
    # zero momentum: A_b ν_b + A_m q̇ = 0, ν_b in pinocchio's free-flyer convention (base frame)
    W = -np.linalg.solve(A[:, :6], A[:, 6:])
    return W, J_ee[:, :6] @ W + J_ee[:, 6:], data.oMf[fid].translation.copy()


def test_tracking_kinematics_match_pinocchio_at_limits_singular_and_random_configurations(robot, kinematics):
    rng = np.random.default_rng(29)
    for q in _configurations(robot):
        x = _base_pose(rng)
        at = kinematics(q, x)
        _, J_ref, p_ref = _pinocchio_reference(robot, q, x)
        np.testing.assert_allclose(at.J_world, J_ref, atol=1e-10)
        np.testing.assert_allclose(at.p_world_ee_m, p_ref, atol=1e-10)


def test_base_pose_rate_is_the_quaternion_kinematics_of_the_zero_momentum_twist(robot, kinematics):
    rng = np.random.default_rng(31)
    for q in _configurations(robot):
        x, qd = _base_pose(rng), rng.normal(size=robot.n_joints)
        rate = kinematics.base_pose_rate(q, qd, x)
        W_ref, _, _ = _pinocchio_reference(robot, q, x)
        nu = W_ref @ qd
        omega = np.concatenate([[0.0], nu[3:]])
        w, v = x[3], x[4:]
        quat_dot = 0.5 * np.concatenate([[-v @ omega[1:]], w * omega[1:] + np.cross(v, omega[1:])])
        np.testing.assert_allclose(rate, np.concatenate([quat_to_matrix(x[3:]) @ nu[:3], quat_dot]), atol=1e-10)


def test_manipulability_gradient_matches_central_differences(robot, kinematics):
    ff = FreeFloatingModel(robot)
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    h = 1e-6
    for q in _configurations(robot)[4:]:  # random ones: at a singular one √det has no derivative
        fd = np.array([(manipulability(np.asarray(ff.gen_jacobian(q + h * e)[0]))
                        - manipulability(np.asarray(ff.gen_jacobian(q - h * e)[0]))) / (2 * h)
                       for e in np.eye(robot.n_joints)])
        np.testing.assert_allclose(kinematics(q, x).grad_manipulability, fd, atol=1e-7)


def test_compiled_equals_interpreted_and_evaluators_keep_their_own_results(robot, kinematics):
    """Compiled C gives the interpreted Functions' numbers bit for bit (the base twist: FreeFloatingModel's own);
    a returned KinematicsAt is not overwritten by later calls, of the same evaluator or of another one."""
    ff = FreeFloatingModel(robot)
    interpreted = TrackingKinematics(tracking_kinematics_function(ff), ff.base_twist, robot.n_joints)
    rng = np.random.default_rng(37)
    q1, q2 = rng.uniform(robot.q_min, robot.q_max, size=(2, robot.n_joints))
    x = _base_pose(rng)
    first = kinematics(q1, x)
    J_first = first.J_world.copy()
    other = kinematics.evaluator()
    second = other(q2, x)
    kinematics(q2, x)
    np.testing.assert_array_equal(first.J_world, J_first)
    assert not np.array_equal(second.J_world, J_first)
    for name in ("J_world", "R_world_ee", "p_world_ee_m", "grad_manipulability"):
        np.testing.assert_array_equal(getattr(interpreted(q1, x), name), getattr(first, name), err_msg=name)
    qd = rng.normal(size=robot.n_joints)
    np.testing.assert_array_equal(interpreted.base_pose_rate(q1, qd, x), kinematics.base_pose_rate(q1, qd, x))


def test_manipulability_and_its_gradient_stay_finite_at_singular_poses(robot, kinematics):
    """At a singular pose det(J* J*ᵀ) is zero or, by rounding, negative: √ of it and its gradient were NaN, the
    tracking IK's null space then NaN and the whole simulation with it (a query crashed with 'SVD did not
    converge'). Now the det is floored: the value is √DET_FLOOR and the gradient zero there, finite everywhere."""
    from planner.nlp.costs import DET_FLOOR

    ff = FreeFloatingModel(robot)
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    # the pose a query's tracking reached (scenario II flat spin at 1.17 °/s): smallest singular value 6e-10
    reached = np.array([1.8980214189672147, -0.4146445056944511, 1.4467497414630615e-05, -0.041206072068663155,
                        0.030727501224786333, 0.7277885461044441, -2.1397757668851538])
    singular = [reached, np.zeros(robot.n_joints), _configurations(robot)[3]]
    for q in singular:
        J = np.asarray(ff.gen_jacobian(q)[0])
        det = np.linalg.det(J @ J.T)
        grad = kinematics(q, x).grad_manipulability
        assert np.isfinite(grad).all(), q
        if det <= DET_FLOOR:
            assert manipulability(J) == np.sqrt(DET_FLOOR) and not grad.any(), q
    J = np.asarray(ff.gen_jacobian(reached)[0])
    assert np.linalg.det(J @ J.T) < 0.0  # the rounding case itself is tested, not only an exact zero
