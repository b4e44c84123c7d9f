"""Tests of planner.model.target against independent references (conservation laws, closed forms, FD)."""

from __future__ import annotations

import numpy as np
import pytest

from planner.errors import ConfigError, TargetStateError
from planner.model.attitude import euler_rhs, propagate
from planner.model.rotation import (
    axis_angle_to_matrix,
    matrix_to_quat,
    quat_multiply,
    quat_to_matrix,
    rpy_to_matrix,
)
from planner.model.target import TargetBody, TargetMotion, TargetState

INERTIA_TUMBLE_KG_M2 = np.diag([5000.0, 3000.0, 7000.0])  # x intermediate, y minor, z major
OMEGA0_TUMBLE_RAD_S = np.deg2rad([2.0, -3.0, 1.5])


def _random_unit_quat(seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=4)
    return q / np.linalg.norm(q)


def _rotation_angle(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """Angle (rad) between rotations, batched. ‖R_a − R_b‖_F = 2√2 sin(θ/2) keeps full precision near
    θ = 0, where arccos((tr − 1)/2) would bottom out at ~1e-8 rad."""
    diff = np.linalg.norm(np.asarray(R_a) - np.asarray(R_b), axis=(-2, -1))
    return 2.0 * np.arcsin(np.clip(diff / (2.0 * np.sqrt(2.0)), 0.0, 1.0))


def _angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle (rad) between vectors, row-wise, via atan2 (accurate at small angles)."""
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.einsum("...i,...i->...", u, v))


def _vee(S: np.ndarray) -> np.ndarray:
    """Vector of the skew-symmetric part of (n, 3, 3) matrices."""
    A = 0.5 * (S - np.swapaxes(S, -1, -2))
    return np.stack([A[..., 2, 1], A[..., 0, 2], A[..., 1, 0]], axis=-1)


def _body(inertia: np.ndarray) -> TargetBody:
    T_body_grasp = np.eye(4)
    T_body_grasp[:3, :3] = rpy_to_matrix([0.3, -0.5, 1.1])
    T_body_grasp[:3, 3] = [0.8, -1.2, 1.5]
    return TargetBody(
        mass_kg=1500.0,
        inertia_body_kg_m2=inertia,
        p_world_com=np.array([12.0, -3.0, 4.0]),
        T_body_grasp=T_body_grasp,
    )


# ---- dynamics


def test_euler_rhs_matches_component_form() -> None:
    # Textbook component form of Euler's equations for a diagonal inertia.
    I1, I2, I3 = 5000.0, 3000.0, 7000.0
    w1, w2, w3 = 0.1, -0.2, 0.05
    expected = np.array([(I2 - I3) / I1 * w2 * w3, (I3 - I1) / I2 * w3 * w1, (I1 - I2) / I3 * w1 * w2])
    got = euler_rhs(np.diag([I1, I2, I3]), [w1, w2, w3])
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=0.0)
    batched = euler_rhs(np.diag([I1, I2, I3]), np.array([[w1, w2, w3], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(batched, [expected, np.zeros(3)], rtol=1e-14, atol=0.0)


def test_general_tumble_conserves_energy_and_world_momentum() -> None:
    inertia = INERTIA_TUMBLE_KG_M2
    motion = TargetMotion(_body(inertia), TargetState(_random_unit_quat(1), OMEGA0_TUMBLE_RAD_S), 100.0)
    assert not motion.trajectory.is_closed_form
    times = np.linspace(0.0, 100.0, 501)

    # Reference computed here, per sample, with planner.model.rotation (not the module's batched helpers).
    q_world_body = motion.trajectory.attitude_wxyz(times)
    omega_body = motion.trajectory.omega_body(times)
    energy_ref = 0.5 * np.einsum("ni,ij,nj->n", omega_body, inertia, omega_body)
    h_world_ref = np.array(
        [quat_to_matrix(q) @ (inertia @ w) for q, w in zip(q_world_body, omega_body, strict=True)]
    )

    energy0 = 0.5 * OMEGA0_TUMBLE_RAD_S @ inertia @ OMEGA0_TUMBLE_RAD_S
    h_world0 = quat_to_matrix(_random_unit_quat(1)) @ inertia @ OMEGA0_TUMBLE_RAD_S
    assert np.max(np.abs(energy_ref - energy0)) / energy0 <= 1e-9
    assert np.max(np.linalg.norm(h_world_ref - h_world0, axis=1)) / np.linalg.norm(h_world0) <= 1e-9
    # The module's own energy / momentum agree with the reference.
    np.testing.assert_allclose(motion.kinetic_energy(times), energy_ref, rtol=1e-13)
    np.testing.assert_allclose(motion.angular_momentum_world(times), h_world_ref, rtol=0, atol=1e-12 * 100)
    # The motion is a genuine tumble (otherwise conservation would be trivial): ω_body changes by O(1).
    assert np.max(np.linalg.norm(omega_body - OMEGA0_TUMBLE_RAD_S, axis=1)) > 0.3 * np.linalg.norm(
        OMEGA0_TUMBLE_RAD_S
    )


def test_quaternion_stays_unit_without_renormalisation() -> None:
    state = TargetState(_random_unit_quat(2), OMEGA0_TUMBLE_RAD_S)
    trajectory = propagate(INERTIA_TUMBLE_KG_M2, state, 100.0)
    times = np.linspace(0.0, 100.0, 501)
    raw_q = trajectory.dense_solution(times)[:4].T
    # q̇ = ½ q ⊗ [0, ω] preserves ‖q‖ exactly; drift only measures integration error.
    assert np.max(np.abs(np.linalg.norm(raw_q, axis=1) - 1.0)) <= 1e-10
    q = trajectory.attitude_wxyz(times)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, rtol=0, atol=1e-15)
    R = trajectory.R_world_body(times)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14)
    np.testing.assert_allclose(R[7], quat_to_matrix(q[7]), atol=1e-15)


def _perturbed_axis_spin(axis: int, rate_rad_s: float, t_end_s: float, seed: int) -> tuple:
    """Spin about body axis ``axis`` with a 1e-6 relative perpendicular perturbation."""
    e_body = np.eye(3)[axis]
    perp = np.cross(e_body, [0.3, 0.5, 0.7])
    perp /= np.linalg.norm(perp)
    omega0_body = rate_rad_s * (e_body + 1e-6 * perp)
    q0 = _random_unit_quat(seed)
    trajectory = propagate(INERTIA_TUMBLE_KG_M2, TargetState(q0, omega0_body), t_end_s)
    return trajectory, quat_to_matrix(q0) @ e_body


@pytest.mark.parametrize(("axis", "name"), [(2, "major"), (1, "minor")])
def test_stable_axis_spin_stays_flat(axis: int, name: str) -> None:
    trajectory, axis_world0 = _perturbed_axis_spin(axis, np.deg2rad(5.0), 100.0, seed=3)
    assert not trajectory.is_closed_form, f"{name}: the 1e-6 perturbation must take the integrator path"
    times = np.linspace(0.0, 100.0, 501)
    R_world_body = trajectory.R_world_body(times)
    omega_world = np.einsum("nij,nj->ni", R_world_body, trajectory.omega_body(times))
    assert np.max(_angle_between(omega_world, axis_world0)) < 1e-4
    assert np.max(_angle_between(R_world_body[:, :, axis], axis_world0)) < 1e-4


def test_intermediate_axis_spin_flips() -> None:
    # Dzhanibekov effect: the 1e-6 perturbation grows like exp(λ t), λ = ω √((I2−I1)(I3−I2)/(I1 I3)) ≈ 0.038
    # rad/s here, so the body x axis stays put for ~100 s and then flips; a frozen ω would never flip.
    trajectory, axis_world0 = _perturbed_axis_spin(0, np.deg2rad(5.0), 600.0, seed=4)
    times = np.linspace(0.0, 600.0, 1201)
    x_world = trajectory.R_world_body(times)[:, :, 0]
    angle = _angle_between(x_world, axis_world0)
    assert np.max(angle[times <= 100.0]) < 1e-3
    assert np.max(angle) > 2.5  # near π: the axis turned over
    omega_body = trajectory.omega_body(times)
    energy = 0.5 * np.einsum("ni,ij,nj->n", omega_body, INERTIA_TUMBLE_KG_M2, omega_body)
    assert np.max(np.abs(energy / energy[0] - 1.0)) <= 1e-9


def test_axisymmetric_matches_closed_form() -> None:
    I1, I3 = 4000.0, 6500.0
    inertia = np.diag([I1, I1, I3])
    omega0_body = np.deg2rad([2.0, -3.0, 1.5])
    q0 = _random_unit_quat(5)
    trajectory = propagate(inertia, TargetState(q0, omega0_body), 100.0)
    times = np.linspace(0.0, 100.0, 501)

    # Euler: ω3 constant, ω1 + i ω2 rotates at λ = (I3 − I1)/I1 · ω3.
    lam = (I3 - I1) / I1 * omega0_body[2]
    c, s = np.cos(lam * times), np.sin(lam * times)
    omega_ref = np.stack(
        [
            omega0_body[0] * c - omega0_body[1] * s,
            omega0_body[0] * s + omega0_body[1] * c,
            np.full_like(times, omega0_body[2]),
        ],
        axis=1,
    )
    assert np.max(np.abs(trajectory.omega_body(times) - omega_ref)) <= 1e-9

    # Attitude: ω = h/I1 − λ e3, so R(t) = Rot(ĥ_world, ‖h‖ t / I1) R0 Rot(e3, −λ t).
    R0 = quat_to_matrix(q0)
    h_world = R0 @ inertia @ omega0_body
    precession_rad_s = np.linalg.norm(h_world) / I1
    e3 = np.array([0.0, 0.0, 1.0])
    R_ref = np.array(
        [
            axis_angle_to_matrix(h_world, precession_rad_s * t) @ R0 @ axis_angle_to_matrix(e3, -lam * t)
            for t in times
        ]
    )
    assert np.max(_rotation_angle(trajectory.R_world_body(times), R_ref)) <= 1e-8


@pytest.mark.parametrize(
    ("inertia_diag", "omega0_body"),
    [
        ([5000.0, 3000.0, 7000.0], [0.0, 0.0, 0.08]),  # major axis
        ([5000.0, 3000.0, 7000.0], [-0.06, 0.0, 0.0]),  # intermediate axis (exact, so no flip)
        ([4000.0, 4000.0, 6500.0], [0.03, -0.04, 0.0]),  # any axis in the degenerate plane
        ([5000.0, 3000.0, 7000.0], [0.0, 0.0, 0.0]),  # at rest
    ],
)
def test_pure_spin_closed_form_matches_integration(inertia_diag: list, omega0_body: list) -> None:
    inertia = np.diag(inertia_diag)
    state = TargetState(_random_unit_quat(6), np.array(omega0_body))
    closed = propagate(inertia, state, 100.0)
    integrated = propagate(inertia, state, 100.0, force_integration=True)
    assert closed.is_closed_form
    assert not integrated.is_closed_form
    times = np.linspace(0.0, 100.0, 501)
    assert np.max(_rotation_angle(closed.R_world_body(times), integrated.R_world_body(times))) <= 1e-9
    q_closed, q_int = closed.attitude_wxyz(times), integrated.attitude_wxyz(times)
    assert np.max(np.abs(q_closed - q_int)) <= 1e-9  # same sign branch: both are continuous from q0
    assert np.max(np.abs(closed.omega_body(times) - integrated.omega_body(times))) <= 1e-9
    # Independent check of the closed form at one time: Rodrigues about the (fixed) spin axis.
    rate = np.linalg.norm(omega0_body)
    if rate > 0:
        R_ref = quat_to_matrix(state.attitude_wxyz) @ axis_angle_to_matrix(omega0_body, rate * 73.0)
        assert _rotation_angle(closed.R_world_body(73.0)[0], R_ref) <= 1e-12


def test_tiny_misalignment_uses_closed_form() -> None:
    omega0_body = 0.05 * np.array([1e-13, 0.0, 1.0])
    trajectory = propagate(INERTIA_TUMBLE_KG_M2, TargetState(_random_unit_quat(7), omega0_body), 10.0)
    assert trajectory.is_closed_form
    assert not propagate(
        INERTIA_TUMBLE_KG_M2, TargetState(_random_unit_quat(7), 0.05 * np.array([1e-9, 0.0, 1.0])), 10.0
    ).is_closed_form


def test_non_principal_body_frame_gives_same_world_motion() -> None:
    # The same physical body described in a body frame rotated by Q (non-diagonal inertia) must move
    # identically in the world: exercises the full-matrix Euler equations.
    Q = rpy_to_matrix([0.4, 0.2, -0.9])  # R_body_body2
    q0 = _random_unit_quat(8)
    q0_body2 = quat_multiply(q0, matrix_to_quat(Q))
    ref = propagate(INERTIA_TUMBLE_KG_M2, TargetState(q0, OMEGA0_TUMBLE_RAD_S), 50.0)
    state_body2 = TargetState(q0_body2, Q.T @ OMEGA0_TUMBLE_RAD_S)
    rotated = propagate(Q.T @ INERTIA_TUMBLE_KG_M2 @ Q, state_body2, 50.0)
    times = np.linspace(0.0, 50.0, 101)
    assert np.max(_rotation_angle(rotated.R_world_body(times), ref.R_world_body(times) @ Q)) <= 1e-9
    np.testing.assert_allclose(rotated.omega_body(times), ref.omega_body(times) @ Q, atol=1e-11)


# ---- grasp frame


def _fast_tumble_motion() -> TargetMotion:
    omega0_body = np.deg2rad([8.0, -12.0, 6.0])  # fast, so FD truncation dominates noise and is still tiny
    return TargetMotion(_body(INERTIA_TUMBLE_KG_M2), TargetState(_random_unit_quat(9), omega0_body), 60.0)


def test_grasp_pose_at_t0() -> None:
    motion = _fast_tumble_motion()
    body = motion.body
    R_world_body0 = quat_to_matrix(_random_unit_quat(9))
    R_world_grasp, p_world_grasp = motion.grasp_pose(0.0)
    np.testing.assert_allclose(R_world_grasp[0], R_world_body0 @ body.T_body_grasp[:3, :3], atol=1e-15)
    np.testing.assert_allclose(
        p_world_grasp[0], body.p_world_com + R_world_body0 @ body.T_body_grasp[:3, 3], atol=1e-14
    )
    R_world_body, p_world_com = motion.body_pose([0.0, 30.0])
    assert R_world_body.shape == (2, 3, 3)
    np.testing.assert_array_equal(p_world_com, [body.p_world_com, body.p_world_com])


def _relative_error(got: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(got - ref, axis=1)) / np.max(np.linalg.norm(ref, axis=1)))


def test_grasp_twist_matches_finite_differences() -> None:
    motion = _fast_tumble_motion()
    times = np.linspace(1.0, 59.0, 59)
    # Central-difference truncation is ≈ (‖ω‖ h)²/6 relative (‖ω‖ ≈ 0.27 rad/s): 1.4e-6 at h = 1e-2 s, 1.4e-8
    # at h = 1e-3 s (measured; clean h² convergence down to a ~1e-9 floor set by the integration error).
    h = 1e-3
    R_plus, p_plus = motion.grasp_pose(times + h)
    R_minus, p_minus = motion.grasp_pose(times - h)
    R_mid, _ = motion.grasp_pose(times)
    v_fd = (p_plus - p_minus) / (2 * h)
    omega_fd = _vee(((R_plus - R_minus) / (2 * h)) @ np.swapaxes(R_mid, 1, 2))  # Ṙ Rᵀ = [ω_world]×
    v_world_grasp, omega_world = motion.grasp_twist(times)
    assert _relative_error(v_world_grasp, v_fd) <= 1e-6
    assert _relative_error(omega_world, omega_fd) <= 1e-6


def test_grasp_acceleration_matches_finite_differences() -> None:
    motion = _fast_tumble_motion()
    times = np.linspace(1.0, 59.0, 59)
    h = 1e-3  # see test_grasp_twist_matches_finite_differences
    v_plus, omega_plus = motion.grasp_twist(times + h)
    v_minus, omega_minus = motion.grasp_twist(times - h)
    a_world_grasp, alpha_world = motion.grasp_acceleration(times)
    assert _relative_error(a_world_grasp, (v_plus - v_minus) / (2 * h)) <= 1e-6
    assert _relative_error(alpha_world, (omega_plus - omega_minus) / (2 * h)) <= 1e-6
    # omega_dot_body from Euler's equations is the derivative of the integrated ω_body.
    trajectory = motion.trajectory
    omega_dot_fd = (trajectory.omega_body(times + h) - trajectory.omega_body(times - h)) / (2 * h)
    assert _relative_error(trajectory.omega_dot_body(times), omega_dot_fd) <= 1e-6


# ---- inputs


@pytest.mark.parametrize(
    ("attitude", "omega", "field"),
    [
        ([1.0, 0.0, 0.0, 1e-2], [0.0, 0.0, 0.1], "attitude_wxyz"),  # norm 1 + 5e-5 > 1e-6 tolerance
        ([0.9, 0.0, 0.0, 0.0], [0.0, 0.0, 0.1], "attitude_wxyz"),
        ([np.nan, 0.0, 0.0, 1.0], [0.0, 0.0, 0.1], "attitude_wxyz"),
        ([1.0, 0.0, 0.0], [0.0, 0.0, 0.1], "attitude_wxyz"),
        ([1.0, 0.0, 0.0, 0.0], [0.0, np.inf, 0.1], "omega_body_rad_s"),
        ([1.0, 0.0, 0.0, 0.0], [0.0, np.nan, 0.1], "omega_body_rad_s"),
    ],
)
def test_bad_state_raises_target_state_error(attitude: list, omega: list, field: str) -> None:
    with pytest.raises(TargetStateError, match=field):
        TargetState(np.array(attitude), np.array(omega))


def test_nearly_unit_quaternion_is_accepted_and_renormalised() -> None:
    state = TargetState(np.array([1.0 + 5e-7, 0.0, 0.0, 0.0]), np.zeros(3))
    assert np.linalg.norm(state.attitude_wxyz) == pytest.approx(1.0, abs=1e-15)
    with pytest.raises(ValueError):
        state.attitude_wxyz[0] = 0.5  # frozen state is really read-only


@pytest.mark.parametrize(
    "inertia",
    [
        np.diag([5000.0, -3000.0, 7000.0]),
        np.diag([5000.0, 0.0, 7000.0]),
        np.array([[5000.0, 100.0, 0.0], [0.0, 3000.0, 0.0], [0.0, 0.0, 7000.0]]),  # not symmetric
        np.diag([5000.0, np.nan, 7000.0]),
        np.eye(2),
    ],
)
def test_bad_inertia_raises_config_error(inertia: np.ndarray) -> None:
    state = TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3))
    with pytest.raises(ConfigError, match="inertia_body_kg_m2"):
        propagate(inertia, state, 10.0)
    with pytest.raises(ConfigError, match="inertia_body_kg_m2"):
        TargetBody(1.0, inertia, np.zeros(3), np.eye(4))


def test_bad_body_fields_raise_config_error() -> None:
    with pytest.raises(ConfigError, match="mass_kg"):
        TargetBody(-1.0, np.eye(3), np.zeros(3), np.eye(4))
    with pytest.raises(ConfigError, match="p_world_com"):
        TargetBody(1.0, np.eye(3), np.array([0.0, np.nan, 0.0]), np.eye(4))
    T_bad = np.eye(4)
    T_bad[0, 0] = 2.0
    with pytest.raises(ConfigError, match="T_body_grasp"):
        TargetBody(1.0, np.eye(3), np.zeros(3), T_bad)


def test_times_outside_horizon_raise_value_error() -> None:
    state = TargetState(_random_unit_quat(10), OMEGA0_TUMBLE_RAD_S)
    trajectory = propagate(INERTIA_TUMBLE_KG_M2, state, 10.0)
    for bad in (-1e-9, [0.0, 10.0 + 1e-9], [np.nan]):
        with pytest.raises(ValueError, match="times_s"):
            trajectory.attitude_wxyz(bad)
    assert trajectory.attitude_wxyz([0.0, 10.0]).shape == (2, 4)  # both ends are inside
    assert trajectory.omega_body(5.0).shape == (1, 3)
    with pytest.raises(ValueError, match="t_end_s"):
        propagate(INERTIA_TUMBLE_KG_M2, state, 0.0)
