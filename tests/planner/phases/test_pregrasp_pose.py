"""The pre-grasp pose with a free grasp axis (planner.phases.pregrasp_pose, the approach NLP's Eq. 20-21 rows): backed
off along the grasp frame turned to the angle the gripper holds it at, the line the tracking closes along."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from planner.config.scenario import load_scenario
from planner.model.rotation import axis_angle_to_matrix
from planner.phases.approach_constraints import pregrasp_error
from planner.phases.approach_ik import REACH_TOLERANCE, PoseIK
from planner.phases.pregrasp_pose import at_own_angle, free_axis_turn, pregrasp_position
from tests.support.scan_context import scan_context

SCENARIOS = Path(__file__).resolve().parents[3] / "configs" / "scenarios"


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(SCENARIOS / "scenario_II.toml")


def _rows(sc):
    """The NLP's pre-grasp rows as a numeric function of (R_ee, p_ee, R_target)."""
    R_ee, p_ee, R_t = ca.MX.sym("R_ee", 3, 3), ca.MX.sym("p_ee", 3), ca.MX.sym("R_t", 3, 3)
    pos, rot, R_free = pregrasp_error(sc, R_ee, p_ee, R_t, ca.DM(sc.target.p_world_com))
    return ca.Function("rows", [R_ee, p_ee, R_t], [pos, rot, R_free])


def _grasp_frame(sc, R_target):
    T = sc.target.grasp.T_body_grasp
    return R_target @ T[:3, :3], sc.target.p_world_com + R_target @ T[:3, 3]


@pytest.mark.parametrize("psi_deg", [0.0, 37.0, 90.0, -120.0, 180.0])
def test_pregrasp_rows_vanish_on_the_turned_frames_backoff_line(scenario_II, psi_deg):
    """A gripper holding the boom at ψ and backed off along the grasp frame turned by ψ meets the rows exactly (ψ = 180°
    on purpose: the turn's sine is 0 there); backed off along the configured frame's z instead it misses the row by
    2·b·sin(ψ/2), the tracking's sideways jump the rows used to ask for (closed form)."""
    sc = scenario_II
    rows = _rows(sc)
    R_t = axis_angle_to_matrix(np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8]), 1.1)
    R_g, p_g = _grasp_frame(sc, R_t)
    R_G = R_g @ axis_angle_to_matrix(sc.target.grasp.free_axis, np.radians(psi_deg))
    b = sc.approach.pregrasp_backoff_m
    pos, rot, R_free = (np.asarray(v) for v in rows(R_G, p_g - b * R_G[:, 2], R_t))
    np.testing.assert_allclose(pos.ravel(), 0.0, atol=1e-12)
    np.testing.assert_allclose(rot.ravel(), 0.0, atol=1e-12)
    np.testing.assert_allclose(R_g @ R_free, R_G, atol=1e-12)
    np.testing.assert_allclose(R_g @ free_axis_turn(sc, R_g, R_G), R_G, atol=1e-12)  # the scan's and drift's turn
    pos_configured = np.asarray(rows(R_G, p_g - b * R_g[:, 2], R_t)[0]).ravel()
    assert np.linalg.norm(pos_configured) == pytest.approx(2 * b * abs(np.sin(np.radians(psi_deg) / 2)), abs=1e-12)


def test_pregrasp_at_the_ik_s_own_angle_by_pinocchio(scenario_II):
    """The scan's IK matches the boom's axis only and picks the angle about it; solved again at that angle, the grasp
    frame sits on the pre-grasp backed off along the frame turned by it, the whole orientation matched (pinocchio's
    placement, the angle read by the test's own formula). Scenario II's default state, the approach starting 32 s after
    the observation, where the IK holds the boom ~80° from the configured angle."""
    import pinocchio as pin

    from planner.model.robot import fk_function, pin_configuration

    sc = scenario_II
    motion = sc.target.motion(sc.target_state.as_state(), 60.0)
    ik, fk = PoseIK.shared(sc), fk_function(sc.robot)
    free = sc.target.grasp.free_axis
    R_g, p_g = (a[0] for a in motion.grasp_pose(32.0 + sc.phases.approach_s))
    home = np.concatenate([sc.q_initial, sc.base_offset_guess_m])
    x_free = ik.solve(pregrasp_position(sc, R_g, p_g), R_g, np.column_stack([free, np.zeros((3, 2))]), [home])
    assert x_free is not None
    x = at_own_angle(sc, ik, R_g, p_g, x_free, np.asarray(fk(x_free[:7])[-2]))
    model, data = sc.robot.pin_model, sc.robot.pin_model.createData()
    pin.framesForwardKinematics(model, data, pin_configuration(np.array([x[7], 0.0, x[8]]),
                                                               np.array([1.0, 0.0, 0.0, 0.0]), x[:7]))
    placement = data.oMf[model.getFrameId(sc.robot.ee_frame)]
    M = R_g.T @ placement.rotation
    psi = np.arctan2(M[2, 1] - M[1, 2], M[1, 1] + M[2, 2])  # about the grasp frame's x, the boom's axis
    assert abs(psi) > np.radians(60.0)  # a case where the configured back-off was wrong by decimetres
    R_G = R_g @ axis_angle_to_matrix(free, psi)
    np.testing.assert_allclose(placement.rotation, R_G, atol=2 * REACH_TOLERANCE)
    expected = p_g - sc.approach.pregrasp_backoff_m * R_G[:, 2]
    assert np.linalg.norm(placement.translation - expected) < REACH_TOLERANCE


def test_the_scan_starts_from_the_turned_pregrasp_and_falls_back_to_the_iks(scenario_II, monkeypatch):
    """A meeting time's pre-grasp is solved again at the IK's own angle and its tracking poses taken from there; where
    they fail from it, they are taken from the IK's first answer, so the reach verdict is never narrower than that
    answer's (the scan's out-of-reach verdict answers a plan at once)."""
    from planner.phases import approach_guess
    from planner.phases.approach_guess import MeetingOutcome, _poses_at

    sc = scenario_II
    free_only = np.column_stack([sc.target.grasp.free_axis, np.zeros((3, 2))])
    ctx = approach_guess.replace(scan_context(sc, sc.target_state.as_state()), S_pre=free_only)
    tried = []

    def from_first_only(ctx_, tau, R_g, x_pre):
        tried.append(x_pre)
        return (MeetingOutcome.IK_UNSOLVED if len(tried) == 1 else MeetingOutcome.REACHED), [x_pre]

    monkeypatch.setattr(approach_guess, "_tracking_poses_from", from_first_only)
    outcome, configs = _poses_at(ctx, 32.0, ctx.x_home)
    assert outcome is MeetingOutcome.REACHED and len(tried) == 2
    assert not np.allclose(tried[0], tried[1])  # the turned pre-grasp first (ψ ≈ 80° here), then the IK's own
    assert configs[0] is tried[1]


def test_without_a_free_axis_the_turn_is_none_and_the_pregrasp_is_the_iks():
    """Scenario I's grasp is fixed: no turn, whatever the end-effector holds, and the IK's pre-grasp is kept as is."""
    sc = load_scenario(SCENARIOS / "scenario_I.toml")
    R_ee = axis_angle_to_matrix(np.array([0.0, 0.6, 0.8]), 2.0)
    assert sc.target.grasp.free_axis is None
    np.testing.assert_array_equal(free_axis_turn(sc, np.eye(3), R_ee), np.eye(3))
    x_pre = np.arange(9.0)
    assert at_own_angle(sc, None, np.eye(3), np.zeros(3), x_pre, R_ee) is x_pre
