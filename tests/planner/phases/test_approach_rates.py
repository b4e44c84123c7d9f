"""The approach NLP's joint-rate rows (paper Eq. 18): with a cost on the arm's motion (Eq. 14-15) they hold the
spline's rates at every RK4 node, where the via points alone let such an approach peak above the limit between them;
without, a peak between via points is found on the dense samples and held by lowered via-point bounds in a re-solve.
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
from planner.phases.approach import ApproachProblem, ApproachSolution
from planner.phases.approach_bounds import AS_SOLVED
from planner.phases.approach_rates import RATE_TRIGGER, lowered_rates, rate_peaks
from planner.phases.approach_solve import decision_vector, solve_approach
from planner.plan_parameters import ApproachParameters
from planner.plan_samples import PhaseSamples, approach_samples

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


def _samples(problem: ApproachProblem, app: ApproachParameters) -> PhaseSamples:
    return approach_samples(problem.scenario, problem.spline, problem.ff, ApproachSolution.given(app))


def test_the_dense_check_finds_the_peak_between_via_points_and_the_re_solve_holds_it(problems):
    """The feasibility problem (rows at its via points only) at the stored approach: the dense check names joint 7 at
    the 1.029× the positions' finite differences give, between two via points; the bounds it asks for lower that
    joint's rows at those two via points by the peak's excess over the NLP's 0.97 and leave every other row as the NLP
    has it; the warm re-solve with them, at the state the approach was made for, keeps every rate within its limit at
    every sample (where the first approach broke it)."""
    plain = problems["scenario_II"]
    app = _peaked_approach()
    samples = _samples(plain, app)
    peaks = rate_peaks(plain, samples)
    worst = peaks[0]
    assert worst.joint == 6 and worst.ratio == pytest.approx(1.029, abs=2e-3)
    via_gap_s = np.min(np.abs(plain.rate_times_s - worst.t_s))
    assert via_gap_s > 0.1  # between two via points 0.5 s apart, not on one
    bounds, same = lowered_rates(plain, samples, AS_SOLVED)
    assert same == peaks
    lower, upper = bounds.rates(plain)
    own_lower, own_upper = AS_SOLVED.rates(plain)
    assert np.all(lower <= 0.0) and np.all(upper >= 0.0)
    row = np.searchsorted(plain.rate_times_s, worst.t_s)
    for r in (row - 1, row):
        rate = np.interp(plain.rate_times_s[r], samples.t, samples.qd[:, 6])
        excess = abs(worst.rate_rad_s) - 0.97 * plain.robot.qd_max[6]
        tightened = upper if worst.rate_rad_s > 0 else -lower
        assert tightened[7 * r + 6] == pytest.approx(max(abs(rate) - excess, 0.0), abs=1e-9)
    touched = set()
    for p in peaks:  # the rows of the two via points around each peak (one before the first via point)
        after = int(np.searchsorted(plain.rate_times_s, p.t_s))
        touched |= {7 * r + p.joint for r in (after - 1, after) if r >= 0}
    untouched = np.setdiff1d(np.arange(len(lower)), sorted(touched))
    np.testing.assert_array_equal(lower[untouched], own_lower[untouched])
    np.testing.assert_array_equal(upper[untouched], own_upper[untouched])
    state = load_scenario(ROOT / "configs" / "scenarios" / "scenario_II_safety.toml").target_state.as_state()
    held = solve_approach(plain, state, app, max_starts=0, tightened=bounds)
    assert held.success
    assert rate_peaks(plain, _samples(plain, held.parameters), above=1.0) == []


def _bumped(problem: ApproachProblem, joint: int, peak_rad_s: float, centre_s: float) -> PhaseSamples:
    """Samples every 0.01 s at rest but for one joint's parabolic rate bump of half-width 0.2 s peaking at
    ``peak_rad_s`` at ``centre_s`` (the positions play no part)."""
    t = np.arange(0.0, problem.scenario.phases.approach_s + 1e-9, 0.01)
    qd = np.zeros((len(t), 7))
    qd[:, joint] = peak_rad_s * np.clip(1.0 - ((t - centre_s) / 0.2) ** 2, 0.0, None)
    return PhaseSamples(t, np.zeros_like(qd), qd, np.zeros((len(t), 7)))


def test_a_peak_counts_from_its_trigger_and_is_lowered_on_its_own_side(problems):
    """At the edges on purpose: a peak of exactly 0.999 of the limit is not one, 1e-9 above it is; a negative peak
    raises the lower bounds (to at most 0: a row's rate may fall to rest, not be pushed across); a peak before the
    first via point has one row around it; ``why_unheld``'s threshold, the limit itself, is a separate one."""
    plain = problems["scenario_II"]
    lim = plain.robot.qd_max[3]
    between = 0.5 * (plain.rate_times_s[4] + plain.rate_times_s[5])
    assert rate_peaks(plain, _bumped(plain, 3, RATE_TRIGGER * lim, between)) == []
    over = rate_peaks(plain, _bumped(plain, 3, RATE_TRIGGER * lim * (1 + 1e-9), between))
    assert [(p.joint, p.t_s) for p in over] == [(3, pytest.approx(between))]
    assert rate_peaks(plain, _bumped(plain, 3, lim, between), above=1.0) == []
    samples = _bumped(plain, 3, -1.05 * lim, between)
    bounds, _ = lowered_rates(plain, samples, AS_SOLVED)
    lower, upper = (b.reshape(-1, 7) for b in bounds.rates(plain))
    own_lower, own_upper = (b.reshape(-1, 7) for b in AS_SOLVED.rates(plain))
    np.testing.assert_array_equal(upper, own_upper)
    excess = 1.05 * lim - 0.97 * lim
    for r in (4, 5):
        rate = np.interp(plain.rate_times_s[r], samples.t, samples.qd[:, 3])
        assert lower[r, 3] == pytest.approx(min(rate + excess, 0.0))
    assert np.count_nonzero(lower != own_lower) == 2
    early, _ = lowered_rates(plain, _bumped(plain, 3, 1.05 * lim, 0.5 * plain.rate_times_s[0]), AS_SOLVED)
    assert np.count_nonzero(early.rates(plain)[1] != AS_SOLVED.rates(plain)[1]) == 1
