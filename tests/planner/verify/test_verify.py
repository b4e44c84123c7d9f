"""Dense verification (planner.verify.verifier) on small synthetic plans built without any NLP solve.

The baseline plan: scenario II's chaser moves its joints smoothly (quintic blend) from an offset
configuration into a grasp configuration over the approach + tracking phases, the base integrated
with zero momentum, then holds still during stabilization. The target is static (ω = 0) and placed so
that its grasp frame coincides with the end-effector at t_grasp, so every check should pass. Each test
then breaks one property and expects verify to name it.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from planner.config.scenario import load_scenario
from planner.model.compound import compound_robot, grasp_geometry
from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import pin_configuration
from planner.model.rotation import matrix_to_quat, quat_to_matrix, rotation_log
from planner.model.target import TargetState
from planner.phases.stabilization import GraspState
from planner.plan import GraspPlan
from planner.verify.kinematics import derivatives, fd_weights, rotation_rates, select_samples
from planner.verify.verifier import VerifyReport, summary_lines, verify

CONFIGS = Path(__file__).resolve().parents[3] / "configs"
Q_GRASP = np.array([-0.549, 0.866, -1.88, -0.005, -1.129, 0.588, 0.925])  # attached target clear of the chaser
Q_OFFSET = np.array([0.15, -0.1, 0.1, 0.15, 0.1, -0.1, 0.1])  # start = Q_GRASP + Q_OFFSET
T0, T_APP, T_TR, T_ST = 0.5, 2.0, 1.0, 1.5  # start delay and phase durations (s)
T_GRASP = T0 + T_APP + T_TR
STEP = 0.01
X0 = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])


def smooth(s: float) -> tuple[float, float]:
    """Quintic 0→1 blend of s ∈ [0, 1] and its derivative d/ds."""
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s**2), 30 * s**2 * (1 - s) ** 2


def baseline_path(t: float) -> tuple[np.ndarray, np.ndarray]:
    S, dS = smooth((t - T0) / (T_APP + T_TR))
    return Q_GRASP + (1 - S) * Q_OFFSET, -dS / (T_APP + T_TR) * Q_OFFSET


def with_bump(path, joint: int, amplitude: float, t_start: float, duration: float):
    """``path`` plus ``amplitude · sin²(π u)`` on one joint for u = (t − t_start)/duration ∈ [0, 1]."""

    def bumped(t: float) -> tuple[np.ndarray, np.ndarray]:
        q, qd = path(t)
        u = (t - t_start) / duration
        if 0.0 <= u <= 1.0:
            q, qd = q.copy(), qd.copy()
            q[joint] += amplitude * np.sin(np.pi * u) ** 2
            qd[joint] += amplitude * np.pi / duration * np.sin(2 * np.pi * u)
        return q, qd

    return bumped


class Builder:
    """Synthetic GraspPlans for one scenario whose static target sits at the baseline's grasp pose."""

    def __init__(self) -> None:
        sc = load_scenario(CONFIGS / "scenarios" / "scenario_II.toml")
        self.ff = FreeFloatingModel(sc.robot)
        self.T_body_grasp = sc.target.grasp.T_body_grasp.copy()
        self.T_ee_target = np.linalg.inv(self.T_body_grasp)  # the ee frame is the grasp frame at the grasp
        self.ff_compound = FreeFloatingModel(compound_robot(sc, self.T_ee_target))
        n = round((T_APP + T_TR + T_ST) / STEP)
        self.t = T0 + STEP * np.arange(n + 1)
        self.k_grasp = round((T_APP + T_TR) / STEP)
        k_join = round(T_APP / STEP)
        self.phase_index = np.where(np.arange(n + 1) <= k_join, 0, np.where(np.arange(n + 1) <= self.k_grasp, 1, 2))
        # place the static target so that its grasp frame is the baseline's ee frame at t_grasp
        x = self.base(baseline_path)
        model = sc.robot.pin_model
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin_configuration(x[self.k_grasp, :3], x[self.k_grasp, 3:], Q_GRASP))
        T_world_body = data.oMf[model.getFrameId(sc.robot.ee_frame)].homogeneous @ self.T_ee_target
        # the synthetic path reaches the grasp straight through the boom, not along the approach axis as a planned
        # one does; these tests are about the other checks, so the target here has no handle (the handle-contact
        # rule has tests of its own)
        shapes = tuple(s for s in sc.target.shapes if s.name not in sc.target.handle_shapes)
        self.scenario = replace(sc, target=replace(sc.target, p_world_com=T_world_body[:3, 3].copy(), shapes=shapes,
                                                   handle_shapes=frozenset()))
        self.state = TargetState(matrix_to_quat(T_world_body[:3, :3]), np.zeros(3))

    def base(self, path, stabilization_ff: FreeFloatingModel | None = None) -> np.ndarray:
        """Base poses along ``path``: zero chaser momentum to the grasp, then the compound's (zero here)."""
        k = self.k_grasp
        x = np.empty((len(self.t), 7))
        x[: k + 1] = self.ff.integrate_base(self.t[: k + 1], path, X0)
        x[k:] = (stabilization_ff or self.ff_compound).integrate_base(self.t[k:], path, x[k], np.zeros(6))
        return x

    def plan(self, path=baseline_path, x_base: np.ndarray | None = None, **changes) -> GraspPlan:
        q, qd = (np.array(a) for a in zip(*(path(ti) for ti in self.t), strict=True))
        x = self.base(path) if x_base is None else x_base
        k = self.k_grasp
        grasp = GraspState(q[k], qd[k], np.zeros(7), x[k], np.zeros(6), self.T_ee_target)
        phases = {"approach": (T0, T0 + T_APP), "tracking": (T0 + T_APP, T_GRASP),
                  "stabilization": (T_GRASP, T_GRASP + T_ST)}
        plan = GraspPlan(self.scenario, self.state, None, None, None, grasp, self.T_body_grasp.copy(), phases,
                         self.t.copy(), q, qd, x, self.phase_index.copy())
        return replace(plan, **changes)


@pytest.fixture(scope="module")
def builder() -> Builder:
    return Builder()


@pytest.fixture(scope="module")
def baseline(builder: Builder) -> tuple[GraspPlan, VerifyReport]:
    plan = builder.plan()
    return plan, verify(plan)


def failed(report: VerifyReport) -> set[str]:
    return {name for name, c in report.checks.items() if not c.passed}


# ----------------------------------------------------------------------------------------------------
# The consistent plan passes, and the report is complete


def test_consistent_synthetic_plan_is_feasible(baseline):
    plan, report = baseline
    assert report.feasible, "\n".join(summary_lines(report))
    assert report.violations == []
    assert report.pair_count == 29 and len(report.pair_min_distance_m) == 29
    assert report.checks["momentum_chaser"].value < 1e-5  # FD error level, far below the 1e-3 limit
    assert report.checks["grasp_position"].value < 1e-9
    assert report.checks["grasp_velocity"].value < 1e-9
    assert all(c.margin >= 0 for c in report.checks.values())


def test_report_samples_cover_the_plan_at_the_requested_step(baseline):
    plan, report = baseline
    n = len(report.t)
    assert report.step_s <= 0.02 + 1e-12
    assert report.t[0] == plan.t[0] and report.t[-1] == plan.t[-1]
    for t_b in (T0 + T_APP, T_GRASP):  # phase joins are verified samples
        assert np.min(np.abs(report.t - t_b)) < 1e-9
    np.testing.assert_array_equal(plan.t[report.sample_index], report.t)
    assert report.min_distance_m.shape == (n,) and report.grasp_wrench.shape == (n, 6)
    for pose in (report.ee_pose, report.grasp_pose, report.target_pose, report.base_pose):
        assert pose.position_m.shape == (n, 3) and pose.wxyz.shape == (n, 4)
    assert np.all(report.grasp_wrench[report.t < T_GRASP - 1e-9] == 0.0)
    # at the grasp the gripper holds the grasp frame
    k = int(np.argmin(np.abs(report.t - T_GRASP)))
    np.testing.assert_allclose(report.ee_pose.position_m[k], report.grasp_pose.position_m[k], atol=1e-9)
    lines = summary_lines(report)
    assert lines[-1].startswith("verdict: FEASIBLE") and len(lines) == len(report.checks) + 3


def test_finer_step_verifies_every_stored_sample_and_bad_steps_are_refused(builder):
    plan = builder.plan()
    assert len(verify(plan, step_s=0.01).t) == len(plan.t)
    with pytest.raises(ValueError, match="step_s"):
        verify(plan, step_s=0.05)


# ----------------------------------------------------------------------------------------------------
# (1)–(4) of the brief: each broken property is caught and named


def test_joint_limit_crossing_is_reported_with_the_joint(builder):
    sc = builder.scenario
    j = 1  # joint2, upper limit 120°
    amplitude = sc.robot.q_max[j] - baseline_path(T0 + T_APP / 2)[0][j] + 0.05  # ~0.05 rad over, mid-approach
    report = verify(builder.plan(with_bump(baseline_path, j, amplitude, T0, T_APP)))
    assert not report.feasible
    check = report.checks["joint_position"]
    assert not check.passed and check.margin < -0.03
    assert "joint2 upper" in check.where
    assert check.limit == pytest.approx(sc.robot.q_max[j])
    assert T0 < check.t_s < T0 + T_APP
    assert any(v.startswith("joint_position") and "joint2" in v for v in report.violations)


def test_link_driven_into_the_base_is_reported_with_the_pair(builder):
    # joint2 swings the arm down onto the base box mid-approach (within its limits)
    path = with_bump(baseline_path, 1, 1.15, T0, T_APP)
    report = verify(builder.plan(path))
    assert report.checks["joint_position"].passed
    check = report.checks["collision"]
    assert not check.passed and check.value < 0.0
    assert "base_link-link" in check.where
    pair = check.where.split(" ")[0]
    assert report.pair_min_distance_m[pair] == pytest.approx(check.value)
    assert report.min_distance_m.min() == pytest.approx(check.value)
    assert T0 < check.t_s < T0 + T_APP
    assert any(v.startswith("collision") and pair in v for v in report.violations)


def test_momentum_check_needs_the_integrated_base(builder, baseline):
    _, report = baseline
    assert report.checks["momentum_chaser"].passed and report.checks["momentum_compound"].passed
    frozen = verify(builder.plan(x_base=np.tile(X0, (len(builder.t), 1))))
    check = frozen.checks["momentum_chaser"]
    assert not check.passed and check.value > 0.1  # O(1): the base does not cancel the arm's momentum
    assert any(v.startswith("momentum_chaser") for v in frozen.violations)


def test_compound_momentum_uses_the_target_attached_to_the_gripper(builder):
    """Arm motion during stabilization: the base integrated for the compound passes, for the bare chaser fails."""
    path = with_bump(baseline_path, 6, 0.2, T_GRASP, T_ST)
    good = verify(builder.plan(path))
    assert good.checks["momentum_compound"].value < 1e-4
    assert good.checks["momentum_chaser"].passed
    wrong = verify(builder.plan(path, x_base=builder.base(path, stabilization_ff=builder.ff)))
    assert not wrong.checks["momentum_compound"].passed and wrong.checks["momentum_compound"].value > 0.05


@pytest.mark.parametrize(("phase", "name"), [(1, "join_velocity_approach_tracking"),
                                             (2, "join_velocity_tracking_stabilization")])
def test_joint_velocity_jump_at_a_phase_join_is_caught(builder, phase, name):
    plan = builder.plan()
    jump = 1e-5  # rad/s, ten times the tolerance
    plan.qd[plan.phase_index == phase, 2] += jump
    report = verify(plan)
    check = report.checks[name]
    assert not check.passed
    assert check.value == pytest.approx(jump, rel=1e-3)
    assert "joint3" in check.where
    if phase == 2:
        assert report.checks["join_velocity_approach_tracking"].passed


def with_onset(path, joint: int, rate_rad_s: float, t_join: float, tau_s: float):
    """``path`` plus a rate onset on one joint after ``t_join``: ``q̇ += A x³ / (1 + x³)``, x = (t − t_join)/τ, and
    its exact integral on ``q`` (by quadrature): continuous with zero rate, acceleration and jerk at the join, but
    far from a quartic on the samples next to it, like the tracking IK's onset."""
    from scipy.integrate import quad

    def extra_rate(t: float) -> float:
        x = max(t - t_join, 0.0) / tau_s
        return rate_rad_s * x**3 / (1 + x**3)

    def onset(t: float) -> tuple[np.ndarray, np.ndarray]:
        q, qd = path(t)
        if t > t_join:
            q, qd = q.copy(), qd.copy()
            q[joint] += quad(extra_rate, t_join, t, epsabs=1e-14, epsrel=1e-12)[0]
            qd[joint] += extra_rate(t)
        return q, qd

    return onset


def test_a_continuous_rate_onset_at_a_join_is_not_a_jump_and_a_jump_on_it_is(builder):
    """A rate that grows like t³ from the join (the tracking's onset) is continuous: the one-sided extrapolation
    from the next samples misses it by more than 1e-6 rad/s, which is its truncation error, not a jump. The check
    passes it, and still catches a real jump ten times its resolution on the same onset."""
    t_join = T0 + T_APP
    onset = with_onset(baseline_path, 3, 0.036, t_join, 0.1)  # 36 t³ at first, as scenario II at 2 °/s
    plan = builder.plan(onset)
    tracking = np.flatnonzero(plan.phase_index == 1)
    quartic, cubic = (fd_weights(plan.t[tracking[:n]] - t_join, 0.0, 0) @ plan.qd[tracking[:n], 3] for n in (5, 4))
    assert abs(quartic - baseline_path(t_join)[1][3]) > 1e-5  # what the check used to call a jump
    check = verify(plan).checks["join_velocity_approach_tracking"]
    assert check.passed, check.where
    jump = 10 * (abs(quartic - cubic) + 1e-6)  # ten times what the check can resolve on joint 4
    plan.qd[tracking, 3] += jump
    check = verify(plan).checks["join_velocity_approach_tracking"]
    assert not check.passed and check.value == pytest.approx(jump, rel=0.2)


# ----------------------------------------------------------------------------------------------------
# Grasp, end state and wrench against independent references


def test_grasp_pose_and_velocity_errors_are_measured(builder):
    plan = builder.plan()
    T_bg = plan.T_body_grasp_used.copy()
    T_bg[:3, 3] += T_bg[:3, :3] @ np.array([0.0, 0.002, 0.0])  # grasp frame 2 mm off along its y axis
    report = verify(replace(plan, T_body_grasp_used=T_bg))
    assert report.checks["grasp_position"].value == pytest.approx(0.002, rel=1e-6)
    assert not report.checks["grasp_position"].passed

    omega_body = np.array([0.0, 0.0, 0.01])  # the target now spins at 0.01 rad/s: the gripper lags
    spinning = verify(replace(plan, target_state=TargetState(plan.target_state.attitude_wxyz, omega_body)))
    R_wb = pin.Quaternion(*plan.target_state.attitude_wxyz).toRotationMatrix()  # (w, x, y, z) constructor
    r = plan.T_body_grasp_used[:3, 3]  # COM → grasp point, body frame
    v_expected = np.linalg.norm(np.cross(R_wb @ omega_body, R_wb @ r))
    assert spinning.checks["grasp_velocity"].value == pytest.approx(v_expected, rel=1e-5)
    assert spinning.checks["grasp_angular_velocity"].value == pytest.approx(0.01, rel=1e-5)
    assert not spinning.checks["grasp_velocity"].passed and not spinning.checks["grasp_angular_velocity"].passed


def test_moving_at_the_end_of_stabilization_is_caught(builder):
    plan = builder.plan()
    plan.qd[-1, 4] = 2e-6
    check = verify(plan).checks["end_velocity"]
    assert not check.passed and check.value == pytest.approx(2e-6) and "joint5" in check.where


def test_grasp_wrench_matches_the_exact_derivative_formula(builder):
    """FD wrench of the attached target vs the stabilization NLP's exact (AD) wrench at several samples."""
    from planner.phases.stabilization import wrench_function

    duration, amplitude, j = T_ST, 0.2, 6
    path = with_bump(baseline_path, j, amplitude, T_GRASP, duration)
    plan = builder.plan(path)
    report = verify(plan)
    sc = builder.scenario
    fn = wrench_function(sc.robot)
    geometry = grasp_geometry(sc, builder.T_ee_target)
    peak = np.abs(report.grasp_wrench).max()
    assert peak > 1.0
    for i in np.flatnonzero(report.t >= T_GRASP - 1e-9)[::10]:
        k = report.sample_index[i]
        qdd = np.zeros(7)
        qdd[j] = amplitude * 2 * (np.pi / duration) ** 2 * np.cos(2 * np.pi * (plan.t[k] - T_GRASP) / duration)
        out = fn(plan.x_base[k], plan.q[k], plan.qd[k], qdd, np.zeros(6), geometry)
        F, M = (np.asarray(a).ravel() for a in out[:2])
        np.testing.assert_allclose(report.grasp_wrench[i], np.concatenate([F, M]), atol=1e-5 * peak)
    assert report.checks["grasp_torque"].value == pytest.approx(np.abs(report.grasp_wrench[:, 3:]).max())


# ----------------------------------------------------------------------------------------------------
# Building blocks


def test_finite_difference_weights():
    np.testing.assert_allclose(fd_weights(np.array([-1.0, 0.0, 1.0]), 0.0, 1), [-0.5, 0.0, 0.5])
    np.testing.assert_allclose(fd_weights(np.array([0.0, 1.0, 2.0, 3.0]), 0.0, 2), [2.0, -5.0, 4.0, -1.0])
    nodes = np.array([0.0, 0.3, 0.7, 1.2, 2.0])  # non-uniform: exact on quartics
    np.testing.assert_allclose(fd_weights(nodes, 0.5, 1) @ nodes**4, 4 * 0.5**3, rtol=1e-12)


def test_finite_difference_weights_for_many_stencils_at_once_equal_one_at_a_time():
    rng = np.random.default_rng(3)
    nodes = np.sort(rng.uniform(-1.0, 1.0, size=(50, 5)), axis=1)
    x0 = rng.uniform(-0.5, 0.5, size=50)
    for order in (0, 1, 2):
        rows = np.array([fd_weights(n, x, order) for n, x in zip(nodes, x0, strict=True)])
        np.testing.assert_allclose(fd_weights(nodes, x0, order), rows, rtol=1e-13, atol=1e-13)


def test_rotation_log_inverts_the_exponential_at_every_angle():
    """Oracle: pinocchio's exp3. Angles from 1e-9 rad to within 1e-12 rad of π (the axis-from-symmetric-part
    branch); the log is unique only below π, so the angles stay under it."""
    rng = np.random.default_rng(4)
    axes = rng.normal(size=(60, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([np.logspace(-9, 0, 30), np.pi - np.logspace(-12, -1, 30)])
    phi = axes * angles[:, None]
    R = np.array([pin.exp3(p) for p in phi])
    err = np.linalg.norm(rotation_log(R) - phi, axis=1)
    # near π the rotation matrix itself only holds the axis to ~1e-16 / sqrt(π − θ): 1e-8 rad at 1e-12 from π
    assert err[:30].max() < 1e-14
    assert err[30:].max() < 1e-7
    assert rotation_log(R).shape == (60, 3) and rotation_log(R[0]).shape == (3,)


@pytest.mark.parametrize("axis", np.vstack([np.eye(3), -np.eye(3)]), ids=["x", "y", "z", "-x", "-y", "-z"])
def test_rotation_log_degenerate_cases_about_a_coordinate_axis(axis):
    """The identity, and rotations about a coordinate axis of either sign (the symmetric part's diagonal
    picks the axis column, whose sign must come from sin θ · u) up to exactly π, where the log is ±π u:
    either sign must give the rotation back."""
    np.testing.assert_array_equal(rotation_log(np.eye(3)), np.zeros(3))
    for angle in (1e-12, 0.5, np.pi - 1e-3, np.pi - 1e-6):
        np.testing.assert_allclose(rotation_log(pin.exp3(axis * angle)), axis * angle, rtol=0.0, atol=1e-14)
    R_pi = pin.exp3(axis * np.pi)
    phi = rotation_log(R_pi)
    assert abs(np.linalg.norm(phi) - np.pi) < 1e-14
    assert abs(abs(phi @ axis) - np.pi) < 1e-14
    np.testing.assert_allclose(pin.exp3(phi), R_pi, rtol=0.0, atol=1e-14)


def test_quaternion_stacks_convert_like_single_quaternions():
    q = np.random.default_rng(5).normal(size=(4, 3, 4))
    stacked = quat_to_matrix(q)
    assert stacked.shape == (4, 3, 3, 3)
    np.testing.assert_array_equal(stacked[2, 1], quat_to_matrix(q[2, 1]))


def test_batched_derivatives_recover_analytic_rates_of_a_smooth_rotation():
    """R(t) = exp([ω₀ t + ½ α t²]×) about a fixed axis: ω = (ω₀ + α t) u, α_world = α u, exact; the
    5-point stencils err by O(h⁴) inside and O(h³) (first) / O(h³) (second) at the one-sided ends."""
    h, u = 0.01, np.array([0.6, 0.0, 0.8])
    t = np.arange(0.0, 1.0 + h / 2, h)
    angle = 0.3 * t + 0.5 * 0.7 * t**2
    R = np.array([pin.exp3(a * u) for a in angle])
    p = np.column_stack([np.sin(t), t**3, np.zeros_like(t)])
    k = np.arange(len(t))
    w, alpha = rotation_rates(t, R, k, (0, len(t) - 1))
    np.testing.assert_allclose(w, np.outer(0.3 + 0.7 * t, u), atol=1e-9)
    np.testing.assert_allclose(alpha, np.tile(0.7 * u, (len(t), 1)), atol=1e-6)
    v = derivatives(t, p, k, (0, len(t) - 1), 1)
    np.testing.assert_allclose(v, np.column_stack([np.cos(t), 3 * t**2, np.zeros_like(t)]), atol=1e-8)
    with pytest.raises(ValueError, match="outside their segment"):
        derivatives(t, p, [5, 50], (0, 40), 1)


def test_sample_selection_keeps_boundaries_and_the_step():
    t = np.round(np.arange(0.0, 1.0 + 1e-9, 0.01), 10)
    sel = select_samples(t, [0.0, 0.33, 1.0], 0.02)
    assert sel[0] == 0 and sel[-1] == len(t) - 1 and 33 in sel
    assert np.diff(t[sel]).max() <= 0.02 + 1e-12


@pytest.mark.slow
def test_solved_plan_is_consistent_under_verification():
    """End to end (~1 min): a solved scenario II plan's dynamics, grasp and joins verify.

    Only the solver-independent consistency checks are asserted: whether the stabilization also
    respects its limits *between* its via points is what verify is for, not a property of this test.
    """
    from planner.plan import Planner

    sc = load_scenario(CONFIGS / "scenarios" / "scenario_II.toml")
    state = sc.target_state.as_state()
    report = verify(Planner(sc).plan(state))
    for name in ("momentum_chaser", "momentum_compound", "joint_rate_consistency", "grasp_position",
                 "grasp_orientation", "grasp_velocity", "grasp_angular_velocity", "join_velocity_approach_tracking",
                 "join_velocity_tracking_stabilization", "end_velocity"):
        assert report.checks[name].passed, "\n".join(summary_lines(report))
    assert report.checks["momentum_chaser"].value < 1e-4 and report.checks["momentum_compound"].value < 1e-4
    assert report.pair_count == 37


def test_join_instants_stored_in_both_phases_verify_alike(builder, baseline):
    """A plan that stores each join instant twice (end of one phase, start of the next) verifies the same."""
    plan, report = baseline
    k_join, k_grasp = round(T_APP / STEP), builder.k_grasp
    order = np.concatenate([np.arange(k_join + 1), [k_join], np.arange(k_join + 1, k_grasp + 1), [k_grasp],
                            np.arange(k_grasp + 1, len(plan.t))])
    phase_index = plan.phase_index[order].copy()
    phase_index[k_join + 1], phase_index[k_grasp + 2] = 1, 2
    doubled = replace(plan, t=plan.t[order], q=plan.q[order], qd=plan.qd[order], x_base=plan.x_base[order],
                      phase_index=phase_index)
    again = verify(doubled)
    assert again.feasible, "\n".join(summary_lines(again))
    assert len(again.t) == len(report.t) + 2
    for name, check in report.checks.items():
        assert again.checks[name].value == pytest.approx(check.value, rel=1e-3, abs=1e-9), name
