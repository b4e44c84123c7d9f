"""The tracking IK's one-call law (planner.phases.tracking_law) against independent references.

References: pinocchio's ``log3`` and ``exp3`` for the rotation log (identity, tiny angles on either side of the
series switch, moderate, near π and exactly π, where the axis' sign is free), pinocchio's centroidal momentum map and
frame Jacobian for the generalized Jacobian and the zero-momentum base twist, numpy's SVD pseudo-inverse for J*⁺, and
Eq. 7 written out here term by term. Then a whole tracking phase (the bundled scenario II plan's) integrated with the
compiled law against the same integration with numpy's SVD law at every call, and the singular pose a query's
tracking once reached, where the law must hand over to the SVD.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import pin_configuration
from planner.model.rotation import quat_to_matrix
from planner.phases import tracking as tracking_module
from planner.phases.tracking import RATE_CAP_FRACTION, RATE_CAP_POWER
from planner.phases.tracking_kinematics import TrackingKinematics
from planner.phases.tracking_law import WELL_CONDITIONED, TrackingLaw, rotation_log_sym, tracking_law_function

ROOT = Path(__file__).resolve().parents[3]
# the pose a query's tracking reached (scenario II flat spin at 1.17 °/s): J*'s smallest singular value 6e-10
SINGULAR_POSE = np.array([1.8980214189672147, -0.4146445056944511, 1.4467497414630615e-05, -0.041206072068663155,
                          0.030727501224786333, 0.7277885461044441, -2.1397757668851538])


def _gains(robot, K: float = 2.0, k_n: float = 0.5, qd_max: np.ndarray | None = None) -> np.ndarray:
    """The law's ``gains`` input: K, k_n, the rate cap's fraction and power, q̇_max."""
    return np.concatenate([[K, k_n, RATE_CAP_FRACTION, RATE_CAP_POWER], robot.qd_max if qd_max is None else qd_max])


@pytest.fixture(scope="module")
def ff(robot):
    return FreeFloatingModel(robot)


@pytest.fixture(scope="module")
def law(ff):
    return TrackingLaw.of(ff)


def _rotation_log():
    R = ca.SX.sym("R", 3, 3)
    return ca.Function("log", [R], [rotation_log_sym(R)])


def _rotations() -> list[tuple[str, np.ndarray]]:
    rng = np.random.default_rng(41)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    cases = [("identity", np.eye(3))]
    for angle in (1e-12, 1e-9, 0.5e-6, 2e-6, 1e-3, 0.7, 2.5, np.pi - 2e-3, np.pi - 0.5e-3, np.pi - 1e-7, np.pi):
        cases.append((f"{angle:.3g} rad", pin.exp3(angle * axis)))
    for k, e in enumerate(np.eye(3)):  # π about a coordinate axis: R − Rᵀ is exactly zero
        cases.append((f"pi about axis {k}", pin.exp3(np.pi * e)))
    return cases


def test_rotation_log_matches_pinocchio_from_identity_to_pi():
    log = _rotation_log()
    for name, R in _rotations():
        phi = np.asarray(log(R)).ravel()
        theta = np.linalg.norm(pin.log3(R))
        assert abs(np.linalg.norm(phi) - theta) < 1e-9, name
        np.testing.assert_allclose(pin.exp3(phi), R, atol=1e-9, err_msg=name)  # at π: either sign of the axis
        if theta < np.pi - 1e-6:
            np.testing.assert_allclose(phi, pin.log3(R), rtol=1e-9, atol=1e-15, err_msg=name)


def _pinocchio_jacobians(robot, q: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, pin.SE3]:
    """(base twist per unit q̇, base frame (6, n); ee twist per unit q̇, world (6, n); ee pose) at zero momentum."""
    model, data = robot.pin_model, robot.pin_model.createData()
    config = pin_configuration(x[:3], x[3:], q)
    A = pin.computeCentroidalMap(model, data, config)
    pin.computeJointJacobians(model, data, config)
    pin.framesForwardKinematics(model, data, config)
    fid = model.getFrameId(robot.ee_frame)
    J_ee = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    W = -np.linalg.solve(A[:, :6], A[:, 6:])
    return W, J_ee[:, :6] @ W + J_ee[:, 6:], data.oMf[fid]


def _capped(qd: np.ndarray, qd_max: np.ndarray) -> np.ndarray:
    r = np.sum((np.abs(qd) / qd_max / RATE_CAP_FRACTION) ** RATE_CAP_POWER) ** (1 / RATE_CAP_POWER)
    return qd / (1 + r**RATE_CAP_POWER) ** (1 / RATE_CAP_POWER)


def _state(robot, rng):
    q = rng.uniform(0.8 * robot.q_min, 0.8 * robot.q_max)
    quat = rng.normal(size=4)
    return q, np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat)])


def test_law_is_eq7_with_pinocchio_kinematics_and_the_svd_pseudo_inverse(robot, law):
    """Each term on its own (feed-forward twist; pose error; posture reference in the null space; the gains' ramp),
    rates small and large (the cap), against Eq. 7 written out with pinocchio's Jacobian and log3 and numpy's pinv."""
    rng = np.random.default_rng(43)
    n = robot.n_joints
    qd_max = robot.qd_max
    for _ in range(6):
        q, x = _state(robot, rng)
        W, J, oMee = _pinocchio_jacobians(robot, q, x)
        J_pinv = np.linalg.pinv(J)
        R_des = pin.exp3(rng.normal(scale=0.3, size=3)) @ oMee.rotation
        p_des = oMee.translation + rng.normal(scale=0.05, size=3)
        twist = rng.normal(scale=0.05, size=6)
        q_ref, qd_ref = q + rng.normal(scale=0.1, size=n), rng.normal(scale=0.05, size=n)
        desired = np.concatenate([R_des.ravel(order="F"), p_des, twist])
        error = np.concatenate([p_des - oMee.translation, pin.log3(R_des @ oMee.rotation.T)])
        # feed-forward alone; with the error; in the gains' ramp (σ scales the feedback and the null space, not the
        # feed-forward); capped
        for K, ramp, scale in ((0.0, 1.0, 1.0), (2.0, 1.0, 1.0), (2.0, 0.3, 1.0), (2.0, 1.0, 40.0)):
            posture = np.concatenate([[ramp], q_ref, qd_ref, [1.0]])
            at = law(q, x, desired, posture, _gains(robot, K, 0.0, qd_max / scale))
            null = ramp * (qd_ref + K * (q_ref - q))
            expected = _capped(J_pinv @ (twist + K * ramp * error) + (np.eye(n) - J_pinv @ J) @ null, qd_max / scale)
            np.testing.assert_allclose(at.qd, expected, rtol=1e-9, atol=1e-12)
            nu = W @ at.qd
            w, v = x[3], x[4:]
            quat_rate = 0.5 * np.concatenate([[-v @ nu[3:]], w * nu[3:] + np.cross(v, nu[3:])])
            np.testing.assert_allclose(at.x_base_rate, np.concatenate([quat_to_matrix(x[3:]) @ nu[:3], quat_rate]),
                                       atol=1e-12)
        assert at.demand > 1.0 and np.all(np.abs(at.qd) < RATE_CAP_FRACTION * qd_max / scale)  # asked over, capped
        assert WELL_CONDITIONED < at.conditioning <= 1.0


def test_without_a_posture_reference_the_null_space_holds_the_manipulability_gradient_alone(robot, ff, law):
    rng = np.random.default_rng(47)
    q, x = _state(robot, rng)
    _, J, oMee = _pinocchio_jacobians(robot, q, x)
    desired = np.concatenate([oMee.rotation.ravel(order="F"), oMee.translation, np.zeros(6)])
    garbage = np.full(robot.n_joints, 1e3)  # a reference's slots are ignored when the flag is 0
    at = law(q, x, desired, np.concatenate([[1.0], garbage, garbage, [0.0]]), _gains(robot))
    kinematics = TrackingKinematics.of(ff)
    J_pinv = np.linalg.pinv(J)
    expected = _capped((np.eye(robot.n_joints) - J_pinv @ J) @ (0.5 * kinematics(q, x).grad_manipulability),
                       robot.qd_max)
    np.testing.assert_allclose(at.qd, expected, rtol=1e-9, atol=1e-13)


def test_compiled_equals_interpreted(robot, ff, law):
    interpreted = TrackingLaw(tracking_law_function(ff), robot.n_joints)
    rng = np.random.default_rng(53)
    q, x = _state(robot, rng)
    args = (q, x, rng.normal(size=18), rng.normal(size=2 * robot.n_joints + 2), _gains(robot))
    a, b = law(*args), interpreted(*args)
    np.testing.assert_array_equal(a.qd, b.qd)
    np.testing.assert_array_equal(a.x_base_rate, b.x_base_rate)


def test_approaching_the_singular_pose_the_qr_pseudo_inverse_holds_until_the_hand_over(robot, ff, law):
    """On a seeded line into the singular pose, J*'s conditioning falling from 1e-3 to 1e-8: wherever the law keeps its
    QR pseudo-inverse (conditioning ≥ WELL_CONDITIONED), J*⁺ ẋ agrees with numpy's SVD to 1e-9 relative (numpy's own
    rounding there is ~κ ε ≈ 4e-10); the last steps are below the threshold, so the hand-over is exercised."""
    rng = np.random.default_rng(59)
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    direction = rng.normal(size=robot.n_joints)
    direction /= np.linalg.norm(direction)
    no_cap = _gains(robot, qd_max=robot.qd_max * 1e15)  # the rates grow as 1/σ_min: the cap must not act
    below = 0
    for step in (1e-2, 1e-3, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6, 1e-7):
        q = SINGULAR_POSE + step * direction
        twist = rng.normal(size=6)
        at = law(q, x, np.concatenate([np.eye(3).ravel(), np.zeros(3), twist]), np.zeros(2 * robot.n_joints + 2),
                 no_cap)
        reference = np.linalg.pinv(np.asarray(ff.gen_jacobian(q)[0])) @ twist  # base at the origin: J_world = J*
        if at.conditioning >= WELL_CONDITIONED:
            assert np.linalg.norm(at.qd - reference) <= 1e-9 * np.linalg.norm(reference), step
        else:
            below += 1
    assert below >= 2


def test_at_the_singular_pose_the_law_hands_over_to_the_svd(robot, law):
    """J*'s smallest singular value 6e-10: R⁻ᵀ is useless there, and the conditioning says so."""
    x = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    at = law(SINGULAR_POSE, x, np.concatenate([np.eye(3).ravel(), np.zeros(9)]),
             np.zeros(2 * robot.n_joints + 2), _gains(robot))
    assert at.conditioning < WELL_CONDITIONED


def test_a_tracking_phase_with_the_compiled_law_is_the_svd_laws_to_rounding(tracking_start, monkeypatch):
    """The bundled scenario II plan's tracking, integrated with the compiled law and with numpy's SVD law at every
    call (the conditioning threshold raised above 1): the same trajectory to rounding, the same peak demand."""
    controller, motion, t_start, q0, x_base0, q_nodes = tracking_start
    fast = controller.simulate(motion, t_start, q0, x_base0, q_nodes)
    monkeypatch.setattr(tracking_module, "WELL_CONDITIONED", 2.0)
    svd = controller.simulate(motion, t_start, q0, x_base0, q_nodes)
    assert not np.array_equal(fast.qd, svd.qd)  # the two really took different paths
    np.testing.assert_allclose(fast.q, svd.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.qd, svd.qd, rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.x_base, svd.x_base, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.qdd_end, svd.qdd_end, rtol=0, atol=1e-8)  # a 1e-4 s difference quotient
    assert abs(fast.peak_rate_demand - svd.peak_rate_demand) < 1e-12
    assert fast.peak_demand_time_s == svd.peak_demand_time_s
    assert fast.position_error_m < 1e-3
