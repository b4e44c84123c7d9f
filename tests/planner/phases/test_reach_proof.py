"""The reach proof: the closed form of a still target, a certified bound (finer sampling never goes below it), the scan
asking no IK where it holds, and its premise on the stored plans (the chaser's centre of mass fixed from the approach's
start to the grasp, the wrist point within the radius)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from lut.output.plan_file import load_plan
from planner.config.scenario import load_scenario
from planner.model.robot import pin_configuration
from planner.model.target import TargetState
from planner.model.wrist_reach import centre_of_mass_m, wrist_reach
from planner.phases import reach_proof as proof_module
from planner.phases.approach import approach_spline
from planner.phases.approach_guess import reach_scan
from planner.phases.reach_proof import _least_offset, reach_proof, wrist_distance_over_window
from planner.verify.checks import GRASP_ORIENTATION_TOL_RAD, GRASP_POSITION_TOL_M

ROOT = Path(__file__).resolve().parents[3]
SCENARIOS = ROOT / "configs" / "scenarios"

# the coverage section's seeded envelope states (bench --seed 8 / 7): two the proof settles, one only the scan refuses
FLAT_SPIN_I_PROVEN = TargetState(np.array([-0.391021503161, 0.589794259301, 0.589153786431, -0.390054780378]),
                                 np.radians([0.0, 1.351291439362, 0.0]))
FLAT_SPIN_II_PROVEN = TargetState(np.array([0.098308741587, 0.856991118432, 0.473549649159, 0.177911056536]),
                                  np.radians([0.0, 0.0, 1.000877636607]))
TUMBLE_I_PROVEN = TargetState(np.array([0.449666640492, 0.730775139637, 0.490746571275, -0.151444413892]),
                              np.radians([1.549025839311, 3.142497959985, 1.042307681625]))
FLAT_SPIN_I_SCAN_ONLY = TargetState(np.array([-0.684751833543, -0.063121000483, 0.176394235902, -0.704283848528]),
                                    np.radians([0.0, 2.683520738779, 0.0]))
# the plan's base is integrated from zero momentum; its centre of mass moved 1.3e-10 m in the stored plans
COM_FIXED_TOL_M = 1e-8


@pytest.fixture(scope="module")
def scenarios():
    return {name: load_scenario(SCENARIOS / f"{name}.toml") for name in ("scenario_I", "scenario_II")}


def test_a_still_target_gives_the_closed_form_slack(scenarios):
    for name, sc in scenarios.items():
        for box in (((0.5, 0.5), (-0.25, -0.25)), ((-1.0, 1.0), (-1.0, 1.0))):  # a pinned base, then the box
            scenario = replace(sc, base_offset_bounds_m=box)
            body = scenario.target.body()
            T = body.T_body_grasp
            wrist = body.p_world_com + T[:3, 3] + T[:3, :3] @ np.array([0.0, 0.0, -0.5])
            if name == "scenario_II":  # the boom's grasp, free about its x axis, at any angle: the wrist on a circle
                turns = np.linspace(0, 2 * np.pi, proof_module.ANGLE_SAMPLES, endpoint=False)
                offsets = np.stack([np.zeros_like(turns), 0.5 * np.sin(turns), -0.5 * np.cos(turns)], axis=1)
                wrist = body.p_world_com + T[:3, 3] + offsets @ T[:3, :3].T
            c_in = centre_of_mass_m(scenario.robot, scenario.q_initial)
            lo, hi = np.array([box[0][0], 0.0, box[1][0]]), np.array([box[0][1], 0.0, box[1][1]])
            rel = np.atleast_2d(wrist) - c_in
            nearest = np.linalg.norm(rel - np.clip(rel, lo, hi), axis=1).min()
            proof = reach_proof(scenario, TargetState(np.array([1.0, 0, 0, 0]), np.zeros(3)))
            tolerance = GRASP_POSITION_TOL_M + 0.5 * GRASP_ORIENTATION_TOL_RAD
            free_angle = 0.0 if name == "scenario_I" else 0.5 * np.pi / proof_module.ANGLE_SAMPLES
            assert proof.margin_m == pytest.approx(tolerance + free_angle, abs=1e-15)  # a still target: no motion
            assert proof.slack_m == pytest.approx(nearest - wrist_reach(sc.robot).radius_m - proof.margin_m,
                                                  abs=1e-12)
            # the least station offset: the wrist point's in-plane distance less the disc its height leaves
            reach = wrist_reach(sc.robot).radius_m + proof.margin_m
            need = np.hypot(rel[:, 0], rel[:, 2]) - np.sqrt(reach ** 2 - rel[:, 1] ** 2)
            assert proof.least_offset_m == pytest.approx(max(0.0, need.min()), abs=1e-12)


@pytest.mark.parametrize("name, state", [("scenario_I", FLAT_SPIN_I_PROVEN), ("scenario_II", FLAT_SPIN_II_PROVEN),
                                         ("scenario_I", TUMBLE_I_PROVEN), ("scenario_I", FLAT_SPIN_I_SCAN_ONLY),
                                         ("scenario_I", None), ("scenario_II", None)])
def test_the_certified_slack_is_below_every_finer_sample(scenarios, monkeypatch, name, state):
    sc = scenarios[name]
    state = sc.target_state.as_state() if state is None else state
    proof = reach_proof(sc, state)
    monkeypatch.setattr(proof_module, "ANGLE_SAMPLES", 3600)
    _, fine = wrist_distance_over_window(sc, state, step_s=0.005)
    finest = float(fine.min() - proof.radius_m)
    assert proof.slack_m <= finest  # a bound: the true minimum lies below every sample, and above the bound
    assert proof.slack_m >= finest - 2 * proof.margin_m  # and not a vacuous one
    _, wrist_points = proof_module._wrist_from_station_com(sc, state, 0.005, None)
    least = _least_offset(wrist_points, proof.radius_m)  # the arm's own radius, 10x finer samples
    assert proof.least_offset_m <= least <= proof.least_offset_m + 2 * proof.margin_m


def test_the_proven_states_are_out_of_reach(scenarios):
    for name, state in (("scenario_I", FLAT_SPIN_I_PROVEN), ("scenario_II", FLAT_SPIN_II_PROVEN),
                        ("scenario_I", TUMBLE_I_PROVEN)):
        proof = reach_proof(scenarios[name], state)
        assert proof.proven and proof.slack_m > 0.05
        assert proof.reason().startswith("out of reach (proven): at every start delay within [0, 90] s")
        # every offset of norm ≤ 1 m lies in the ±1 m box, which the proof rules out: the least one lies beyond it
        assert 1.0 < proof.least_offset_m < np.inf
        assert f"at least {proof.least_offset_m:.2f} m from its station" in proof.reason()
    for sc in scenarios.values():  # the default states plan feasible: nothing proves them out of reach
        assert not reach_proof(sc, sc.target_state.as_state()).proven


def test_the_scan_asks_no_ik_where_the_proof_holds_and_says_which_verdict_it_gives(scenarios):
    sc = scenarios["scenario_I"]
    proven = reach_scan(sc, approach_spline(sc), FLAT_SPIN_I_PROVEN)
    assert not proven.reachable and proven.proven_out_of_reach and proven.outcomes == () and proven.guesses == []
    assert proven.reason() == proven.proof.reason()
    scan_only = reach_scan(sc, approach_spline(sc), FLAT_SPIN_I_SCAN_ONLY)
    assert not scan_only.reachable and not scan_only.proven_out_of_reach and len(scan_only.outcomes) == 46
    assert scan_only.reason().startswith("out of reach: no meeting time") and "not a proof" in scan_only.reason()


@pytest.mark.parametrize("plan, name", [("plan_I", "scenario_I"), ("plan_II", "scenario_II")])
def test_a_planned_grasp_meets_the_proofs_premise(scenarios, plan, name):
    sc = scenarios[name]
    doc = load_plan(ROOT / "tests" / "data" / f"{plan}.json.gz")
    s, t = doc["samples"], np.asarray(doc["samples"]["t"])
    model, data = sc.robot.pin_model, sc.robot.pin_model.createData()

    def at(time_s: float) -> np.ndarray:
        i = int(np.argmin(np.abs(t - time_s)))
        return pin_configuration(*(np.asarray(s[key][i]) for key in ("base_position", "base_wxyz", "q")))

    start, grasp = doc["phases"]["approach"][0], doc["phases"]["tracking"][1]
    com = np.array([pin.centerOfMass(model, data, at(x)).copy() for x in np.linspace(start, grasp, 40)])
    base_offset = at(start)[:3]  # θ_b(0), the base at rest at the approach's start, unturned
    np.testing.assert_allclose(com, np.broadcast_to(centre_of_mass_m(sc.robot, sc.q_initial) + base_offset,
                                                    com.shape), atol=COM_FIXED_TOL_M)
    pin.framesForwardKinematics(model, data, at(grasp))
    wrist = data.oMf[model.getFrameId(sc.robot.body_names[wrist_reach(sc.robot).body_index])].translation
    assert np.linalg.norm(wrist - com[-1]) <= wrist_reach(sc.robot).radius_m


def test_at_the_reach_radius_itself_the_proof_turns_a_millimetre_either_side(scenarios):
    """The touching case: the chaser pinned where a still target's wrist point lies exactly the radius plus the margin
    from its centre of mass: slack 0, not proven; waiting 1 mm farther away proves it, 1 mm nearer does not."""
    sc = scenarios["scenario_I"]
    body = sc.target.body()
    T = body.T_body_grasp
    rel = body.p_world_com + T[:3, 3] + T[:3, :3] @ np.array([0.0, 0.0, -0.5]) - centre_of_mass_m(sc.robot,
                                                                                                  sc.q_initial)
    still = TargetState(np.array([1.0, 0, 0, 0]), np.zeros(3))
    margin = reach_proof(sc, still).margin_m  # a still target: verify's tolerances alone, wherever the base
    reach = wrist_reach(sc.robot).radius_m + margin
    x_touching = rel[0] - np.sqrt(reach ** 2 - rel[1] ** 2)

    def pinned(x: float):
        return replace(sc, base_offset_bounds_m=((x, x), (rel[2], rel[2])))

    assert reach_proof(pinned(x_touching), still).slack_m == pytest.approx(0.0, abs=1e-12)
    farther, nearer = reach_proof(pinned(x_touching - 1e-3), still), reach_proof(pinned(x_touching + 1e-3), still)
    assert farther.proven and farther.slack_m == pytest.approx(1e-3, abs=1e-9)
    assert not nearer.proven and nearer.slack_m == pytest.approx(-1e-3, abs=1e-9)


@pytest.mark.parametrize("points, radius, least", [
    ([[3.0, 0.0, 4.0]], 5.0, 0.0),                    # on the sphere: touching, no offset needed
    ([[6.0, 0.0, 8.0]], 5.0, 5.0),                    # 10 m away in the plane: 5 m to come
    ([[6.0, 3.0, 8.0]], 5.0, 6.0),                    # 3 m out of the plane leaves a disc of radius 4
    ([[6.0, 5.0, 8.0]], 5.0, 10.0),                   # exactly the radius out of the plane: the disc is a point
    ([[6.0, 5.0 + 1e-9, 8.0]], 5.0, np.inf),          # beyond it: no offset in the plane brings it
    ([[0.0, 4.0, 0.0], [9.0, 0.0, 0.0]], 5.0, 0.0),   # the nearest sample decides
])
def test_the_least_offset_of_wrist_points_in_closed_form(points, radius, least):
    assert _least_offset([np.asarray(points)], radius) == pytest.approx(least, abs=1e-12)
    assert _least_offset([np.asarray(points)[::-1], np.asarray(points)], radius) == pytest.approx(least, abs=1e-12)
