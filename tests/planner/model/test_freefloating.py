"""Momentum map, generalized Jacobian and base integration against pinocchio and finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from planner.model.robot import pin_configuration
from planner.model.rotation import quat_to_matrix


def _state(robot, rng):
    q = rng.uniform(robot.q_min, robot.q_max)
    qd = rng.uniform(-1, 1, size=robot.n_joints) * robot.qd_max
    quat = rng.normal(size=4)
    return q, qd, rng.uniform(-2, 2, size=3), quat / np.linalg.norm(quat)


def _to_base(R, h_world):
    return np.concatenate([R.T @ h_world[:3], R.T @ h_world[3:]])


@pytest.mark.parametrize("h_world", [np.zeros(6), np.array([12.0, -30.0, 5.0, 250.0, -80.0, 489.0])])
def test_base_twist_gives_the_required_pinocchio_momentum(robot, ff_model, h_world):
    """A_g(q) [ν_b; q̇] from pinocchio's centroidal map equals h₀ (0 before grasp, ≠ 0 after)."""
    model, data = robot.pin_model, robot.pin_model.createData()
    rng = np.random.default_rng(2)
    worst = 0.0
    for _ in range(50):
        q, qd, p, quat = _state(robot, rng)
        R = quat_to_matrix(quat)
        twist = np.asarray(ff_model.base_twist(q, qd, _to_base(R, h_world))).ravel()
        A_g = pin.computeCentroidalMap(model, data, pin_configuration(p, quat, q))
        worst = max(worst, np.abs(A_g @ np.concatenate([twist, qd]) - h_world).max())
    assert worst <= 1e-9


def test_momentum_matrices_match_pinocchio_centroidal_map(robot, ff_model):
    """A_b, A_m (base frame) equal pinocchio's centroidal map rotated into the base frame."""
    model, data = robot.pin_model, robot.pin_model.createData()
    rng = np.random.default_rng(3)
    for _ in range(20):
        q, _, p, quat = _state(robot, rng)
        R = quat_to_matrix(quat)
        A_b, A_m, r_g = (np.asarray(x) for x in ff_model.momentum(q))
        A_g = pin.computeCentroidalMap(model, data, pin_configuration(p, quat, q))
        Rb = np.kron(np.eye(2), R.T)
        np.testing.assert_allclose(np.hstack([A_b, A_m]), Rb @ A_g, atol=1e-9)
        np.testing.assert_allclose(p + R @ r_g.ravel(), data.com[0], atol=1e-12)


def _ee_pose(model, data, fid, x):
    pin.framesForwardKinematics(model, data, x)
    return data.oMf[fid].copy()


@pytest.mark.parametrize("h_world", [np.zeros(6), np.array([3.0, 1.0, -2.0, 40.0, 10.0, -25.0])])
def test_generalized_jacobian_matches_finite_differences_of_momentum_conserving_motion(robot, ff_model, h_world):
    """ee twist = J* q̇ + D h: compared with central differences of pinocchio FK, the base moving with
    the twist that pinocchio's centroidal map requires (an oracle independent of our momentum map)."""
    model, data = robot.pin_model, robot.pin_model.createData()
    fid = model.getFrameId(robot.ee_frame)
    rng = np.random.default_rng(4)
    eps = 1e-6
    for _ in range(20):
        q, qd, p, quat = _state(robot, rng)
        x = pin_configuration(p, quat, q)
        A_g = pin.computeCentroidalMap(model, data, x)
        nu_b = np.linalg.solve(A_g[:, :6], h_world - A_g[:, 6:] @ qd)  # pinocchio's own base twist
        v = np.concatenate([nu_b, qd])
        plus = _ee_pose(model, data, fid, pin.integrate(model, x, v * eps))
        minus = _ee_pose(model, data, fid, pin.integrate(model, x, -v * eps))
        v_fd = (plus.translation - minus.translation) / (2 * eps)
        w_fd = pin.log3(plus.rotation @ minus.rotation.T) / (2 * eps)
        R = quat_to_matrix(quat)
        J_star, D, _, _ = (np.asarray(a) for a in ff_model.gen_jacobian(q))
        twist_base = J_star @ qd + D @ _to_base(R, h_world)
        twist_world = np.concatenate([R @ twist_base[:3], R @ twist_base[3:]])
        ref = np.concatenate([v_fd, w_fd])
        assert np.linalg.norm(twist_world - ref) <= 1e-6 * np.linalg.norm(ref)


def _smooth_motion(robot, seed):
    """q(t) = q_mid + Σ a sin(ω t + φ): a smooth motion inside the joint limits (rad, rad/s)."""
    rng = np.random.default_rng(seed)
    amp = rng.uniform(0.1, 0.3, size=(3, robot.n_joints))
    om = rng.uniform(0.2, 0.8, size=(3, robot.n_joints))
    ph = rng.uniform(0, 2 * np.pi, size=(3, robot.n_joints))
    q_mid = 0.3 * rng.uniform(robot.q_min, robot.q_max)

    def joint_state(t):
        return (q_mid + (amp * np.sin(om * t + ph)).sum(0), (amp * om * np.cos(om * t + ph)).sum(0))

    return joint_state


@pytest.mark.parametrize("h_world", [np.zeros(6), np.array([5.0, -3.0, 2.0, 60.0, -20.0, 35.0])])
def test_integrated_base_motion_conserves_pinocchio_momentum(robot, ff_model, h_world):
    """Along 10 s of RK4-integrated motion, pinocchio's momentum of (base pose, base twist, q, q̇)
    stays h₀ at every step, and the integrated poses move with that twist (finite differences)."""
    model, data = robot.pin_model, robot.pin_model.createData()
    motion = _smooth_motion(robot, 5)
    dt = 0.02
    times = np.arange(0.0, 10.0 + dt / 2, dt)
    x0 = np.array([0.1, -0.2, 0.3, 1.0, 0.0, 0.0, 0.0])
    xs = ff_model.integrate_base(times, motion, x0, h_world)
    worst = 0.0
    twists = []
    for t, x in zip(times, xs, strict=True):
        q, qd = motion(t)
        R = quat_to_matrix(x[3:])
        nu = np.asarray(ff_model.base_twist(q, qd, _to_base(R, h_world))).ravel()
        twists.append(np.concatenate([R @ nu[:3], R @ nu[3:]]))
        A_g = pin.computeCentroidalMap(model, data, pin_configuration(x[:3], x[3:], q))
        worst = max(worst, np.abs(A_g @ np.concatenate([nu, qd]) - h_world).max())
    assert worst <= 1e-8
    assert np.all(np.abs(np.linalg.norm(xs[:, 3:], axis=1) - 1) < 1e-12)
    # the base position really moves with the momentum-conserving twist: central differences agree
    # to O(dt²) (here ~1e-7 m/s for base speeds ~1e-2 m/s)
    v_fd = (xs[2:, :3] - xs[:-2, :3]) / (2 * dt)
    v_map = np.array(twists)[1:-1, :3]
    assert np.abs(v_fd - v_map).max() <= 1e-5 * max(1.0, np.abs(v_map).max())
    assert np.abs(v_map).max() > 1e-3  # the base does move: the check above is not vacuous


def test_rk4_base_attitude_converges_at_fourth_order(robot, ff_model):
    """Halving the RK4 step divides the final base-attitude error by ~16 (2⁴)."""
    motion = _smooth_motion(robot, 6)
    x0 = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])

    def final_R(dt):
        times = np.linspace(0.0, 10.0, round(10.0 / dt) + 1)
        return quat_to_matrix(ff_model.integrate_base(times, motion, x0)[-1, 3:])

    R_ref = final_R(0.01)
    errors = [np.linalg.norm(pin.log3(final_R(dt).T @ R_ref)) for dt in (0.4, 0.2, 0.1)]
    ratios = [errors[0] / errors[1], errors[1] / errors[2]]
    assert errors[0] > 1e-8  # the error is measurable, far above round-off
    assert all(12.0 < r < 20.0 for r in ratios), (errors, ratios)
