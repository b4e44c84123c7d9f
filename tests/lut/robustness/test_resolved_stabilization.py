"""``lutgen robustness --resolve-stabilization``: the stabilization NLP solved warm at each run's grasp changes the
run's stabilization only, gives the plan's own verdict at zero error, and flies the planned spline when it fails."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lut.output.plan_replay import replay_inputs
from tests.support.cli import (
    ROOT,
    lutgen_in_process,
    replay_plan_for_current_model,
    write_replay_plan_for_current_model,
)

SIGMA_ATT_DEG, SIGMA_RATE_DEG_S = 0.5, 0.05  # the error (1-σ)
DRAW_SEED = 1  # a draw at which scenario II's planned spline exceeds the grasp torque (its first failing check)


@pytest.fixture(scope="module")
def planner_and_inputs():
    from planner.config.scenario import load_scenario
    from planner.plan import Planner

    inputs = replay_inputs(replay_plan_for_current_model(), "plan")
    return Planner(load_scenario(ROOT / inputs.scenario_file)), inputs


@pytest.fixture(scope="module")
def planned_run(planner_and_inputs):
    """The drawn state and the plan as planned flown against it (its stabilization spline as it is)."""
    planner, inputs = planner_and_inputs
    state = drawn_state(inputs, DRAW_SEED)
    return state, planner.simulate(state, inputs.parameters)


def drawn_state(inputs, seed: int):
    from lut.robustness.error_model import ErrorModel, perturbed_states, standard_draws

    model = ErrorModel.from_sigmas(np.radians(SIGMA_ATT_DEG), np.radians(SIGMA_RATE_DEG_S))
    return perturbed_states(inputs.state, model, standard_draws(1, seed), 1.0)[0]


def assert_same_approach_and_tracking(a, b) -> None:
    """Bit-identical samples before the grasp (phase 0 approach, 1 tracking) and the same grasp state."""
    assert np.array_equal(a.t, b.t) and np.array_equal(a.phase_index, b.phase_index)
    before = a.phase_index < 2
    for name in ("q", "qd", "x_base"):
        assert np.array_equal(getattr(a, name)[before], getattr(b, name)[before]), name
    assert np.array_equal(a.grasp.q, b.grasp.q) and np.array_equal(a.grasp.qd, b.grasp.qd)


def test_the_re_solve_changes_the_stabilization_only(planner_and_inputs, planned_run):
    from planner.plan_grasps import STABILIZATION_BUDGET
    from planner.verify.verifier import verify

    planner, inputs = planner_and_inputs
    state, planned = planned_run
    resolved = planner.simulate(state, inputs.parameters, STABILIZATION_BUDGET)
    assert_same_approach_and_tracking(planned, resolved)
    assert np.array_equal(planned.stabilization.params, inputs.parameters.stabilization_params)
    assert resolved.stabilization.success and resolved.stabilization.iterations > 0
    assert not np.allclose(resolved.stabilization.params, planned.stabilization.params)
    before, after = verify(planned), verify(resolved)
    # the planned spline brakes too hard from this grasp state; the re-solve's torque constraint brings it in
    assert before.checks["grasp_torque"].margin < 0 <= after.checks["grasp_torque"].margin


def test_a_failed_re_solve_flies_the_planned_spline(planner_and_inputs, planned_run):
    from planner.nlp.outcome import SolveOutcome
    from planner.verify.verifier import verify

    planner, inputs = planner_and_inputs
    state, planned = planned_run
    failed = planner.simulate(state, inputs.parameters, 0)  # no iteration allowed: the budget ends the solve at once
    assert not failed.stabilization.success
    assert failed.stabilization.status == SolveOutcome.ITERATION_BUDGET_EXHAUSTED
    assert np.array_equal(failed.stabilization.params, inputs.parameters.stabilization_params)
    assert np.array_equal(failed.q, planned.q) and np.array_equal(failed.qd, planned.qd)
    assert "planned spline is flown" in failed.notes[-1]
    assert not verify(failed).feasible  # the planned spline's verdict at this draw (its grasp torque)


def test_the_report_says_which_stabilization_was_flown_and_zero_error_is_the_plans_verdict(tmp_path):
    plan = write_replay_plan_for_current_model(tmp_path / "plan.json")
    common = ("robustness", plan, "--samples", "1", "--scales", "1", "--no-progress")  # zero error: the plan itself
    for extra, mode, words in (((), "as_planned", "stabilization as planned"),
                               (("--resolve-stabilization",), "resolved_warm", "re-solved warm")):
        out = tmp_path / f"{mode}.json"
        res = lutgen_in_process(*common, *extra, "--json", out)
        assert res.returncode == 0 and words in res.stdout, res.stdout + res.stderr
        doc = json.loads(out.read_text())
        # zero error: as planned and re-solved, the plan's own verdict (feasible)
        assert doc["stabilization"]["mode"] == mode and doc["success"]["probability"] == 1.0
    assert doc["stabilization"]["max_iterations"] > 0 and doc["stabilization"]["resolved_runs"] == 1
