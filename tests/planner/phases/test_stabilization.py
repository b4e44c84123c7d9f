"""The stabilization NLP (phase 3) and its solve: the constraint Jacobian, and the cold solve by way of the coarse NLP.

The grasp state is scenario II's grasp taken from the bundled plan (tests/data/plan_II.json.gz): joint
state and base pose at the tracking end, grasp frame from the export, and the compound momentum formed
by the planner's own ``grasp_momentum_world``. The screen's test uses two scanned grasps (tests/data/grasps_II.json):
one of a flat spin the NLP cannot brake, and the default state's second, which it brakes.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from lut.output.plan_file import load_plan
from planner.config.scenario import load_scenario
from planner.model.compound import compound_robot
from planner.model.freefloating import FreeFloatingModel
from planner.model.rotation import quat_to_matrix
from planner.nlp.outcome import SolveOutcome
from planner.nlp.phase_spline import stabilization_vertices
from planner.phases import stabilization_solve
from planner.phases.between_via_points import (
    AS_SOLVED,
    CLEARANCE_PAD_M,
    TORQUE_MARGIN,
    BetweenViaPoints,
    ViaPointBounds,
    tightened,
    within_limits,
)
from planner.phases.stabilization import (
    GraspState,
    StabilizationProblem,
    StabilizationSolution,
    grasp_momentum_world,
    smooth_stop_params,
    stabilization_spline,
)
from planner.phases.stabilization_solve import solve_stabilization
from planner.plan_grasps import SCREEN_BUDGET, STABILIZATION_BUDGET

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(ROOT / "configs" / "scenarios" / "scenario_II.toml")


@pytest.fixture(scope="module")
def grasp(scenario_II) -> GraspState:
    doc = load_plan(ROOT / "tests" / "data" / "plan_II.json.gz")
    s = doc["samples"]
    i = int(np.argmin(np.abs(np.asarray(s["t"]) - doc["phases"]["stabilization"][0])))
    q, qd = np.asarray(s["q"][i]), np.asarray(s["qd"][i])
    x_base = np.concatenate([s["base_position"][i], s["base_wxyz"][i]])
    g = doc["target"]["grasp_in_body"]
    T_body_grasp = np.eye(4)
    T_body_grasp[:3, :3] = quat_to_matrix(np.asarray(g["wxyz"]))
    T_body_grasp[:3, 3] = g["position"]
    T_ee_target = np.linalg.inv(T_body_grasp)
    h_world = grasp_momentum_world(FreeFloatingModel(scenario_II.robot),
                                   FreeFloatingModel(compound_robot(scenario_II, T_ee_target)), q, qd, x_base)
    return GraspState(q, qd, np.zeros(7), x_base, h_world, T_ee_target)


def _without_dense_check(monkeypatch):
    """Stand-in solves return made-up parameters: the torque check between via points is left out of their flow."""
    monkeypatch.setattr(stabilization_solve, "_held_between_via_points", lambda problem, grasp, solved, *a: solved)


@pytest.fixture(scope="module")
def problem(scenario_II, grasp) -> StabilizationProblem:
    return StabilizationProblem(scenario_II)


def test_constraint_jacobian_matches_central_differences(problem, grasp):
    """The NLP's Jacobian (CasADi AD, the grasp wrench by its own Jacobian; see JACOBIAN_FIRST_PENALTY)
    equals finite differences of the constraints on the joint-box and grasp-wrench rows.

    Fourth-order central differences, step 1e-5 in the spline parameters: the wrench is strongly curved
    in them (second-order differences at this step are off by 1e-5 of an entry, their h² truncation),
    while the fourth-order truncation (~h⁴) and roundoff (~1e-16·|g|/h) both stay below 1e-9 relative.
    The distance rows are left to tests/planner/collision/test_collision_callback.py (FCL's witness points switch
    faces).
    """
    par = problem.parameters(grasp)
    P = problem.initial_params(grasp)
    g_fun = problem.solver.get_function("nlp_g")
    J = np.asarray(problem.solver.get_function("nlp_jac_g")(P, par)[1])
    g_rows = problem.constraints
    rows = np.r_[g_rows.slice("joint_positions"), g_rows.slice("joint_velocities"), g_rows.slice("grasp_torque"),
                 g_rows.slice("grasp_force")]
    assert g_rows.slice("grasp_force").stop == len(problem.lbg)  # every row but the distances
    step = 1e-5

    def g(x: np.ndarray) -> np.ndarray:
        return np.asarray(g_fun(x, par)).ravel()[rows]

    J_fd = np.empty((len(rows), len(P)))
    for j in range(len(P)):
        e = np.zeros(len(P))
        e[j] = step
        J_fd[:, j] = (-g(P + 2 * e) + 8 * g(P + e) - 8 * g(P - e) + g(P - 2 * e)) / (12 * step)
    scale = np.maximum(np.abs(J_fd).max(axis=1, keepdims=True), 1e-3)
    np.testing.assert_array_less(np.abs(J[rows] - J_fd) / scale, 1e-7)


def test_coarse_problem_is_the_same_nlp_on_fewer_via_points(problem, scenario_II):
    coarse = problem.coarse_problem()
    assert coarse is problem.coarse_problem()  # built once
    assert coarse.functions is problem.functions  # the robot's inner Functions are built and loaded once
    assert coarse.coarse_via_points == 0  # no coarse problem of its own
    assert coarse.n_params == problem.n_params
    assert scenario_II.stabilization.coarse_via_points < coarse.k < problem.k  # knots are always via points


def test_cold_solve_falls_back_to_the_full_nlp_when_the_warm_solve_fails(problem, grasp, monkeypatch):
    """Coarse → full (from the coarse answer) → full from the cold guess, when the second fails; the
    answer is the last solve's, with times and iterations summed over all three."""
    calls = []
    template = StabilizationSolution(np.zeros(problem.n_params), True, "", 0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def fake_solve(nlp, g, warm_params, max_iterations=None, deadline=None, stall=None):
        assert max_iterations is None  # no budget asked, none passed on
        calls.append((nlp is problem, None if warm_params is None else np.asarray(warm_params).copy()))
        n = len(calls)
        sol = replace(template, params=np.full(problem.n_params, float(n)), iterations=10 * n,
                      solve_time_s=float(n), success=n != 2, status=f"solve {n}")
        return sol

    monkeypatch.setattr(stabilization_solve, "solve_once", fake_solve)
    _without_dense_check(monkeypatch)
    sol = solve_stabilization(problem, grasp)
    assert [is_full for is_full, _ in calls] == [False, True, True]
    assert calls[0][1] is None and calls[2][1] is None
    np.testing.assert_array_equal(calls[1][1], np.full(problem.n_params, 1.0))  # started from the coarse answer
    assert sol.status == "solve 3" and sol.success
    assert sol.iterations == 60 and sol.solve_time_s == 6.0
    assert sol.build_time_s == problem.build_time_s + problem.coarse_problem().build_time_s


def test_an_iteration_budget_is_shared_by_the_coarse_and_full_solves(problem, grasp, monkeypatch):
    """The budget bounds the iterations of all solves together: each gets what the earlier ones left, and
    none starts once it is spent."""
    calls = []
    template = StabilizationSolution(np.zeros(problem.n_params), False, "", 0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def fake_solve(nlp, g, warm_params, max_iterations=None, deadline=None, stall=None):
        calls.append(max_iterations)
        return replace(template, iterations=min(70, max_iterations), status="Iteration_Budget_Exhausted"
                       if max_iterations <= 70 else "Infeasible_Problem_Detected")

    monkeypatch.setattr(stabilization_solve, "solve_once", fake_solve)
    _without_dense_check(monkeypatch)
    sol = solve_stabilization(problem, grasp, max_iterations=120)
    assert calls == [120, 50]  # coarse: 70 of 120; full from the coarse answer: the 50 left; then nothing
    assert sol.iterations == 120 and not sol.success and sol.status == "Iteration_Budget_Exhausted"


def test_warm_solve_skips_the_coarse_problem(problem, grasp, monkeypatch):
    calls = []

    def fake_solve(nlp, g, warm_params, max_iterations=None, deadline=None, stall=None):
        calls.append((nlp is problem, max_iterations))
        return "answer"

    monkeypatch.setattr(stabilization_solve, "solve_once", fake_solve)
    _without_dense_check(monkeypatch)
    assert solve_stabilization(problem, grasp, problem.initial_params(grasp), max_iterations=30) == "answer"
    assert calls == [(True, 30)]


def test_a_real_solve_stops_at_its_iteration_budget(problem, grasp):
    """The wiring to IPOPT: from the cold guess (far outside the torque limit, so not feasible within 3
    iterations) a budget of 3 ends the solve after exactly 3 iterations, unsuccessful, named as such."""
    sol = stabilization_solve.solve_once(problem, grasp, None, 3)
    assert sol.iterations == 3 and not sol.success and sol.status == "Iteration_Budget_Exhausted"


def test_a_screen_ends_a_cold_solve_whose_coarse_nlp_is_not_feasible_within_it(problem, grasp, monkeypatch):
    """With a screen the coarse NLP, then the full one from its answer, get the smaller of what is left of the
    budget and the screen; a failure of either ends the solve at once (no full NLP from the initial parameters),
    named ``Screened_Out``; when both pass, the answer is the full NLP's."""
    template = StabilizationSolution(np.zeros(problem.n_params), False, "", 0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for coarse_ok, full_ok, expected in ((False, True, [(False, 20)]), (True, False, [(False, 20), (True, 20)]),
                                         (True, True, [(False, 20), (True, 20)])):
        calls = []

        def fake_solve(nlp, g, warm_params, max_iterations=None, deadline=None, stall=None, oks=(coarse_ok, full_ok),
                       calls=calls):
            calls.append((nlp is problem, max_iterations))
            ok = oks[nlp is problem]
            return replace(template, iterations=10 if ok else max_iterations, success=ok,
                           status="ok" if ok else "Iteration_Budget_Exhausted")

        monkeypatch.setattr(stabilization_solve, "solve_once", fake_solve)
        _without_dense_check(monkeypatch)
        sol = solve_stabilization(problem, grasp, max_iterations=120, screen_iterations=20)
        assert calls == expected
        assert sol.success is (coarse_ok and full_ok)
        assert sol.status == ("ok" if coarse_ok and full_ok else SolveOutcome.SCREENED_OUT)
        assert sol.iterations == sum(10 if ok else 20 for ok in (coarse_ok, full_ok)[:len(expected)])
    # warm solves are never screened: they keep their grasp
    calls.clear()
    solve_stabilization(problem, grasp, problem.initial_params(grasp), max_iterations=30, screen_iterations=20)
    assert calls == [(True, 30)]


@pytest.fixture(scope="module")
def scanned_grasps() -> list[GraspState]:
    doc = json.loads((ROOT / "tests" / "data" / "grasps_II.json").read_text(encoding="utf-8"))
    return [GraspState(*(np.asarray(g[k], dtype=float) for k in ("q", "qd", "qdd", "x_base", "h_world", "T_ee_target")))
            for g in doc["grasps"]]


def test_the_screen_sets_aside_the_grasp_the_nlp_cannot_brake_and_passes_the_one_it_can(problem, scanned_grasps):
    """A flat spin's grasp the NLP cannot brake (120 iterations end at 201 N·m) is screened out, with the panel still
    inside the chaser and the torque over its limit; the default state's second grasp passes the screen and
    stabilizes, with the very answer of the unscreened solve."""
    hopeless, braked = scanned_grasps
    out = solve_stabilization(problem, hopeless, max_iterations=STABILIZATION_BUDGET, screen_iterations=SCREEN_BUDGET)
    assert out.status == SolveOutcome.SCREENED_OUT and not out.success and out.iterations == SCREEN_BUDGET
    assert out.min_distance_m < 0.0 and out.peak_torque_nm > problem.scenario.limits.grasp_torque_max_nm
    ok = solve_stabilization(problem, braked, max_iterations=STABILIZATION_BUDGET, screen_iterations=SCREEN_BUDGET)
    assert ok.success and ok.iterations <= 2 * SCREEN_BUDGET
    assert ok.peak_torque_nm <= problem.scenario.limits.grasp_torque_max_nm and ok.min_distance_m > 0.02
    plain = solve_stabilization(problem, braked, max_iterations=STABILIZATION_BUDGET)
    np.testing.assert_array_equal(ok.params, plain.params)


def test_the_smooth_stop_of_a_grasp_at_rest_stays_put_and_one_of_a_moving_grasp_stops(scenario_II, grasp):
    """The cold start's heuristic (no NLP): a grasp at rest (the degenerate case, no joint moving) keeps its
    configuration; a moving grasp's stop never passes a joint limit."""
    spline, robot = stabilization_spline(scenario_II), scenario_II.robot
    t = np.linspace(0.0, spline.duration_s, 200)
    at_rest = replace(grasp, qd=np.zeros(7), qdd=np.zeros(7))
    V = stabilization_vertices(spline, at_rest.q, at_rest.qd, at_rest.qdd, smooth_stop_params(spline, robot, at_rest))
    # round-off only: the vertices come from solving the boundary conditions through the basis matrices, whose
    # conditioning grows with the vertex count (14: 1.4e-12 rad off at most)
    np.testing.assert_allclose(spline.evaluate(V, t), np.tile(at_rest.q, (len(t), 1)), rtol=0, atol=1e-11)
    V = stabilization_vertices(spline, grasp.q, grasp.qd, grasp.qdd, smooth_stop_params(spline, robot, grasp))
    q = spline.evaluate(V, t)
    assert (q >= robot.q_min).all() and (q <= robot.q_max).all()


def test_the_dense_torques_hold_the_nlps_own_at_its_via_points(problem, grasp):
    """The check between via points evaluates the NLP's own model: at the via points (part of the dense set) it
    gives the NLP's torques to integration accuracy (the dense RK4 takes smaller steps)."""
    from planner.phases.stabilization import DENSE_FACTOR

    par = problem.parameters(grasp)
    P = problem.initial_params(grasp)
    at_via = np.asarray(problem.outputs(P, par)[0]).reshape(-1, 3)
    T = problem.scenario.phases.stabilization_s
    times = np.union1d(np.linspace(0.0, T, DENSE_FACTOR * problem.k + 1), problem.via_times_s)
    np.testing.assert_array_equal(problem.dense_times_s, times)
    dense = np.asarray(problem.dense_samples()(P, par)[0]).reshape(-1, 3)
    assert dense.shape[0] == len(times)
    rows = [int(np.argmin(np.abs(times - t))) for t in problem.via_times_s]
    atol = 1e-6 * max(1.0, np.abs(at_via).max())
    np.testing.assert_allclose(dense[rows], at_via, atol=atol)
    assert np.abs(dense).max() >= np.abs(at_via).max() - atol  # a superset of the instants, to integration accuracy


class _BetweenStandIn:
    """What the dense check reads of a problem: the limits, and dense samples (one instant) that change as the bounds
    tighten: a torque peak and each pair's clearance per re-solve."""

    dense_times_s = np.array([0.0])  # one instant: its torque is the peak, its distances the least

    def __init__(self, problem, peaks, distances=None):
        self.torque_limit = 10.0
        self.scenario = problem.scenario
        self.peaks = list(peaks)
        self.distances = list(distances) if distances is not None else [np.full(3, 0.1)] * len(self.peaks)
        self.problem = problem

    def parameters(self, grasp):
        return self.problem.parameters(grasp)

    def dense_samples(self):
        return lambda P, par: (np.array([self.peaks.pop(0), 0.0, 0.0]), np.asarray(self.distances.pop(0)))


def _recording_resolve(bounds_seen: list):
    def resolve(prob, grasp_, warm, left, deadline, bounds=AS_SOLVED):
        bounds_seen.append(bounds)
        return StabilizationSolution(np.asarray(warm), True, SolveOutcome.FEASIBLE_POINT_FOUND, 3, 0.1, 0.0, 0.0,
                                     9.0, 0.1)
    return resolve


def test_a_torque_peak_between_via_points_tightens_the_bound_and_resolves(problem, grasp, monkeypatch):
    seen: list = []
    monkeypatch.setattr(stabilization_solve, "solve_once", _recording_resolve(seen))
    first = StabilizationSolution(problem.initial_params(grasp), True, SolveOutcome.FEASIBLE_POINT_FOUND, 20, 1.0,
                                  0.0, 0.0, 9.5, 0.1)
    held = stabilization_solve._held_between_via_points
    # 10.5 N·m between via points: one re-solve with the bound × 0.98·10/10.5, then 9.9 N·m holds
    out = held(_BetweenStandIn(problem, [10.5, 9.9]), grasp, first, 120, stabilization_solve.NO_DEADLINE)
    assert out.success and out.iterations == 23
    assert [b.torque_scale for b in seen] == [pytest.approx(TORQUE_MARGIN * 10.0 / 10.5)]
    assert not any(seen[0].clearance_raise_m)
    # still above after every round: a failure the grasp search moves on from
    seen.clear()
    peaks = [10.5] * (stabilization_solve.HOLD_ROUNDS + 1)
    out = held(_BetweenStandIn(problem, peaks), grasp, first, 120, stabilization_solve.NO_DEADLINE)
    assert not out.success and out.status == SolveOutcome.TORQUE_BETWEEN_VIA_POINTS
    assert len(seen) == stabilization_solve.HOLD_ROUNDS
    # within the limit at once: the solve as it was, no re-solve
    seen.clear()
    assert held(_BetweenStandIn(problem, [9.99]), grasp, first, 120, stabilization_solve.NO_DEADLINE) is first
    assert seen == []


def test_a_pair_too_close_between_via_points_raises_its_clearance_bound_alone(problem, grasp, monkeypatch):
    """Pair 1 at 1.2 cm between the via points (margin 2 cm): one re-solve with that pair's bound raised by its
    shortfall below margin + pad, the others' not; at 2.6 cm it holds. Torque within its limit: its bound as it was."""
    margin = problem.scenario.limits.collision_margin_m
    seen: list = []
    monkeypatch.setattr(stabilization_solve, "solve_once", _recording_resolve(seen))
    first = StabilizationSolution(problem.initial_params(grasp), True, SolveOutcome.FEASIBLE_POINT_FOUND, 20, 1.0,
                                  0.0, 0.0, 9.5, 0.1)
    held = stabilization_solve._held_between_via_points
    close, clear = np.array([0.1, 0.012, 0.3]), np.array([0.1, margin + CLEARANCE_PAD_M + 1e-3, 0.3])
    out = held(_BetweenStandIn(problem, [9.0, 9.0], [close, clear]), grasp, first, 120,
               stabilization_solve.NO_DEADLINE)
    assert out.success and out.iterations == 23
    (bounds,) = seen
    assert bounds.torque_scale == 1.0
    np.testing.assert_allclose(bounds.clearance_raise_m, [0.0, margin + CLEARANCE_PAD_M - 0.012, 0.0], atol=1e-15)
    # exactly at margin + pad holds; just below it re-solves, and the raises accumulate over the rounds
    seen.clear()
    edge = np.array([0.1, margin + CLEARANCE_PAD_M, 0.3])
    assert held(_BetweenStandIn(problem, [9.0], [edge]), grasp, first, 120, stabilization_solve.NO_DEADLINE) is first
    rounds = stabilization_solve.HOLD_ROUNDS + 1
    out = held(_BetweenStandIn(problem, [9.0] * rounds, [edge - 1e-6] * rounds), grasp, first, 120,
               stabilization_solve.NO_DEADLINE)
    assert [b.clearance_raise_m[1] for b in seen] == pytest.approx([1e-6, 2e-6])
    # short of the pad only, never of the margin: the last solve is the answer (verify judges it), not a failure
    assert out.success and out.iterations == 20 + 3 * stabilization_solve.HOLD_ROUNDS
    # below the margin itself after every round: a failure the grasp search moves on from
    out = held(_BetweenStandIn(problem, [9.0] * rounds, [close] * rounds), grasp, first, 120,
               stabilization_solve.NO_DEADLINE)
    assert not out.success and out.status == SolveOutcome.CLEARANCE_BETWEEN_VIA_POINTS


def test_a_tighter_resolve_that_fails_falls_back_to_the_solve_within_the_margin(problem, grasp, monkeypatch):
    """Short of the pad only (2.2 cm against 2 cm + 5 mm): the re-solve with the raised bound fails (its budget); the
    answer is the first solve, with the iterations of both."""
    failing = StabilizationSolution(problem.initial_params(grasp) + 1.0, False,
                                    SolveOutcome.ITERATION_BUDGET_EXHAUSTED, 7, 0.5, 0.0, 0.0, 30.0, 0.0)
    monkeypatch.setattr(stabilization_solve, "solve_once", lambda *a, **k: failing)
    first = StabilizationSolution(problem.initial_params(grasp), True, SolveOutcome.FEASIBLE_POINT_FOUND, 20, 1.0,
                                  0.0, 0.0, 9.5, 0.1)
    near = np.array([0.1, problem.scenario.limits.collision_margin_m + 0.002, 0.3])
    out = stabilization_solve._held_between_via_points(_BetweenStandIn(problem, [9.0], [near]), grasp, first, 120,
                                                      stabilization_solve.NO_DEADLINE)
    assert out.success and out.status == SolveOutcome.FEASIBLE_POINT_FOUND
    np.testing.assert_array_equal(out.params, first.params)
    assert out.iterations == 27 and out.solve_time_s == pytest.approx(1.5)


def _relative_excess(problem, params, par) -> float:
    """Σ over the NLP's constraint rows of the excess beyond the bounds, relative to each bound (written here,
    apart from the callback's)."""
    g = np.asarray(problem.solver.get_function("nlp_g")(params, par)).ravel()
    total = 0.0
    for value, lo, hi in zip(g, problem.lbg, problem.ubg, strict=True):
        bound = max(abs(b) for b in (lo, hi) if np.isfinite(b)) if np.isfinite([lo, hi]).any() else 0.0
        over = max(lo - value, value - hi, 0.0)
        total += over / (bound if bound > 1e-9 else 1.0)
    return total


def test_a_failing_stabilization_answers_with_its_least_violating_iterate(problem, scanned_grasps, monkeypatch):
    """From scenario II's hopeless grasp (cold), 15 iterations of the full NLP, whose violation grows again after
    iteration 14: the answer is the least violating of the iterates IPOPT went through (recorded as it handed them
    to the callback), by a violation computed here from the NLP's own constraint function."""
    hopeless = scanned_grasps[0]
    par = problem.parameters(hopeless)
    assert problem.n_extra == 0
    iterates = []
    callback = type(problem.stop).eval

    def recording(arg):
        iterates.append(np.asarray(arg[ca.nlpsol_out().index("x")]).ravel().copy())
        return callback(problem.stop, arg)

    monkeypatch.setattr(problem.stop, "eval", recording)
    answer = stabilization_solve.solve_once(problem, hopeless, None, 15)
    assert not answer.success and answer.iterations == 15 and len(iterates) == 16
    violations = [_relative_excess(problem, x, par) for x in iterates]
    assert min(violations) < violations[-1]  # the last iterate is not the least violating one
    np.testing.assert_array_equal(answer.params, iterates[int(np.argmin(violations))])


def test_the_dense_distances_at_the_via_points_are_the_nlps_own(problem, grasp):
    """The dense samples' distances, sampled at the via points (the dense instants include them), gives the NLP's own
    constraint distances there, pair by pair: the same engine, the same layout (point-major), the same instants."""
    par = problem.parameters(grasp)
    params = problem.initial_params(grasp)
    dense = np.asarray(problem.dense_samples()(params, par)[1]).reshape(len(problem.dense_times_s), -1)
    at_via = np.asarray(problem.outputs(params, par)[2]).reshape(problem.k, -1)
    rows = [int(np.argmin(np.abs(problem.dense_times_s - t))) for t in problem.via_times_s]
    np.testing.assert_allclose(problem.dense_times_s[rows], problem.via_times_s, atol=1e-9)
    np.testing.assert_allclose(dense[rows], at_via, rtol=0, atol=1e-9)
    assert dense.shape[1] == len(problem.scene.pairs)


def test_tightened_bounds_raise_only_their_pairs_rows_at_every_via_point_and_scale_only_the_torque(problem):
    n_pairs = len(problem.scene.pairs)
    raise_m = np.zeros(n_pairs)
    raise_m[[0, n_pairs - 1]] = 0.01, 0.003
    lbg, ubg = ViaPointBounds(0.9, tuple(raise_m)).applied(problem)
    collision, torque = problem.constraints.slice("collision"), problem.constraints.slice("grasp_torque")
    want_lbg, want_ubg = problem.lbg.copy(), problem.ubg.copy()
    for via in range(problem.k):  # written out row by row, apart from the np.tile in applied()
        want_lbg[collision.start + via * n_pairs] += 0.01
        want_lbg[collision.start + via * n_pairs + n_pairs - 1] += 0.003
    want_lbg[torque], want_ubg[torque] = 0.9 * want_lbg[torque], 0.9 * want_ubg[torque]
    np.testing.assert_array_equal(lbg, want_lbg)
    np.testing.assert_array_equal(ubg, want_ubg)
    as_solved = AS_SOLVED.applied(problem)
    np.testing.assert_array_equal(as_solved[0], problem.lbg)
    assert as_solved[0] is not problem.lbg  # a copy: the problem's own bounds are never changed


@pytest.mark.parametrize(("torque_limit", "peak", "clearance_over_margin_m", "holds"), [
    (10.0, 10.0, 0.0, True),  # touching both limits exactly: within them
    (10.0, 10.0 + 1e-9, 0.0, False),  # the torque just over
    (10.0, 10.0, -1e-9, False),  # a pair just inside the margin
    (np.inf, 1e6, 0.0, True),  # no torque limit: any torque, and the margin still judged
    (np.inf, 1e6, -1e-9, False),
])
def test_within_limits_at_and_just_past_each_limit(problem, torque_limit, peak, clearance_over_margin_m, holds):
    stand_in = _BetweenStandIn(problem, [])
    stand_in.torque_limit = torque_limit
    margin = problem.scenario.limits.collision_margin_m
    seen = BetweenViaPoints(peak, np.array([0.3, margin + clearance_over_margin_m]))
    assert within_limits(stand_in, seen) is holds
    # within the limits but short of the pad: tightened (a re-solve), never a torque scale without an overshoot
    tighter = tightened(stand_in, AS_SOLVED, seen)
    assert tighter is not None and (tighter.torque_scale < 1.0) is (peak > torque_limit)
