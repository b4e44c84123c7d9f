"""The tracking IK's dense clearance check (issue 20: a scenario II tumble's link 2 swept 12.5 cm into the panel while
the tracking blended onto the grasp frame, where no NLP row looks).

Its distances against verify's own engine on a stored plan's tracking (clear: no dip); its rule on distances built by
hand: a dip below the margin, a pair exactly at it (touching is allowed), and the gripper–handle pair held to the
margin less the closed back-off, just above and just below that bound."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from planner.collision.contact_rule import TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import scene_layout
from planner.phases.tracking_clearance import tracking_dip
from tests.support.stored_plan import stored_phase, verify_engine_distances

T_START_S = 30.0  # the hand-built trackings start here [s since the observation]


def test_a_stored_feasible_plans_tracking_keeps_its_clearance_as_verifys_engine_measures_it(clearance):
    sc = clearance.problem.scenario
    phase = stored_phase(sc, "tracking")
    assert tracking_dip(clearance, phase, phase.motion) is None
    # the same rule on verify's engine and pinocchio's kinematics: the plan's tracking is clear there too, and the
    # two engines agree on every distance
    pairs = clearance.problem.scene.pairs
    theirs = verify_engine_distances(sc, phase, pairs)
    assert np.max(np.abs(clearance.distances_at(phase.t, phase.q, phase.x_base, phase.motion) - theirs)) < 1e-6
    handle = scene_layout(sc.robot, sc.target).gripper_handle
    required = np.array([required_clearance_m(pairs, handle, sc.limits.collision_margin_m, TRACKING,
                                              closed_backoff_m(sc.approach.pregrasp_backoff_m, t - phase.start_s,
                                                               sc.phases.tracking_s)) for t in phase.t])
    assert (theirs >= required).all()


def _dip(clearance, monkeypatch, pair: int, t_into_s: float, distance_m: float):
    """``tracking_dip`` on distances of 1 m everywhere but ``pair``, at ``distance_m`` ``t_into_s`` into a 5 s tracking
    sampled every 0.01 s."""
    t = T_START_S + np.linspace(0.0, 5.0, 501)
    d = np.ones((t.size, clearance.n_pairs))
    d[np.argmin(np.abs(t - T_START_S - t_into_s)), pair] = distance_m
    monkeypatch.setattr(clearance, "distances_at", lambda *args: d)
    return tracking_dip(clearance, SimpleNamespace(t=t, q=None, x_base=None), None)


def _handle_pair(clearance) -> int:
    sc = clearance.problem.scenario
    return list(clearance.problem.scene.pairs).index(scene_layout(sc.robot, sc.target).gripper_handle)


def test_a_link_into_the_target_is_a_dip_named_with_its_pair_depth_and_time(clearance, monkeypatch):
    pair = 3 if _handle_pair(clearance) != 3 else 4
    dip = _dip(clearance, monkeypatch, pair, 1.82, -0.125)
    a, b = clearance.problem.scene.pairs[pair]
    assert dip.pair == f"{a}-{b}" and dip.distance_m == -0.125 and dip.t_s == pytest.approx(1.82)
    assert dip.clearance_m == clearance.problem.scenario.limits.collision_margin_m


def test_at_the_margin_exactly_is_clear_and_a_nanometre_below_is_not(clearance, monkeypatch):
    pair = 3 if _handle_pair(clearance) != 3 else 4
    margin = clearance.problem.scenario.limits.collision_margin_m
    assert _dip(clearance, monkeypatch, pair, 2.0, margin) is None
    assert _dip(clearance, monkeypatch, pair, 2.0, margin - 1e-9) is not None


def test_the_gripper_may_close_on_the_handle_by_the_closed_back_off_and_no_further(clearance, monkeypatch):
    sc = clearance.problem.scenario
    k = _handle_pair(clearance)
    for t_into in (0.0, 2.0, 3.5, 5.0):
        bound = sc.limits.collision_margin_m - closed_backoff_m(sc.approach.pregrasp_backoff_m, t_into,
                                                                sc.phases.tracking_s)
        assert _dip(clearance, monkeypatch, k, t_into, bound + 1e-9) is None
        below = _dip(clearance, monkeypatch, k, t_into, bound - 1e-6)
        assert below is not None and below.clearance_m == pytest.approx(bound, abs=1e-12)
    # at the grasp the gripper sits on the handle: the bound there is the margin less the whole back-off
    assert _dip(clearance, monkeypatch, k, 5.0, sc.limits.collision_margin_m - sc.approach.pregrasp_backoff_m) is None
