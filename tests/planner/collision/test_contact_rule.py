"""The handle-contact rule: the scene's bodies and pairs, the clearance per phase, and that the NLPs and verify
hold the gripper to it (the gripper was once never checked against the handle)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner.collision.contact_rule import APPROACH, STABILIZATION, TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import HANDLE_BODY, TARGET_BODY, scene_layout
from planner.collision.nlp_scene import build_scene
from planner.config.scenario import load_scenario
from planner.nlp import constraint_backoff
from planner.phases.approach import BLEND_CHECK_NODES, ApproachProblem
from planner.phases.tracking_profile import TRACKING_NODES
from planner.verify.collision import required_clearances
from planner.verify.verifier import verify
from tests.planner.verify.test_verify import T0, T_APP, Builder

CONFIGS = Path(__file__).resolve().parents[3] / "configs"


@pytest.fixture(scope="module", params=("scenario_I", "scenario_II"))
def scenario(request):
    return load_scenario(CONFIGS / "scenarios" / f"{request.param}.toml")


def test_layout_has_the_handle_as_a_body_on_the_target_frame(scenario) -> None:
    """37 pairs: 21 chaser pairs, every chaser body against the target and against the handle."""
    layout = scene_layout(scenario.robot, scenario.target)
    assert len(layout.pairs) == 37
    bodies = {b.name: b for b in layout.bodies}
    assert bodies[HANDLE_BODY].frame_name == TARGET_BODY
    assert {s.name for s in bodies[HANDLE_BODY].shapes} == set(scenario.target.handle_shapes)
    assert not {s.name for s in bodies[TARGET_BODY].shapes} & set(scenario.target.handle_shapes)
    gripper = scenario.robot.body_names[-1]
    assert layout.gripper_handle == (gripper, HANDLE_BODY)
    assert [p for p in layout.pairs if HANDLE_BODY in p] == [(b, HANDLE_BODY) for b in scenario.robot.body_names]
    assert build_scene(scenario, gripper_handle=True).pairs == layout.pairs
    assert build_scene(scenario).pairs == tuple(p for p in layout.pairs if p != layout.gripper_handle)


def test_target_without_handle_has_no_exempt_pair(scenario) -> None:
    target = replace(scenario.target, handle_shapes=frozenset())
    layout = scene_layout(scenario.robot, target)
    assert layout.gripper_handle is None and len(layout.pairs) == 29
    req = required_clearance_m(layout.pairs, None, 0.02, STABILIZATION)
    assert np.all(req == 0.02)


def test_required_clearance_per_phase() -> None:
    """Margin everywhere; the gripper–handle pair less the closed back-off in tracking, exempt after the grasp."""
    pairs = [("base", "link3"), ("link7", "handle"), ("link6", "handle"), ("link7", "target")]
    gh = ("link7", "handle")
    np.testing.assert_array_equal(required_clearance_m(pairs, gh, 0.02, APPROACH), [0.02] * 4)
    np.testing.assert_allclose(required_clearance_m(pairs, gh, 0.02, TRACKING, 0.05), [0.02, -0.03, 0.02, 0.02],
                               atol=1e-15)
    stab = required_clearance_m(pairs, gh, 0.02, STABILIZATION)
    assert stab[1] == -np.inf and np.all(stab[[0, 2, 3]] == 0.02)


def test_closed_backoff_goes_from_zero_to_all_of_it() -> None:
    assert closed_backoff_m(0.2, 0.0, 5.0) == 0.0
    assert closed_backoff_m(0.2, 5.0, 5.0) == pytest.approx(0.2, abs=1e-15)
    values = [closed_backoff_m(0.2, t, 5.0) for t in np.linspace(0.0, 5.0, 51)]
    assert np.all(np.diff(values) >= 0.0)


def test_verify_clearances_follow_the_rule_over_a_plan(scenario) -> None:
    """verify's (n, m) bounds: the gripper–handle column follows the rule; every other column is the margin."""
    layout = scene_layout(scenario.robot, scenario.target)
    phases = {"approach": (0.0, 10.0), "tracking": (10.0, 15.0), "stabilization": (15.0, 60.0)}
    t = np.array([5.0, 10.0, 12.0, 15.0, 15.0, 30.0])
    phase = np.array([APPROACH, TRACKING, TRACKING, TRACKING, STABILIZATION, STABILIZATION])
    margin, b0 = scenario.limits.collision_margin_m, scenario.approach.pregrasp_backoff_m
    req = required_clearances(layout, margin, t, phase, phases, b0)
    k = layout.pairs.index(layout.gripper_handle)
    expected = [margin, margin, margin - closed_backoff_m(b0, 2.0, 5.0), margin - b0, -np.inf, -np.inf]
    np.testing.assert_allclose(req[:, k], expected, atol=1e-15)
    assert np.all(np.delete(req, k, axis=1) == margin)


def test_verify_catches_the_gripper_passing_through_the_handle_in_the_approach() -> None:
    """The synthetic path of tests/planner/verify/test_verify.py reaches the grasp straight through scenario II's
    boom: with the boom kept as the handle, verify must name link7–handle during the approach (it was never checked)."""
    builder = Builder()
    full = load_scenario(CONFIGS / "scenarios" / "scenario_II.toml")
    target = replace(full.target, p_world_com=builder.scenario.target.p_world_com)
    with_handle = replace(builder.scenario, target=target)
    report = verify(replace(builder.plan(), scenario=with_handle))
    check = report.checks["collision"]
    assert not check.passed
    assert check.where.startswith("link7-handle") and "(approach)" in check.where
    assert T0 < check.t_s < T0 + T_APP
    assert verify(builder.plan()).checks["collision"].passed  # the same plan without the boom passes


def test_approach_nlp_bounds_the_gripper_handle_pair() -> None:
    """The approach NLP's distance bounds: the gripper–handle pair at the margin at every via point, the rule at
    the tracking nodes, plus the blend checks; all with the constraint back-off."""
    sc = load_scenario(CONFIGS / "scenarios" / "scenario_I.toml")
    problem = ApproachProblem(sc)
    layout = scene_layout(sc.robot, sc.target)
    n_d = len(problem.scene.pairs)
    k_gh = problem.scene.pairs.index(layout.gripper_handle)
    bounds = problem.lbg[problem.constraints.slice("collision")].reshape(-1, n_d)
    margin, b0, t2 = sc.limits.collision_margin_m, sc.approach.pregrasp_backoff_m, sc.phases.tracking_s
    back = constraint_backoff.COLLISION_M
    k = sc.approach.via_points
    np.testing.assert_allclose(bounds[:k, k_gh], margin + back)
    expected = [margin - closed_backoff_m(b0, f * t2, t2) + back for f in TRACKING_NODES]
    np.testing.assert_allclose(bounds[k:, k_gh], expected)
    assert np.all(np.delete(bounds, k_gh, axis=1) == margin + back)
    blend = problem.lbg[problem.constraints.slice("blend_clearance")]
    assert len(blend) == len(BLEND_CHECK_NODES)
    np.testing.assert_allclose(blend, [margin - closed_backoff_m(b0, f * t2, t2) + back for f in BLEND_CHECK_NODES])
