"""Solving the stabilization NLP for one grasp: warm, or cold by way of the coarse problem.

A cold solve goes coarse to fine: the same NLP on ``coarse_via_points`` via points first (a third of the
cost per iteration), then the full NLP from that answer: a thin feasible set (a tight torque limit) that
IPOPT's limited-memory iterations approach slowly from the heuristic start is approached in a fraction of
the iterations from the coarse answer.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from planner.deadline import NO_DEADLINE, Deadline
from planner.nlp.feasibility_stop import StallRule
from planner.nlp.outcome import SolveOutcome
from planner.phases.between_via_points import (
    AS_SOLVED,
    ViaPointBounds,
    between_via_points,
    failed_between,
    tightened,
    within_limits,
)
from planner.phases.stabilization import GraspState, StabilizationProblem, StabilizationSolution

Array = NDArray[np.float64]

# a solve that breaks the torque limit or the collision margin between its via points is repeated this many times,
# its via-point bounds tightened (planner.phases.between_via_points)
HOLD_ROUNDS = 2


def solve_stabilization(problem: StabilizationProblem, grasp: GraspState, warm_params: Array | None = None,
                        max_iterations: int | None = None, screen_iterations: int | None = None,
                        deadline: Deadline = NO_DEADLINE, stall: StallRule | None = None) -> StabilizationSolution:
    """Solve ``problem`` for ``grasp``, from ``warm_params`` ``(7·(N−5),)`` or, cold, by way of the coarse problem.

    A cold start first solves the coarse NLP from :meth:`~StabilizationProblem.initial_params` and starts the
    full NLP from its answer, which sits near the full NLP's feasible set; should that solve fail, the full NLP
    is solved from the initial parameters as well, so a cold solve never does worse than the full NLP alone.
    The returned times and iteration counts cover every solve made. ``max_iterations`` (None: only the
    scenario's per-NLP ``max_iter``) bounds the IPOPT iterations of all those solves together; a solve that
    spends it ends unsuccessful with status ``Iteration_Budget_Exhausted``. ``screen_iterations`` (cold only)
    screens the grasp: the coarse NLP, and then the full NLP from its answer, each get at most that many
    iterations, and a grasp where either is not feasible within them is given up at once (status
    ``Screened_Out``, no full solve from the initial parameters); a grasp that passes has the very answer of an
    unscreened solve (the same iterates, only the budgets are smaller). Past ``deadline`` a running solve ends
    and no further one starts (status ``Out_Of_Time``). A warm solve armed with ``stall`` ends once its violation has
    stopped falling (status ``Stalled``).
    """
    if warm_params is not None or problem.coarse_via_points == 0:
        solved = solve_once(problem, grasp, warm_params, max_iterations, deadline, stall=stall)
    else:
        solved = _coarse_to_fine(problem, grasp, max_iterations, screen_iterations, deadline)
    return _held_between_via_points(problem, grasp, solved, max_iterations, deadline)


def _coarse_to_fine(problem: StabilizationProblem, grasp: GraspState, max_iterations: int | None,
                    screen_iterations: int | None, deadline: Deadline) -> StabilizationSolution:
    """A cold solve: the coarse NLP from the initial parameters, then the full NLP from its answer (and, should that
    fail, from the initial parameters), screened when ``screen_iterations`` is given (:func:`solve_stabilization`)."""
    coarse = problem.coarse_problem()
    attempts = [solve_once(coarse, grasp, None, _screened(max_iterations, screen_iterations), deadline)]
    screened_out = screen_iterations is not None and not attempts[0].success
    for start in () if screened_out else (attempts[0].params, None):
        left = None if max_iterations is None else max_iterations - sum(a.iterations for a in attempts)
        if (left is not None and left <= 0) or attempts[-1].status == SolveOutcome.OUT_OF_TIME:
            break
        attempts.append(solve_once(problem, grasp, start, _screened(left, screen_iterations), deadline))
        screened_out = screen_iterations is not None and not attempts[-1].success
        if attempts[-1].success or screened_out:
            break
    last = attempts[-1]
    return replace(last, iterations=sum(a.iterations for a in attempts),
                   solve_time_s=sum(a.solve_time_s for a in attempts),
                   build_time_s=problem.build_time_s + coarse.build_time_s,
                   status=SolveOutcome.SCREENED_OUT if screened_out and last.status != SolveOutcome.OUT_OF_TIME
                   else last.status)


def _held_between_via_points(problem: StabilizationProblem, grasp: GraspState, solved: StabilizationSolution,
                             max_iterations: int | None, deadline: Deadline) -> StabilizationSolution:
    """``solved``, once its grasp torque and its clearance hold between the via points too (the NLP's own model at
    :data:`~planner.phases.stabilization.DENSE_FACTOR` times as many instants,
    :func:`~planner.phases.between_via_points.between_via_points`); where either does not, the solve is repeated warm
    with its via-point bounds tightened by the shortfall (:func:`~planner.phases.between_via_points.tightened`), up to
    :data:`HOLD_ROUNDS` times. A pair short of only the pad (:data:`~planner.phases.between_via_points.CLEARANCE_PAD_M`)
    triggers a re-solve but is not refused: should the tighter re-solves fail, the last solve within the limits
    themselves is the answer (``verify`` judges it). Still beyond a limit, the solve is a failure (status
    ``Torque_Over_Limit_Between_Via_Points`` or ``Clearance_Under_Margin_Between_Via_Points``)."""
    bounds, holding = AS_SOLVED, None  # holding: the last solve within the limits themselves, short of the pad only
    for round_ in range(HOLD_ROUNDS + 1):
        if not solved.success:
            return solved if holding is None else _spent_on(holding, solved)
        seen = between_via_points(problem, grasp, solved.params)
        tighter = tightened(problem, bounds, seen)
        if tighter is None:
            return solved
        holding = solved if within_limits(problem, seen) else holding
        left = None if max_iterations is None else max_iterations - solved.iterations
        if round_ == HOLD_ROUNDS or (left is not None and left <= 0) or deadline.passed:
            break
        bounds = tighter
        again = solve_once(problem, grasp, solved.params, left, deadline, bounds=bounds)
        solved = replace(again, iterations=again.iterations + solved.iterations,
                         solve_time_s=again.solve_time_s + solved.solve_time_s)
    if holding is not None:
        return _spent_on(holding, solved)
    return replace(solved, success=False, status=failed_between(problem, seen))


def _spent_on(kept: StabilizationSolution, last: StabilizationSolution) -> StabilizationSolution:
    """``kept`` with the iterations and solve time of every solve up to ``last`` (which includes it)."""
    return replace(kept, iterations=last.iterations, solve_time_s=last.solve_time_s)


def _screened(max_iterations: int | None, screen_iterations: int | None) -> int | None:
    """One solve's iteration budget: what is left of the whole budget, or the screen's if smaller (None: neither)."""
    budgets = [b for b in (max_iterations, screen_iterations) if b is not None]
    return min(budgets) if budgets else None


def solve_once(problem: StabilizationProblem, grasp: GraspState, warm_params: Array | None,
               max_iterations: int | None = None, deadline: Deadline = NO_DEADLINE,
               bounds: ViaPointBounds = AS_SOLVED, stall: StallRule | None = None) -> StabilizationSolution:
    """One IPOPT run of ``problem`` from ``warm_params`` (None: its initial parameters), its via-point bounds
    tightened by ``bounds`` (:mod:`planner.phases.between_via_points`), ended early by ``stall`` (None: never)."""
    par = problem.parameters(grasp)
    w0 = problem.initial_params(grasp) if warm_params is None else np.asarray(warm_params, dtype=float)
    if problem.n_extra:
        M0, _, _ = problem.outputs(w0, par)
        w0 = np.concatenate([w0, [float(np.abs(np.asarray(M0)).max())]])
    lbg, ubg = bounds.applied(problem)
    problem.stop.arm(lbg, ubg, problem.feasibility_only, max_iterations, deadline, stall)
    t0 = time.perf_counter()
    sol = problem.solver(x0=w0, p=par, lbx=problem.lbw, ubx=problem.ubw, lbg=lbg, ubg=ubg)
    elapsed = time.perf_counter() - t0
    stats = problem.solver.stats()
    x, cost = np.asarray(sol["x"]).ravel(), float(sol["f"])
    success, status = bool(stats["success"]), SolveOutcome.from_ipopt(str(stats["return_status"]))
    if not (success or problem.stop.stopped):  # what the solve came closest to, not where it stopped
        x, cost = problem.stop.least_violating(x, cost, np.asarray(sol["g"]).ravel())
    P = x[problem.decision.slice("spline_params")]
    M, _, d = (np.asarray(a).ravel() for a in problem.outputs(P, par))
    if problem.stop.stopped:
        success, status = True, SolveOutcome.FEASIBLE_POINT_FOUND
    elif problem.stop.budget_exhausted:
        success, status = False, SolveOutcome.ITERATION_BUDGET_EXHAUSTED
    elif problem.stop.stalled:
        success, status = False, SolveOutcome.STALLED
    elif problem.stop.out_of_time:
        success, status = False, SolveOutcome.OUT_OF_TIME
    return StabilizationSolution(P, success, status, int(stats["iter_count"]), elapsed, problem.build_time_s,
                                 cost, float(np.abs(M).max()), float(d.min()))
