"""``lutgen query --robust``: the plain answer is always among the judged candidates, the chosen plan is at
least as robust as the plain query's (checked independently by ``lutgen robustness`` on both exported plans),
and bad values are one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.support.cli import ROOT, assert_one_line_error, lutgen_in_process, write_golden_for_current_model

SIGMAS = "0.05,0.005"  # 1-σ attitude (deg) and rate (deg/s): a tenth of the issue's
EDGE = [4.0, 90.0, 3.0]  # between two grid nodes of one rate: the plain answer (interpolated) and both nodes' plans
EDGE_SCALE = 0.035  # of the issue's σ's (0.0175°, 0.00175 °/s): where the candidates part (0, 1, 2 of 2 draws)


@pytest.fixture(scope="module")
def golden(tmp_path_factory):
    path = tmp_path_factory.mktemp("robust") / "golden.h5"
    write_golden_for_current_model(path)
    return path


def state_args(golden, coords) -> tuple[str, ...]:
    from lut.query.table_query import TableQuery

    state = TableQuery(golden).grid.state_at(coords)
    return ("--attitude", ",".join(f"{v:.12f}" for v in state.attitude_wxyz),
            "--omega-deg-s", ",".join(f"{v:.12f}" for v in np.degrees(state.omega_body_rad_s)))


def test_robust_query_with_no_time_left_answers_the_plain_plan_unjudged(golden, tmp_path):
    """A judgement that no longer fits the budget is not started: the plain answer, said not judged (before, it was
    judged anyway and the query overran its budget by the judgement)."""
    args = state_args(golden, [3.5, 90.0, 0.0])  # a grid node: its own plan, feasible
    plain = lutgen_in_process("query", golden, *args, "--budget-s", "1", "--out", tmp_path / "plain.json")
    robust = lutgen_in_process("query", golden, *args, "--budget-s", "1", "--robust", SIGMAS, "--robust-samples", "1",
                               "--out", tmp_path / "robust.json")
    assert plain.returncode == robust.returncode == 0, robust.stderr
    assert "→ plain interpolated" in robust.stdout and "not judged: the budget left no time" in robust.stdout, \
        robust.stdout
    a, b = (json.loads((tmp_path / f"{n}.json").read_text())["parameters"] for n in ("plain", "robust"))
    assert a == b


def test_the_choice_is_the_most_robust_candidate_by_an_independent_count(golden):
    from lut.query.robust_choice import RobustRequest, robust_query
    from lut.query.table_query import TableQuery
    from lut.robustness.error_model import ErrorModel
    from planner.verify.verifier import verify
    from tests.lut.robustness.test_robustness_command import (
        SIGMA_ATT_DEG,
        SIGMA_RATE_DEG_S,
        independent_true_states,
    )

    tq = TableQuery(golden)
    state = tq.grid.state_at(EDGE)
    model = ErrorModel.from_sigmas(np.radians(SIGMA_ATT_DEG * EDGE_SCALE), np.radians(SIGMA_RATE_DEG_S * EDGE_SCALE))
    choice = robust_query(tq, state, RobustRequest(model, samples=2, seed=0, jobs=1), budget_s=600.0, refine=False)
    judged = [c for c in choice.candidates if c.estimate is not None]
    assert [c.label for c in judged] == ["plain interpolated", "corner 2", "corner 3"], candidate_text(choice)
    target = {"target": {"attitude_wxyz": state.attitude_wxyz, "omega_body_rad_s": state.omega_body_rad_s}}
    draws = independent_true_states(target, 2, 0, EDGE_SCALE)
    # each judged plan flown against the same draws and verified one by one, outside robust_choice
    truth = {c.label: sum(verify(tq.planner.simulate(s, c.plan.parameters)).feasible for s in draws) for c in judged}
    assert len(set(truth.values())) > 1, truth  # the candidates differ: a worse choice would show
    assert truth[choice.chosen.label] == max(truth.values()), (choice.chosen.label, truth)
    assert all(c.estimate.successes == truth[c.label] for c in judged), candidate_text(choice)


def candidate_text(choice) -> str:
    from lut.query.robust_choice import candidate_lines

    return "\n".join(candidate_lines(choice))


@pytest.mark.slow
def test_robust_plan_is_at_least_as_robust_as_the_plain_one(golden, tmp_path):
    args = state_args(golden, EDGE)  # between two nodes: interpolated, its two corners and a refine as candidates
    sigmas = f"{0.5 * EDGE_SCALE:g},{0.05 * EDGE_SCALE:g}"  # where the candidates part (test above)
    plain = lutgen_in_process("query", golden, *args, "--budget-s", "120", "--out", tmp_path / "plain.json")
    robust = lutgen_in_process("query", golden, *args, "--budget-s", "120", "--robust", sigmas, "--robust-samples",
                               "2", "--seed", "0", "-j", "2", "--out", tmp_path / "robust.json")
    assert plain.returncode in (0, 2) and robust.returncode in (0, 2), robust.stderr
    assert "corner" in robust.stdout, robust.stdout
    success = {}
    for name in ("plain", "robust"):
        out = tmp_path / f"{name}.rob.json"
        att, rate = sigmas.split(",")
        res = lutgen_in_process("robustness", tmp_path / f"{name}.json", "--attitude-sigma-deg", att,
                                "--rate-sigma-deg-s", rate, "--samples", "2", "--scales", "1", "--seed", "0",
                                "-j", "2", "--json", out, "--no-progress", "--scenario",
                                ROOT / "configs" / "scenarios" / "scenario_II.toml")
        assert res.returncode == 0, res.stderr
        success[name] = json.loads(out.read_text())["success"]["probability"]
    assert success["robust"] >= success["plain"], success


@pytest.mark.parametrize("args, words", [
    (("--robust", "0.5"), "--robust"),
    (("--robust", "-0.5,0.05"), "--robust"),
    (("--robust", "0.5,nan"), "--robust"),
    (("--robust", "0.5,0.05", "--robust-samples", "0"), "--robust-samples"),
])
def test_bad_robust_values_are_one_line(golden, args, words):
    assert_one_line_error(lutgen_in_process("query", golden, "--attitude", "1,0,0,0", "--omega-deg-s", "0,0,3.75",
                                            *args), words)
