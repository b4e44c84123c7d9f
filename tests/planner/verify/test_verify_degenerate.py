"""Degenerate cases of verify's kinematics and joint checks (issue 19), against pinocchio computed here.

The kinematics the planner and ``verify`` use (symbolic FK, generalized Jacobian J* = J_m − J_b A_b⁻¹ A_m,
zero-momentum base twist, verify's :class:`PinKinematics`) are compared with pinocchio's own algorithms
(``forwardKinematics``, ``computeJointJacobians``/``getFrameJacobian``, ``ccrba``,
``computeCentroidalMomentum``) at configurations where a chain of axes degenerates: q = 0 (the arm
straight, axes 1, 3, 5, 7 on one line), the wrist singular (q6 = 0: axes 5 and 7 on one line; q5 = 0:
axes 4 and 6 parallel), the elbow straight (q4 = 0: axes 3 and 5 on one line), and every joint exactly
at its URDF limit. Then ``verify``'s joint box: a joint exactly at its bound (or rate exactly at its
limit) passes, 2e-6 beyond fails, and nothing else in the report changes.

Tolerance: every comparison is held to 1e-12 × its largest entry (× 1 for O(1) poses). Two float64
evaluations of the same kinematics in different algorithm orders differ by rounding only: measured worst
1.7e-15 relative (the base twist, through the 800 kg base's momentum matrix), so 1e-12 leaves ~600×
headroom for other BLAS/CPUs, while a wrong axis, lever or inertia term is O(1) relative.
"""

from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest
from numpy.typing import NDArray

from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import BodyInertia, RobotModel, fk_function
from planner.model.rotation import matrix_to_quat, quat_to_matrix
from planner.model.target import TargetState
from planner.plan import GraspPlan
from planner.verify.checks import FEASIBILITY_TOL, joint_checks
from planner.verify.kinematics import PinKinematics
from planner.verify.verifier import VerifyReport, verify
from tests.planner.verify.test_verify import T0, T_APP, Builder, baseline_path

Array = NDArray[np.float64]

BEYOND = 2e-6  # rad or rad/s past a limit: twice verify's FEASIBILITY_TOL (1e-6), so it must fail
TOL = 1e-12  # relative to the largest entry compared (module docstring): rounding only
BASE_P = np.array([0.3, -1.2, 0.7])
BASE_QUAT = np.array([0.8, 0.2, -0.5, 0.3]) / np.linalg.norm([0.8, 0.2, -0.5, 0.3])
CONFIG_NAMES = ("zero", "wrist_q6_zero", "wrist_q5_zero", "elbow_q4_zero", "wrist_elbow_straight", "all_lower",
                "all_upper", "alternating_lower_upper", "alternating_upper_lower", "upper_wrist_elbow_straight")


def configurations(robot: RobotModel) -> dict[str, Array]:
    """The degenerate joint configurations (rad) by name; the joints a name leaves free are seeded random."""
    rng = np.random.default_rng(19)
    lo, hi = robot.q_min, robot.q_max
    even = np.arange(robot.n_joints) % 2 == 0

    def with_zero(*joints: int) -> Array:  # joints counted from 1, as in the URDF
        q = rng.uniform(0.5 * lo, 0.5 * hi)
        q[[j - 1 for j in joints]] = 0.0
        return q

    upper_singular = hi.copy()
    upper_singular[[3, 5]] = 0.0
    return {"zero": np.zeros(robot.n_joints), "wrist_q6_zero": with_zero(6), "wrist_q5_zero": with_zero(5),
            "elbow_q4_zero": with_zero(4), "wrist_elbow_straight": with_zero(4, 6), "all_lower": lo.copy(),
            "all_upper": hi.copy(), "alternating_lower_upper": np.where(even, lo, hi),
            "alternating_upper_lower": np.where(even, hi, lo), "upper_wrist_elbow_straight": upper_singular}


def scale(a: Array) -> float:
    """Largest entry of ``a``, at least 1 (for poses: rotations are O(1) whatever the positions)."""
    return max(1.0, largest(a))


def largest(a: Array) -> float:
    return float(np.abs(a).max())


def blkdiag(R: Array) -> Array:
    return np.kron(np.eye(2), R)


@pytest.fixture(scope="module")
def payload_robot(robot: RobotModel) -> RobotModel:
    """The chaser holding a 1500 kg payload off-axis at the grasp frame (the stabilization's compound)."""
    T = np.eye(4)
    T[:3, :3] = quat_to_matrix([0.9, 0.1, -0.3, 0.2])
    T[:3, 3] = [0.0, 0.5, 1.7]
    return robot.with_payload(BodyInertia(1500.0, np.array([0.1, -0.2, 0.3]), np.diag([5e3, 3e3, 7e3])), T)


@pytest.fixture(scope="module")
def ff_models(robot: RobotModel, ff_model: FreeFloatingModel, payload_robot: RobotModel) -> dict:
    return {"chaser": ff_model, "with_payload": FreeFloatingModel(payload_robot)}


class PinReference:
    """Pinocchio's own algorithms at one free-flyer state (base pose ``BASE_P``, ``BASE_QUAT``)."""

    def __init__(self, robot: RobotModel, q: Array) -> None:
        self.model = robot.pin_model
        self.data = self.model.createData()
        w, x, y, z = BASE_QUAT  # pinocchio's own conversions, not the planner's pin_configuration
        self.R = pin.Quaternion(w, x, y, z).toRotationMatrix()
        self.x = np.concatenate([pin.SE3ToXYZQUAT(pin.SE3(self.R, BASE_P)), q])
        pin.forwardKinematics(self.model, self.data, self.x)
        pin.updateFramePlacements(self.model, self.data)
        self.ee_id = self.model.getFrameId(robot.ee_frame)
        pin.computeJointJacobians(self.model, self.data, self.x)
        self.J_ee = pin.getFrameJacobian(self.model, self.data, self.ee_id, pin.LOCAL_WORLD_ALIGNED).copy()
        self.A_g = pin.ccrba(self.model, self.data, self.x, np.zeros(self.model.nv)).copy()

    def joint_axes(self) -> list[tuple[Array, Array]]:
        """World (origin, unit axis) of each arm joint."""
        out = []
        for jid in range(2, self.model.njoints):
            M = self.data.oMi[jid]
            axis = self.model.joints[jid].shortname()[-1]
            out.append((M.translation.copy(), M.rotation[:, "XYZ".index(axis)].copy()))
        return out


# ----------------------------------------------------------------------------------------------------
# The configurations are what their names say


def test_degenerate_configurations_are_degenerate(robot):
    """The named configurations really align the named axes, sit exactly on the URDF limits, and q = 0 drops
    the fixed-base Jacobian to rank 3 (so the comparisons below exercise the degenerate cases)."""
    qs = configurations(robot)
    model = robot.pin_model

    def colinear(ref: PinReference, a: int, b: int) -> bool:
        (oa, ka), (ob, kb) = ref.joint_axes()[a - 1], ref.joint_axes()[b - 1]
        return np.linalg.norm(np.cross(ka, kb)) < 1e-12 and np.linalg.norm(np.cross(ka, ob - oa)) < 1e-12

    def parallel(ref: PinReference, a: int, b: int) -> bool:
        return np.linalg.norm(np.cross(ref.joint_axes()[a - 1][1], ref.joint_axes()[b - 1][1])) < 1e-12

    refs = {name: PinReference(robot, q) for name, q in qs.items()}
    assert all(colinear(refs["zero"], a, b) for a, b in ((1, 3), (3, 5), (5, 7)))
    assert np.linalg.matrix_rank(refs["zero"].J_ee[:, 6:], tol=1e-9) == 3
    assert colinear(refs["wrist_q6_zero"], 5, 7) and not colinear(refs["wrist_q5_zero"], 5, 7)
    assert parallel(refs["wrist_q5_zero"], 4, 6) and not parallel(refs["wrist_q6_zero"], 4, 6)
    assert colinear(refs["elbow_q4_zero"], 3, 5)
    assert colinear(refs["wrist_elbow_straight"], 3, 5) and colinear(refs["wrist_elbow_straight"], 5, 7)
    assert colinear(refs["upper_wrist_elbow_straight"], 3, 5) and colinear(refs["upper_wrist_elbow_straight"], 5, 7)
    np.testing.assert_array_equal(qs["all_lower"], model.lowerPositionLimit[7:])
    np.testing.assert_array_equal(qs["all_upper"], model.upperPositionLimit[7:])


# ----------------------------------------------------------------------------------------------------
# Symbolic FK, generalized Jacobian, base twist


@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_symbolic_fk_matches_pinocchio_at_degenerate_configurations(robot, name):
    """fk_function's body and ee poses (base frame) equal pinocchio's forwardKinematics placements."""
    q = configurations(robot)[name]
    ref = PinReference(robot, q)
    out = [np.asarray(a) for a in fk_function(robot)(q)]
    ids = [ref.model.getFrameId(b, pin.BODY) for b in robot.body_names] + [ref.ee_id]
    for k, fid in enumerate(ids):
        oMf = ref.data.oMf[fid]
        R_base, p_base = ref.R.T @ oMf.rotation, ref.R.T @ (oMf.translation - BASE_P)
        np.testing.assert_allclose(out[2 * k], R_base, rtol=0, atol=TOL, err_msg=f"{name} R[{k}]")
        np.testing.assert_allclose(out[2 * k + 1].ravel(), p_base, rtol=0, atol=TOL * scale(p_base),
                                   err_msg=f"{name} p[{k}]")


@pytest.mark.parametrize("model_name", ["chaser", "with_payload"])
@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_generalized_jacobian_matches_pinocchio_at_degenerate_configurations(robot, ff_models, model_name, name):
    """J* and D of FreeFloatingModel.gen_jacobian equal pinocchio's J_ee,m − J_ee,b A_g,b⁻¹ A_g,m and J_ee,b A_g,b⁻¹
    (frame Jacobian and ccrba, base frame), and its ee pose pinocchio's."""
    ff = ff_models[model_name]
    q = configurations(robot)[name]
    ref = PinReference(ff.robot, q)
    J_b, J_m, A_b, A_m = ref.J_ee[:, :6], ref.J_ee[:, 6:], ref.A_g[:, :6], ref.A_g[:, 6:]
    Rb = blkdiag(ref.R)
    J_star_ref = Rb.T @ (J_m - J_b @ np.linalg.solve(A_b, A_m))  # world ee twist per q̇ → base frame
    D_ref = Rb.T @ J_b @ np.linalg.inv(A_b) @ Rb  # ee twist (base) per momentum (base frame)
    J_star, D, R_ee, p_ee = (np.asarray(a) for a in ff.gen_jacobian(q))
    np.testing.assert_allclose(J_star, J_star_ref, rtol=0, atol=TOL * scale(J_star_ref))
    np.testing.assert_allclose(D, D_ref, rtol=0, atol=TOL * largest(D_ref))
    oMf = ref.data.oMf[ref.ee_id]
    np.testing.assert_allclose(R_ee, ref.R.T @ oMf.rotation, rtol=0, atol=TOL)
    p_ref = ref.R.T @ (oMf.translation - BASE_P)
    np.testing.assert_allclose(p_ee.ravel(), p_ref, rtol=0, atol=TOL * scale(p_ref))


def joint_rates(robot: RobotModel, kind: str) -> Array:
    """Seeded joint rates within the limits, or every joint exactly at +/− its velocity limit (rad/s)."""
    if kind == "seeded":
        return np.random.default_rng(20).uniform(-1.0, 1.0, robot.n_joints) * robot.qd_max
    return np.where(np.arange(robot.n_joints) % 2 == 0, 1.0, -1.0) * robot.qd_max


@pytest.mark.parametrize("rates", ["seeded", "at_limits"])
@pytest.mark.parametrize("model_name", ["chaser", "with_payload"])
@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_zero_momentum_base_twist_matches_pinocchio(robot, ff_models, model_name, name, rates):
    """FreeFloatingModel.base_twist(q, q̇, 0) equals −A_g,b⁻¹ A_g,m q̇ from pinocchio's ccrba (the free-flyer's
    local twist), and pinocchio's centroidal momentum of the resulting motion is zero."""
    ff = ff_models[model_name]
    q, qd = configurations(robot)[name], joint_rates(robot, rates)
    ref = PinReference(ff.robot, q)
    nu_ref = -np.linalg.solve(ref.A_g[:, :6], ref.A_g[:, 6:] @ qd)
    nu = np.asarray(ff.base_twist(q, qd, np.zeros(6))).ravel()
    np.testing.assert_allclose(nu, nu_ref, rtol=0, atol=TOL * largest(nu_ref))
    h = pin.computeCentroidalMomentum(ref.model, ref.data, ref.x, np.concatenate([nu, qd])).vector
    assert largest(h) <= TOL * largest(ref.A_g[:, 6:] @ qd)  # the arm alone: the scale to cancel


# ----------------------------------------------------------------------------------------------------
# verify's pinocchio kinematics


@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_pin_kinematics_poses_match_pinocchio_joint_placements(robot, name):
    """PinKinematics' body and ee poses equal pinocchio's joint placements oMi (× the URDF frame placement)."""
    q = configurations(robot)[name]
    ref = PinReference(robot, q)
    kin = PinKinematics(robot)
    kin.forward(np.concatenate([BASE_P, BASE_QUAT]), q)
    poses = kin.body_poses()
    assert list(poses) == list(robot.body_names)
    for jid, body in enumerate(robot.body_names, start=1):  # joint 1 is the free flyer carrying the base
        M = ref.data.oMi[jid].homogeneous
        np.testing.assert_allclose(poses[body], M, rtol=0, atol=TOL * scale(M),
                                   err_msg=f"{name} {body}")
    frame = ref.model.frames[ref.ee_id]
    ee_ref = (ref.data.oMi[frame.parentJoint] * frame.placement).homogeneous
    np.testing.assert_allclose(kin.ee_pose(), ee_ref, rtol=0, atol=TOL * scale(ee_ref))


@pytest.mark.parametrize("model_name", ["chaser", "with_payload"])
@pytest.mark.parametrize("name", CONFIG_NAMES)
def test_pin_kinematics_momentum_matches_pinocchio(robot, ff_models, model_name, name):
    """PinKinematics.momentum from world base rates equals pinocchio's computeCentroidalMomentum of the local
    twist (checked against getFrameVelocity of the base), its arm part ccrba's A_g,m q̇, and the zero-momentum
    base twist of FreeFloatingModel gives zero momentum."""
    ff = ff_models[model_name]
    q, qd = configurations(robot)[name], joint_rates(robot, "at_limits")
    ref = PinReference(ff.robot, q)
    kin = PinKinematics(ff.robot)
    x_base = np.concatenate([BASE_P, BASE_QUAT])
    rng = np.random.default_rng(21)
    v_w, w_w = rng.uniform(-0.05, 0.05, 3), rng.uniform(-0.02, 0.02, 3)
    nu_local = np.concatenate([ref.R.T @ v_w, ref.R.T @ w_w, qd])
    pin.forwardKinematics(ref.model, ref.data, ref.x, nu_local)
    base_id = ref.model.getFrameId(ff.robot.body_names[0], pin.BODY)
    base_vel = pin.getFrameVelocity(ref.model, ref.data, base_id, pin.LOCAL_WORLD_ALIGNED)
    np.testing.assert_allclose(np.concatenate([base_vel.linear, base_vel.angular]), np.concatenate([v_w, w_w]),
                               rtol=0, atol=TOL)  # nu_local is the twist the world rates describe
    h_ref = pin.computeCentroidalMomentum(ref.model, ref.data, ref.x, nu_local).vector.copy()
    h, h_arm = kin.momentum(x_base, q, v_w, w_w, qd)
    tol = TOL * largest(ref.A_g[:, 6:] @ qd)
    np.testing.assert_allclose(h, h_ref, rtol=0, atol=TOL * largest(h_ref))
    np.testing.assert_allclose(h_arm, ref.A_g[:, 6:] @ qd, rtol=0, atol=tol)
    nu = np.asarray(ff.base_twist(q, qd, np.zeros(6))).ravel()  # base frame = pinocchio's local twist
    h0, _ = kin.momentum(x_base, q, ref.R @ nu[:3], ref.R @ nu[3:], qd)
    assert np.abs(h0).max() <= tol


# ----------------------------------------------------------------------------------------------------
# The joint box: exactly at a bound passes, 2e-6 beyond fails


def _samples(q_row: Array, qd_row: Array) -> tuple[Array, Array, Array, Array]:
    """``(t, q, qd, phase_index)`` of five samples, one per phase at least, all at ``q_row``, ``qd_row``."""
    return 0.01 * np.arange(5), np.tile(q_row, (5, 1)), np.tile(qd_row, (5, 1)), np.array([0, 0, 1, 1, 2])


@pytest.mark.parametrize("side", ["lower", "upper"])
def test_joint_checks_pass_with_every_joint_exactly_at_its_bound(robot, side):
    """joint_checks: every joint exactly on its position bound and every rate exactly ±qd_max pass, margin 0."""
    q = robot.q_min if side == "lower" else robot.q_max
    qd = np.where(np.arange(robot.n_joints) % 2 == 0, 1.0, -1.0) * robot.qd_max
    checks = joint_checks(robot, *_samples(q, qd))
    for name in ("joint_position", "joint_velocity"):
        assert checks[name].passed and checks[name].margin == 0.0, checks[name]
    assert f"{side} bound" in checks["joint_position"].where


@pytest.mark.parametrize("side", ["lower", "upper"])
@pytest.mark.parametrize("joint", range(7))
def test_joint_checks_fail_2e6_beyond_any_bound(robot, joint, side):
    """joint_checks: one joint 2e-6 rad past its bound (or 2e-6 rad/s past qd_max) fails and is named; half the
    tolerance past it passes (the solver-activity slack FEASIBILITY_TOL)."""
    sign = -1.0 if side == "lower" else 1.0
    q = robot.q_min.copy() if side == "lower" else robot.q_max.copy()
    qd = sign * robot.qd_max.copy()
    for excess, ok in ((BEYOND, False), (0.5 * FEASIBILITY_TOL, True)):
        q_out, qd_out = q.copy(), qd.copy()
        q_out[joint] += sign * excess
        qd_out[joint] += sign * excess
        checks = joint_checks(robot, *_samples(q_out, qd_out))
        for name in ("joint_position", "joint_velocity"):
            c = checks[name]
            assert c.passed is ok and c.margin == pytest.approx(-excess, rel=1e-6, abs=1e-15), (name, c)
            assert c.where.startswith(f"{robot.joints[joint].name} "), c.where
        assert f"{side} bound" in checks["joint_position"].where


# ----------------------------------------------------------------------------------------------------
# ... and the same through verify, on whole synthetic plans


@pytest.fixture(scope="module")
def builder() -> Builder:
    return Builder()


def held(path, joint: int, value: float):
    """``path`` with one joint (index from 0) held at ``value`` (rad), at rest."""

    def f(t: float) -> tuple[Array, Array]:
        q, qd = (a.copy() for a in path(t))
        q[joint], qd[joint] = value, 0.0
        return q, qd

    return f


def placed_for(builder: Builder, path) -> Builder:
    """A copy of ``builder`` whose static target's grasp frame is the ee frame of ``path`` at t_grasp."""
    out = copy.copy(builder)
    k = builder.k_grasp
    x = builder.base(path)
    sc = builder.scenario
    kin = PinKinematics(sc.robot)
    kin.forward(x[k], path(builder.t[k])[0])
    T_world_body = kin.ee_pose() @ builder.T_ee_target
    out.scenario = replace(sc, target=replace(sc.target, p_world_com=T_world_body[:3, 3].copy()))
    out.state = TargetState(matrix_to_quat(T_world_body[:3, :3]), np.zeros(3))
    return out


def failed(report: VerifyReport) -> set[str]:
    return {name for name, c in report.checks.items() if not c.passed}


def assert_only_joint_check_differs(at: VerifyReport, beyond: VerifyReport, name: str) -> None:
    """``name`` passes at the limit and fails beyond it; every other check has the same verdict in both."""
    assert at.checks[name].passed and at.checks[name].margin == 0.0, at.checks[name]
    assert not beyond.checks[name].passed and beyond.checks[name].margin == pytest.approx(-BEYOND, rel=1e-6)
    assert failed(beyond) == failed(at) | {name}, (failed(at), failed(beyond))
    assert any(v.startswith(name) for v in beyond.violations)


@pytest.mark.parametrize(("joint", "side"), [(0, "lower"), (4, "upper"), (6, "lower"), (6, "upper")])
def test_verify_passes_a_joint_exactly_at_its_bound_and_fails_2e6_beyond(builder, joint, side):
    """verify on a synthetic scenario II plan with one joint held exactly on its URDF bound for the whole plan
    (base integrated, target placed at the resulting grasp): joint_position passes with margin 0; the same plan
    with that joint's stored angle 2e-6 rad further out fails, and only that check changes verdict."""
    robot = builder.scenario.robot
    bound = robot.q_min[joint] if side == "lower" else robot.q_max[joint]
    path = held(baseline_path, joint, bound)
    plan = placed_for(builder, path).plan(path)
    assert np.all(plan.q[:, joint] == bound)
    at = verify(plan)
    q = plan.q.copy()
    q[:, joint] += BEYOND if side == "upper" else -BEYOND
    beyond = verify(replace(plan, q=q))
    assert_only_joint_check_differs(at, beyond, "joint_position")
    assert at.checks["joint_position"].value == bound and f"{robot.joints[joint].name} {side}" in \
        beyond.checks["joint_position"].where


def rate_at_limit_plan(builder: Builder, joint: int, sign: float) -> tuple[GraspPlan, int]:
    """A plan whose ``joint`` (held at its grasp angle otherwise) makes an A sin²(π u) excursion over the approach
    with peak rate exactly ``sign`` · qd_max at the stored sample u = 1/4; returns the plan and that sample."""
    robot = builder.scenario.robot
    q_grasp = baseline_path(builder.t[builder.k_grasp])[0][joint]
    amplitude = sign * robot.qd_max[joint] * T_APP / np.pi

    def path(t: float) -> tuple[Array, Array]:
        q, qd = held(baseline_path, joint, q_grasp)(t)
        u = (t - T0) / T_APP
        if 0.0 <= u <= 1.0:
            q[joint] += amplitude * np.sin(np.pi * u) ** 2
            qd[joint] += amplitude * np.pi / T_APP * np.sin(2 * np.pi * u)
        return q, qd

    plan = placed_for(builder, path).plan(path)
    k = int(np.argmin(np.abs(plan.t - (T0 + T_APP / 4))))
    assert plan.qd[k, joint] == pytest.approx(sign * robot.qd_max[joint], rel=1e-14)
    plan.qd[k, joint] = sign * robot.qd_max[joint]  # exactly, not to the last ulp of sin(π/2) · π / T
    assert np.abs(plan.qd[:, joint]).max() == robot.qd_max[joint]
    return plan, k


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_verify_passes_a_rate_exactly_at_its_limit_and_fails_2e6_beyond(builder, sign):
    """verify on a synthetic plan whose joint7 rate reaches exactly ±qd_max (consistent q, base integrated):
    joint_velocity passes with margin 0; the stored rate 2e-6 rad/s further out fails, nothing else changes."""
    joint = 6
    plan, k = rate_at_limit_plan(builder, joint, sign)
    at = verify(plan)
    qd = plan.qd.copy()
    qd[k, joint] += sign * BEYOND
    beyond = verify(replace(plan, qd=qd))
    assert_only_joint_check_differs(at, beyond, "joint_velocity")
    assert beyond.checks["joint_velocity"].t_s == pytest.approx(plan.t[k])
    assert beyond.checks["joint_velocity"].where.startswith("joint7 ")


def test_sampled_poses_equal_forward_kinematics_row_by_row(robot):
    """PinKinematics.sampled_poses (every configuration in one call, bodies at chosen rows) gives exactly the poses
    of forward + ee_pose + body_poses at each row, at every degenerate configuration."""
    qs = np.array(list(configurations(robot).values()))
    rng = np.random.default_rng(4)
    quats = rng.normal(size=(len(qs), 4))
    x_base = np.hstack([rng.uniform(-1, 1, (len(qs), 3)), quats / np.linalg.norm(quats, axis=1, keepdims=True)])
    rows = np.arange(0, len(qs), 2)
    kin = PinKinematics(robot)
    T_ee, T_bodies = kin.sampled_poses(x_base, qs, rows)
    assert list(T_bodies) == list(robot.body_names)
    for k in range(len(qs)):
        kin.forward(x_base[k], qs[k])
        np.testing.assert_array_equal(T_ee[k], kin.ee_pose())
        if k in rows:
            r = int(np.flatnonzero(rows == k)[0])
            for name, T in kin.body_poses().items():
                np.testing.assert_array_equal(T_bodies[name][r], T)
