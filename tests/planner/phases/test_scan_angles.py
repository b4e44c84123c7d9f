"""The scan's grasps held at angles about a free grasp axis (planner.phases.approach_guess): where they hold the
handle, and how the scan's guesses are spread over meeting times and angles."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.config.scenario import load_scenario
from planner.nlp.bspline import UniformCubicBSpline
from planner.phases import approach_guess
from planner.phases.approach_guess import (
    ANGLE_SEPARATION_RAD,
    MIN_SEPARATION_S,
    _Candidate,
    _diverse,
    angles_apart,
    reach_scan,
)

SCENARIOS = Path(__file__).resolve().parents[3] / "configs" / "scenarios"


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(SCENARIOS / "scenario_II.toml")


def _spline(sc) -> UniformCubicBSpline:
    return UniformCubicBSpline(sc.approach.n_vertices, sc.phases.approach_s)


def _angle_about_x(R_world_grasp: np.ndarray, R_world_ee: np.ndarray) -> float:
    """The turn about the grasp frame's x axis taking it onto the ee frame [rad] (the boom's free axis is x)."""
    M = R_world_grasp.T @ R_world_ee
    return float(np.arctan2(M[2, 1] - M[1, 2], M[1, 1] + M[2, 2]))


def _wrapped(a: float) -> float:
    return (a + np.pi) % (2 * np.pi) - np.pi


def test_held_guesses_hold_the_boom_at_their_angle_by_pinocchio(scenario_II):
    """Each guess of scenario II's default state says at which angle about the boom it holds the grasp frame.
    Oracle: pinocchio's placement of the grasp frame at the guess's pre-grasp joints and base offset, against the
    target's grasp frame at the meeting time, the angle read by a formula of the test's own. The base drifts a little
    during the approach (the guess's joints are corrected for it), hence the 0.05 rad."""
    import pinocchio as pin

    from planner.model.robot import pin_configuration

    sc = scenario_II
    state = sc.target_state.as_state()
    scan = reach_scan(sc, _spline(sc), state, 5)
    assert len(scan.guesses) > 5  # the scan's own five, then the held angles'
    robot = sc.robot
    model, data = robot.pin_model, robot.pin_model.createData()
    fid = model.getFrameId(robot.ee_frame)
    motion = sc.target.motion(state, 200.0)
    angles = []
    for g in scan.guesses:
        base = np.array([g.base_offset_m[0], 0.0, g.base_offset_m[1]])
        pin.framesForwardKinematics(model, data, pin_configuration(base, np.array([1.0, 0, 0, 0]), g.q_pregrasp))
        R_g = motion.grasp_pose(g.start_delay_s + sc.phases.approach_s)[0][0]
        R_ee = data.oMf[fid].rotation
        assert abs(_wrapped(_angle_about_x(R_g, R_ee) - g.free_axis_angle_rad)) < 0.05
        angles.append(g.free_axis_angle_rad)
    # the held scans are there: the guesses hold the boom in three or more of the four quarter turns
    bins = {round(_wrapped(a) / (np.pi / 2)) % 4 for a in angles}
    assert len(bins) >= 3


def test_first_guess_is_the_scans_own(scenario_II, monkeypatch):
    """The held angles add guesses after the first: a plan's first grasp is the one the IK's own angle gives (the
    scan without held angles as the oracle), so states planned well before are planned the same way first."""
    sc = scenario_II
    state = sc.target_state.as_state()
    with_angles = reach_scan(sc, _spline(sc), state, 5)
    held = approach_guess.FREE_AXIS_ANGLES_DEG
    monkeypatch.setattr(approach_guess, "FREE_AXIS_ANGLES_DEG", ())
    without = reach_scan(sc, _spline(sc), state, 5)
    np.testing.assert_array_equal(with_angles.guesses[0].params, without.guesses[0].params)
    assert with_angles.guesses[0].start_delay_s == without.guesses[0].start_delay_s
    assert with_angles.outcomes == without.outcomes  # the reach verdict is the scan's own
    # a scan asked for no held angles (a query's reach check, a start from another base offset) is that same scan
    monkeypatch.setattr(approach_guess, "FREE_AXIS_ANGLES_DEG", held)
    unheld = reach_scan(sc, _spline(sc), state, 5, held_angles=False)
    assert unheld.outcomes == without.outcomes
    assert len(unheld.guesses) == len(without.guesses) < len(with_angles.guesses)
    for a, b in zip(unheld.guesses, without.guesses, strict=True):
        np.testing.assert_array_equal(a.params, b.params)


def _candidate(score: float, t_s: float, psi_deg: float | None) -> _Candidate:
    return _Candidate(score, 0.1, [], t_s, None if psi_deg is None else np.radians(psi_deg), None)


def test_guesses_are_the_scans_own_then_one_per_held_angle_all_apart():
    """Degenerate cases on purpose: one meeting time at 355° and 10° (15° apart across the wrap: one grasp), angles
    21° and 19° apart (two grasps, one), meeting times exactly 6 s apart (two), a fixed grasp axis (meeting times
    alone, as before the held angles)."""
    assert abs(ANGLE_SEPARATION_RAD - np.radians(20.0)) < 1e-15
    own = [_candidate(1.0, 20.0, 10.0), _candidate(0.9, 22.0, 12.0), _candidate(0.8, 40.0, 15.0)]
    held_a = [_candidate(0.7, 20.0, 50.0)]
    held_b = [_candidate(0.6, 20.0, 31.0)]  # 21° from the first, but 19° from held_a's
    held_c = [_candidate(0.5, 20.0, 355.0), _candidate(0.4, 60.0, 355.0)]  # 15° from the first across the wrap
    chosen = _diverse(own, [held_c, held_b, held_a], 5)
    got = [(c.start_delay_s, round(np.degrees(c.free_axis_angle_rad)) % 360) for c in chosen]
    # the scan's own distinct ones, then each held angle's best distinct one, the angle with the best candidate first
    assert got == [(20.0, 10), (40.0, 15), (20.0, 50), (60.0, 355)]
    for i, a in enumerate(chosen):
        for b in chosen[:i]:
            assert abs(a.start_delay_s - b.start_delay_s) >= MIN_SEPARATION_S or angles_apart(
                a.free_axis_angle_rad, b.free_axis_angle_rad)
    assert [(c.start_delay_s, round(np.degrees(c.free_axis_angle_rad))) for c in _diverse(own, [held_b], 5)] == \
        [(20.0, 10), (40.0, 15), (20.0, 31)]
    assert [c.start_delay_s for c in _diverse(own, [held_a], 1)] == [20.0, 20.0]  # ``count`` bounds the scan's own
    fixed = [_candidate(1.0, 20.0, None), _candidate(0.9, 25.0, None), _candidate(0.8, 26.0, None),
             _candidate(0.7, 14.0, None)]
    assert [c.start_delay_s for c in _diverse(fixed, [], 5)] == [20.0, 26.0, 14.0]
    assert [c.start_delay_s for c in _diverse(fixed, [], 2)] == [20.0, 26.0]


def test_angles_apart_across_the_wrap_and_at_the_separation():
    """The angle between two grasps is taken the short way round; an unknown angle is never apart."""
    deg = np.radians
    assert not angles_apart(deg(355.0), deg(10.0))  # 15° across 0
    assert angles_apart(deg(300.0), deg(10.0))  # 70° across 0
    assert not angles_apart(deg(-175.0), deg(170.0))  # 15° across ±180°
    assert angles_apart(deg(-160.0), deg(150.0))  # 50° across ±180°
    assert angles_apart(0.0, ANGLE_SEPARATION_RAD + 1e-12) and not angles_apart(0.0, ANGLE_SEPARATION_RAD - 1e-12)
    assert not angles_apart(None, 1.0) and not angles_apart(1.0, None)
