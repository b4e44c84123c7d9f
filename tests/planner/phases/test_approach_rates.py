"""The approach NLP's joint-rate rows (paper Eq. 18): with a cost on the arm's motion (Eq. 14-15) they hold the
spline's rates at every RK4 node, where the via points alone let such an approach peak above the limit between them.
Checked at a real such approach (scenario II's safety descent, 1.029× joint 7's limit), against the rates of its
re-simulated positions by finite differences."""

from __future__ import annotations

import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from planner.config.scenario import load_scenario
from planner.nlp.phase_spline import approach_vertices
from planner.phases.approach import ApproachProblem
from planner.phases.approach_solve import decision_vector
from planner.plan_parameters import ApproachParameters

ROOT = Path(__file__).resolve().parents[3]
PEAK = ROOT / "tests" / "data" / "approach_rate_peak_II_safety.json"


def _peaked_approach() -> ApproachParameters:
    doc = json.loads(PEAK.read_text())
    return ApproachParameters(np.asarray(doc["approach_params"]), np.asarray(doc["base_offset_m"]),
                              float(doc["start_delay_s"]), np.asarray(doc["q_tracking_rad"]))


def _rate_rows(problem: ApproachProblem, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joint-rate rows' values at ``w`` and their bounds ``(g, lbg, ubg)``; the target state plays no part."""
    g = ca.Function("g", [problem._nlp["x"], problem._nlp["p"]], [problem._nlp["g"]])
    x = np.concatenate([w, np.zeros(problem.n_extra)])
    p = problem.parameter_layout.pack({"attitude_wxyz": np.array([1.0, 0.0, 0.0, 0.0]),
                                       "omega_body_rad_s": np.zeros(3)})
    rows = problem.constraints.slice("joint_velocities")
    return np.asarray(g(x, p)).ravel()[rows], problem.lbg[rows], problem.ubg[rows]


@pytest.fixture(scope="module")
def problems() -> dict[str, ApproachProblem]:
    return {name: ApproachProblem(load_scenario(ROOT / "configs" / "scenarios" / f"{name}.toml"))
            for name in ("scenario_II", "scenario_II_energy", "scenario_II_safety")}


def test_via_points_alone_miss_the_peak_that_every_node_bounds(problems):
    """At the stored approach the feasibility problem's via-point rows all hold (the hole: the spline's rates, by
    finite differences of its positions, peak 2.9 % over joint 7's limit between them), while the costed problem's
    node rows see the peak past their bound."""
    app = _peaked_approach()
    plain, costed = problems["scenario_II"], problems["scenario_II_safety"]
    spline = plain.spline
    V = approach_vertices(spline, plain.scenario.q_initial, app.params)
    t = np.linspace(0.0, spline.duration_s, 20001)
    q = spline.evaluate(V, t)
    qd_fd = np.gradient(q, t, axis=0)  # the rates from the positions alone, not the spline's derivative
    qd_max = plain.robot.qd_max
    assert np.max(np.abs(qd_fd) / qd_max) == pytest.approx(1.029, abs=2e-3)
    for name in ("scenario_II", "scenario_II_energy"):  # Eq. 16 weighs θ_b(0) alone: the via points
        assert len(_rate_rows(problems[name], decision_vector(app))[0]) == 7 * plain.k
    g, lo, hi = _rate_rows(plain, decision_vector(app))
    assert len(g) == 7 * plain.k and np.all((g >= lo - 1e-6) & (g <= hi + 1e-6))  # IPOPT's tolerance on active rows
    g, lo, hi = _rate_rows(costed, decision_vector(app))
    assert len(g) == 7 * (costed.m_steps - 1)
    assert np.any(g > hi + 1e-3) and np.max(g / np.tile(qd_max, costed.m_steps - 1)) > 1.02


def test_the_node_rows_are_the_spline_rates_at_every_rk4_node(problems):
    """Each costed row is its joint's rate at node i·t_f¹/m (i = 1…m−1), as the positions' finite differences give
    it (to their O(h²) error), bounded at 0.97 of the URDF's limit; the rates at both ends are 0 by Eq. 6."""
    costed = problems["scenario_II_safety"]
    app = _peaked_approach()
    g, lo, hi = _rate_rows(costed, decision_vector(app))
    V = approach_vertices(costed.spline, costed.scenario.q_initial, app.params)
    t_nodes = costed.spline.duration_s * np.arange(1, costed.m_steps) / costed.m_steps
    h = 1e-5
    fd = (costed.spline.evaluate(V, t_nodes + h) - costed.spline.evaluate(V, t_nodes - h)) / (2 * h)
    np.testing.assert_allclose(g, fd.ravel(), atol=1e-7)
    np.testing.assert_allclose(hi, np.tile(0.97 * costed.robot.qd_max, costed.m_steps - 1))
    np.testing.assert_allclose(lo, -hi)
    ends = costed.spline.evaluate(V, np.array([0.0, costed.spline.duration_s]), 1)
    np.testing.assert_allclose(ends, 0.0, atol=1e-12)
