"""A scan that reaches no meeting time from near the base-offset guess scans again with the IK started from the rest of
the box (``planner.phases.approach_guess``): "out of reach" must not be the verdict of one side of the box."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import planner.phases.approach_guess as approach_guess
from planner.config.scenario import load_scenario
from planner.model.target_state import TargetState
from planner.phases.approach import approach_spline
from planner.phases.approach_guess import BASE_STARTS_PER_AXIS, reach_scan
from planner.phases.approach_ik import REGULARISATION, PoseIK, pack_ik_parameters
from planner.phases.approach_start import base_offset_grid, starts_elsewhere_in_box

SCENARIO_I = Path(__file__).resolve().parents[3] / "configs" / "scenarios" / "scenario_I.toml"
# the coverage section's scenario I flat spin 8 (--seed 7): answered out of reach when the IK started only near the
# guess (0, 0) m; planned feasible in 4.3 s once it starts from the rest of the box too
FROM_ELSEWHERE = TargetState(np.array([0.29205183528970935, -0.1264312496464797, 0.6439764945274885,
                                       0.6957119656243017]), np.radians([0.0, 1.9757552067758226, 0.0]))


@pytest.fixture(scope="module")
def scenario_I():
    sc = load_scenario(SCENARIO_I)
    return sc, approach_spline(sc)


def test_a_state_reached_only_away_from_the_guess_is_not_out_of_reach(scenario_I, monkeypatch):
    sc, spline = scenario_I
    scan = reach_scan(sc, spline, FROM_ELSEWHERE)
    assert scan.reachable
    # every start the scan hands the NLP has its base far from the guess, which the IK's starts near it never reached
    assert all(np.linalg.norm(g.base_offset_m - sc.base_offset_guess_m) > 0.5 for g in scan.guesses)
    monkeypatch.setattr(approach_guess, "starts_elsewhere_in_box", lambda *args: [])
    assert not reach_scan(sc, spline, FROM_ELSEWHERE).reachable


def test_a_state_reached_near_the_guess_is_scanned_once(scenario_I, monkeypatch):
    """The second pass runs only where the first reached nothing: a reachable state's scan is what it was."""
    sc, spline = scenario_I

    def never(*args):
        raise AssertionError("the rest of the box was scanned for a state reached near the guess")

    monkeypatch.setattr(approach_guess, "starts_elsewhere_in_box", never)
    assert reach_scan(sc, spline, sc.target_state.as_state()).reachable


def test_the_other_starts_are_the_guess_starts_moved_to_every_other_grid_point(scenario_I):
    sc, _ = scenario_I
    home = np.concatenate([sc.q_initial, sc.base_offset_guess_m])
    extra = [np.concatenate([np.full(7, 0.1 * k), sc.base_offset_guess_m]) for k in range(2)]
    groups = starts_elsewhere_in_box(sc, [home, *extra], BASE_STARTS_PER_AXIS)
    grid = base_offset_grid(sc, BASE_STARTS_PER_AXIS)
    assert len(grid) == BASE_STARTS_PER_AXIS ** 2 and len(groups) == len(grid) - 1  # the guess (0, 0) is in the grid
    moved = [group[0][-2:] for group in groups]
    assert all(not np.allclose(b, sc.base_offset_guess_m) for b in moved)
    for group, b in zip(groups, moved, strict=True):
        for start, original in zip(group, [home, *extra], strict=True):
            np.testing.assert_array_equal(start[:-2], original[:-2])
            np.testing.assert_array_equal(start[-2:], b)


def test_the_ik_regularisation_pulls_the_base_toward_its_anchor(scenario_I):
    """The residual's last two rows are weight · (base − anchor), whatever the anchor; the pose rows do not see it."""
    sc, _ = scenario_I
    ik = PoseIK(sc)
    x = np.concatenate([sc.q_initial + 0.1, [0.7, -0.4]])
    rows = []
    for anchor in (sc.base_offset_guess_m, np.array([1.0, 0.0])):
        args = (np.zeros(3), np.eye(3), np.eye(3), REGULARISATION, np.zeros(3), np.eye(3), np.zeros(2), 0.0, anchor)
        r = np.asarray(ik.fn(x, *args)[0]).ravel()
        np.testing.assert_allclose(r[-2:], REGULARISATION * (x[-2:] - anchor), rtol=0, atol=1e-15)
        rows.append(r)
        assert ik.lm(x, pack_ik_parameters(*args))[0].shape[0] == x.size
    np.testing.assert_array_equal(rows[0][:-2], rows[1][:-2])
