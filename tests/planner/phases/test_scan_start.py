"""Where the chaser may wait (planner.phases.approach_start) and how the scan uses it (planner.phases.approach_guess):
θ_in at the base offset against the target at the approach's start, which the approach NLP cannot move but by the
base; a guess with a clear start ranks before any other."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lut.output.preview_geometry import chaser_body_poses
from planner.collision.layout import TARGET_BODY, scene_layout
from planner.config.scenario import load_scenario
from planner.model.target import TargetState
from planner.nlp.bspline import UniformCubicBSpline
from planner.phases import approach_guess
from planner.phases.approach_guess import _Candidate, _diverse, _drift_corrected, _scan, _scored
from planner.phases.approach_start import StartClearance
from planner.phases.tracking_profile import TRACKING_NODES
from planner.verify.collision import sweep_pairs
from tests.support.scan_context import scan_context

SCENARIOS = Path(__file__).resolve().parents[3] / "configs" / "scenarios"
# scenario II general tumble 3 of the coverage section (seed 7): its scan's best-scored meeting times start with the
# chaser's arm inside the target
TUMBLE = TargetState(np.array([-0.3394232665, -0.1586336632, -0.8999953385, -0.2227904795]),
                     np.radians([1.106234751, -1.470538432, -3.995410357]))
# general tumble 6 (seed 7): every scanned candidate starts clear, and the drift correction's IK moved two of them 0.34
# m into the target (−0.26 and −0.20 m at the approach's start)
TUMBLE_DRIFT = TargetState(np.array([-0.4713286957, -0.0485308051, -0.5818500420, 0.6610178138]),
                           np.radians([2.150373340, 3.591500592, -3.278571596]))


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(SCENARIOS / "scenario_II.toml")


def _verify_engine_start(sc, ctx, base_offset_m: np.ndarray, t_s: float) -> np.ndarray:
    """Every pair's distance [m] of θ_in at ``base_offset_m`` against the target at ``t_s``: pinocchio's poses on
    verify's engine, in the order of the scan's pairs."""
    base = np.array([[base_offset_m[0], 0.0, base_offset_m[1]]])
    chaser = chaser_body_poses(sc.robot, base, np.array([[1.0, 0.0, 0.0, 0.0]]), sc.q_initial[None])
    frames = {name: np.vstack([chaser[0, i], [0.0, 0.0, 0.0, 1.0]])[None] for i, name in enumerate(sc.robot.body_names)}
    R, p = ctx.motion.body_pose(t_s)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R[0], p[0]
    frames[TARGET_BODY] = T[None]
    layout = scene_layout(sc.robot, sc.target)
    order = [layout.pair_names().index(f"{a}-{b}") for a, b in ctx.scene.pairs]
    return sweep_pairs(layout, frames).distance_m[0, order]


@pytest.mark.parametrize("base_offset_m", [(0.0, 0.0), (1.0, 1.0), (0.5, 1.0), (-1.0, -1.0)])
@pytest.mark.parametrize("t_s", [0.0, 48.0, 90.0])
def test_start_distances_equal_verify_engine_by_pinocchio(scenario_II, base_offset_m, t_s):
    """The start's distances are θ_in at the base offset against the target at the approach's start, to 1e-6 m of
    verify's own engine on pinocchio's poses. The corner (1, 1) puts the arm 0.4 m inside the target at
    every time (the tumble's first scanned guesses waited near it); the middle of the box is clear at 0 and 48 s,
    and at 90 s the turning target reaches into it."""
    sc = scenario_II
    ctx = scan_context(sc, TUMBLE)
    b = np.array(base_offset_m)
    ours = ctx.start.distances(b[None], t_s)[0]
    ref = _verify_engine_start(sc, ctx, b, t_s)
    assert ours.shape == ref.shape
    np.testing.assert_allclose(ours, ref, atol=1e-6)
    if base_offset_m == (0.0, 0.0):
        assert bool(ours.min() > sc.limits.collision_margin_m) == (t_s < 90.0)
    if base_offset_m == (1.0, 1.0):
        assert ours.min() < -0.3


def _candidate(score: float, t_s: float, start_clear: bool, psi_deg: float | None = None) -> _Candidate:
    return _Candidate(score, 0.1, [], t_s, None if psi_deg is None else np.radians(psi_deg), None, start_clear)


def test_a_clear_start_ranks_before_any_score():
    """Every candidate whose start is clear comes before every one whose start is not, whatever the scores (also
    among the held angles, and between their pools); within each, the score decides."""
    own = [_candidate(5.0, 20.0, False), _candidate(-3.0, 40.0, True), _candidate(0.2, 60.0, True),
           _candidate(9.0, 80.0, False)]
    assert [c.start_delay_s for c in _diverse(own, [], 4)] == [60.0, 40.0, 80.0, 20.0]
    assert [c.start_delay_s for c in _diverse(own, [], 2)] == [60.0, 40.0]
    held_a = [_candidate(8.0, 10.0, False, 90.0), _candidate(-1.0, 30.0, True, 90.0)]
    held_b = [_candidate(0.5, 50.0, True, 180.0)]
    chosen = _diverse(own[:1], [held_a, held_b], 1)
    assert [(c.start_delay_s, c.start_clear) for c in chosen] == [(20.0, False), (50.0, True), (30.0, True)]


def test_start_clear_at_the_margin_exactly(scenario_II, monkeypatch):
    """A start whose closest pair sits exactly at the collision margin is clear, 1e-9 m below it is not; the scan's
    candidate says which."""
    sc = scenario_II
    ctx = scan_context(sc, TUMBLE)
    bound = sc.limits.collision_margin_m
    configs = [np.concatenate([sc.q_initial, [0.0, 0.0]])] * (1 + len(TRACKING_NODES))
    for start_m, clear in [(bound, True), (bound - 1e-9, False), (5.0, True), (-0.4, False)]:
        monkeypatch.setattr(StartClearance, "distances", lambda self, b, t, d=start_m: np.array([[0.3, d, 0.5]]))
        assert ctx.start.is_clear(np.zeros(2), 30.0) is clear
        assert _scored(ctx, 30.0, configs).start_clear is clear


def test_the_tumbles_first_guesses_start_clear(scenario_II):
    """At the tumble whose best-scored meeting times start inside the target, the guesses the NLP starts from first
    start clear (verify's engine at their base offsets and start delays); the scan still offers the others after
    them."""
    sc = scenario_II
    scan = _scan(sc, UniformCubicBSpline(sc.approach.n_vertices, sc.phases.approach_s), TUMBLE, 5, True)
    ctx = scan_context(sc, TUMBLE)
    starts = [_verify_engine_start(sc, ctx, g.base_offset_m, g.start_delay_s).min() for g in scan.guesses]
    assert min(starts[:3]) >= sc.limits.collision_margin_m
    assert min(starts) < 0.0


def test_every_clear_candidate_still_starts_clear_after_the_drift_correction(scenario_II):
    """At the tumble where the drift correction's IK moved two clear starts into the target, every guess starts clear
    by verify's engine at its own base offset and start delay: a correction into the target is not taken."""
    sc = scenario_II
    scan = _scan(sc, UniformCubicBSpline(sc.approach.n_vertices, sc.phases.approach_s), TUMBLE_DRIFT, 5, True)
    ctx = scan_context(sc, TUMBLE_DRIFT)
    starts = [_verify_engine_start(sc, ctx, g.base_offset_m, g.start_delay_s).min() for g in scan.guesses]
    assert len(starts) >= 5 and min(starts) >= sc.limits.collision_margin_m, starts


@pytest.mark.parametrize("start_clear, corrected_clear, taken", [(True, True, "corrected"), (True, False, "own"),
                                                                 (False, False, "corrected"),
                                                                 (False, True, "corrected")])
def test_a_correction_is_taken_unless_it_moves_a_clear_start_inside(scenario_II, monkeypatch, start_clear,
                                                                     corrected_clear, taken):
    """The drift-corrected configurations replace the scan's unless the scan's start was clear and the corrected one
    is not (judged at the corrected base offset, at the margin exactly: clear)."""
    sc = scenario_II
    ctx = scan_context(sc, TUMBLE)
    own = [np.concatenate([sc.q_initial, [0.1, 0.2]])] * (1 + len(TRACKING_NODES))
    corrected = [np.concatenate([sc.q_initial, [0.6, -0.4]])] * (1 + len(TRACKING_NODES))
    monkeypatch.setattr(approach_guess, "correct_for_base_drift", lambda *args: corrected)
    at_corrected = sc.limits.collision_margin_m if corrected_clear else sc.limits.collision_margin_m - 1e-9

    def distances(self, b, t):
        return np.array([[at_corrected if np.allclose(b, [[0.6, -0.4]]) else 1.0]])

    monkeypatch.setattr(StartClearance, "distances", distances)
    cand = _Candidate(0.5, 0.1, own, 30.0, None, ctx, start_clear)
    assert _drift_corrected(cand) is (own if taken == "own" else corrected)
