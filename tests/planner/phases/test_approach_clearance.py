"""The approach's dense clearance check (issue 20: collisions between the approach's via points).

Its distances are held pair by pair to verify's own engine and pinocchio's kinematics on a stored plan; its
bookkeeping (which via points' rows are raised, by how much) on distances built by hand: a dip between two via
points, before the first, one just above the clearance, several in one pair; and a whole plan that dipped between
its via points (a seeded flat spin of the coverage run) comes out feasible (slow)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from planner.config.scenario import load_scenario
from planner.model.target import TargetState
from planner.phases.approach_clearance import DIP_TRIGGER_M, ApproachClearance
from planner.plan_samples import PhaseSamples
from tests.support.stored_plan import stored_phase, verify_engine_distances

ROOT = Path(__file__).resolve().parents[3]


def test_distances_equal_verify_engine_pair_by_pair(clearance):
    sc = clearance.problem.scenario
    phase = stored_phase(sc, "approach")
    samples = PhaseSamples(phase.t - phase.start_s, phase.q, phase.qd, phase.x_base)
    ours = clearance.distances(samples, phase.start_s, phase.motion)
    theirs = verify_engine_distances(sc, phase, clearance.problem.scene.pairs)
    assert ours.shape == (phase.t.size, 37)
    assert np.max(np.abs(ours - theirs)) < 1e-6


def _dipped(clearance: ApproachClearance, monkeypatch, pair: int, t_dip: float, d_dip: float):
    """``raised_bounds`` on distances of 1 m everywhere but ``pair`` at 0.05 m, dipping to ``d_dip`` at ``t_dip``."""
    t = np.linspace(0.0, clearance.via_times_s[-1], 1001)
    d = np.ones((t.size, clearance.n_pairs))
    d[:, pair] = 0.05
    d[np.argmin(np.abs(t - t_dip)), pair] = d_dip
    monkeypatch.setattr(clearance, "distances", lambda samples, delay, motion: d)
    samples = PhaseSamples(t, np.zeros((t.size, 7)), np.zeros((t.size, 7)), np.zeros((t.size, 7)))
    raised, dips = clearance.raised_bounds(SimpleNamespace(start_delay_s=30.0), samples, None)
    return raised.reshape(clearance.n_points, clearance.n_pairs), dips


def test_a_dip_between_two_via_points_raises_both_by_its_depth(clearance, monkeypatch):
    via = clearance.via_times_s
    raised, dips = _dipped(clearance, monkeypatch, pair=5, t_dip=0.5 * (via[3] + via[4]), d_dip=0.0)
    assert np.flatnonzero(raised.ravel()).tolist() == [3 * clearance.n_pairs + 5, 4 * clearance.n_pairs + 5]
    assert raised[3, 5] == pytest.approx(0.05) and raised[4, 5] == pytest.approx(0.05)
    assert len(dips) == 1 and dips[0].distance_m == 0.0 and dips[0].clearance_m == pytest.approx(0.02)
    assert dips[0].t_s == pytest.approx(0.5 * (via[3] + via[4]), abs=0.01)


def test_a_dip_before_the_first_via_point_raises_only_that_one(clearance, monkeypatch):
    raised, _ = _dipped(clearance, monkeypatch, pair=0, t_dip=0.5 * clearance.via_times_s[0], d_dip=0.01)
    assert np.flatnonzero(raised.ravel()).tolist() == [0] and raised[0, 0] == pytest.approx(0.04)


def test_a_dip_at_a_via_point_belongs_to_the_segment_it_ends(clearance, monkeypatch):
    via = clearance.via_times_s
    raised, _ = _dipped(clearance, monkeypatch, pair=2, t_dip=via[6], d_dip=0.0)
    assert set(np.flatnonzero(raised[:, 2])) == {5, 6}


def test_just_above_the_clearance_still_counts_and_a_clear_path_raises_nothing(clearance, monkeypatch):
    via = clearance.via_times_s
    near = clearance.clearance_m[7] + 0.5 * DIP_TRIGGER_M
    raised, dips = _dipped(clearance, monkeypatch, pair=7, t_dip=0.5 * (via[9] + via[10]), d_dip=near)
    assert len(dips) == 1 and raised[9, 7] == pytest.approx(0.05 - near)
    raised, dips = _dipped(clearance, monkeypatch, pair=7, t_dip=0.5 * (via[9] + via[10]), d_dip=0.045)
    assert dips == [] and not raised.any()
    # exactly at the trigger is not a dip (strict), a nanometre below it is
    at = clearance.clearance_m[7] + DIP_TRIGGER_M
    assert _dipped(clearance, monkeypatch, pair=7, t_dip=0.5 * (via[9] + via[10]), d_dip=at)[1] == []
    assert len(_dipped(clearance, monkeypatch, pair=7, t_dip=0.5 * (via[9] + via[10]), d_dip=at - 1e-9)[1]) == 1


def test_the_tracking_nodes_rows_are_never_raised(clearance, monkeypatch):
    raised, _ = _dipped(clearance, monkeypatch, pair=3, t_dip=clearance.via_times_s[-1], d_dip=-0.1)
    assert clearance.n_points == clearance.problem.k + 3 and not raised[clearance.problem.k:].any()


@pytest.mark.slow
def test_a_plan_that_dipped_between_via_points_is_re_solved_feasible():
    from planner.plan import Planner
    from planner.verify.verifier import verify

    planner = Planner(load_scenario(ROOT / "configs" / "scenarios" / "scenario_I.toml"))
    # coverage seed 7, scenario I flat spin: base_link-link6 at 0.01999 m between two via points (verify refused it)
    state = TargetState(np.array([-0.0200234658412, -0.67893241023, 0.706823217513, -0.19761270794]),
                        np.radians([0.0, 1.2961112207, 0.0]))
    plan = planner.plan(state)
    assert any("between the approach's via points" in note for note in plan.notes)
    report = verify(plan)
    assert report.feasible, report.violations
