"""Solving the approach NLP for one target state: its starts (warm, base pinned, scanned guesses) and IPOPT.

Everything a solve depends on besides the problem is passed in: the target state, the warm start, the scan
of meeting times (held by the caller for one plan), the tracking-rate scale, the iteration budget and the
plan's deadline.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, replace
from itertools import islice

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.deadline import NO_DEADLINE, START_LEAD_S, Deadline
from planner.model.target import TargetState
from planner.nlp.feasibility_stop import StallRule
from planner.nlp.outcome import SolveOutcome
from planner.phases.approach import ApproachProblem, ApproachSolution
from planner.phases.approach_bounds import AS_SOLVED, ApproachBounds
from planner.phases.approach_branch import one_side_of_singularities
from planner.phases.approach_guess import ApproachGuess, ScanOnDemand, angles_apart
from planner.phases.scan_in_time import meets_in_time, scan_in_time
from planner.phases.tracking_profile import TRACKING_NODES
from planner.plan_parameters import ApproachParameters

Array = NDArray[np.float64]

# IPOPT iterations a start from a scanned guess gets before the next guess is tried: cold starts that led to feasible
# plans took 5-78 (two scenario I flat spins 246 and 315); failing ones ran 400-900 and spent the plan's budget
COLD_START_ITERATIONS = 150
# a feasibility approach's start from a scanned guess whose least violation so far is above 1e-3 and has not halved over
# its last 50 iterations is given up, and the next guess tried: on 259 such starts traced (coverage states, seeds 7, 8)
# that cuts none of the 180 that succeeded, 47 of the 79 that failed; a window of 30 lost a start that converged after a
# 45-iteration plateau (README, "The measurements behind the planner's constants")
APPROACH_STALL = StallRule(after=50, over=50, ratio=0.5, least_so_far=True, floor=1e-3)  # judged from its 50th on
# IPOPT iterations a base-pinned start of an Eq. 16 solve gets: where the optimum at the base-offset guess exists it
# converged in 8-16 (36 scenario I flat spins); where not (scenario II) it ran 100-400 and failed, 17-52 s a plan
PINNED_START_ITERATIONS = 40
# a cold Eq. 16 solve pins the base from this many guesses, and ends when none converges: at 36 scenario I flat spins
# traced the first converged at 35, the second at the 36th; none at any scenario II state traced, where free starts
# then found an optimum whose braking was screened out (README, "The measurements behind the planner's constants")
PINNED_STARTS = 2
# a retry's meeting time keeps at least this far [s] from those of the grasps already tried (a grasp 1 s away is the
# same grasp: scenario II's retries met at 37.8 s twice, at the touching edges of their guesses' boxes)
AVOID_GAP_S = 2.0


@dataclass(frozen=True)
class TriedGrasp:
    """A grasp a plan has tried: a retry from a guess holding the handle at about its angle keeps clear of its time."""

    start_delay_s: float  # [s]
    free_axis_angle_rad: float | None  # about a free grasp axis, from the configured grasp frame [rad]


def decision_vector(start: ApproachParameters | ApproachSolution | ApproachGuess) -> Array:
    """``w`` without extras, ``[params, base offset, start delay, tracking nodes]``, of a start."""
    return np.concatenate([start.params, start.base_offset_m, [start.start_delay_s], start.q_tracking.ravel()])


def solve_approach(problem: ApproachProblem, state: TargetState,
                   warm_start: ApproachParameters | ApproachSolution | None = None, max_starts: int = 3,
                   tracking_speed_scale: float | Array = 1.0, skip_guesses: int = 0, max_iterations: int | None = None,
                   scan: ScanOnDemand | None = None, deadline: Deadline = NO_DEADLINE,
                   meeting_time_box_s: float | None = None, avoid: tuple[TriedGrasp, ...] = (),
                   tightened: ApproachBounds = AS_SOLVED) -> ApproachSolution:
    """Solve ``problem`` for one observed target state.

    With ``warm_start`` (e.g. a solved neighbour of a grid) the NLP starts there; otherwise, and if that fails, it
    starts from the ``max_starts`` best scanned initial guesses of ``scan`` (made here when not given or not of this
    state and count; for a live plan, of those meeting after its answer can come, a guess too early taking no
    start), best first, less the first ``skip_guesses`` of them (the planner's next grasp when a stabilization
    failed), and returns the first success (or the last attempt, with its failure status; its ``start_guess`` says
    which guess). ``tracking_speed_scale`` scales the tracking-node rate bounds (one factor, or one per tracking
    segment). ``max_iterations`` (None: only the scenario's per-NLP ``max_iter``) bounds the IPOPT iterations of all
    the starts together; a solve that spends it ends unsuccessful, status ``Iteration_Budget_Exhausted`` (IPOPT
    calls back once per iteration, and once more in a cold start's restoration phase). Past ``deadline`` no further
    start is tried and a running solve ends, status ``Out_Of_Time``; a start that can no longer be on time
    (:func:`start_deadline`) ends the same way, and so does this solve (the grasp search goes on from the next
    guess). The approach's end and the tracking nodes stay on one side of every singular joint angle
    (:func:`~planner.phases.approach_branch.one_side_of_singularities`). ``meeting_time_box_s`` keeps every start
    within that many seconds of its own start delay (None: anywhere in the window) and :data:`AVOID_GAP_S` from each
    grasp of ``avoid`` at about its angle (a start whose box that leaves empty is skipped), so that guesses reach
    grasps not tried yet. A start from a scanned guess ends after :data:`COLD_START_ITERATIONS` iterations, or once
    stalled (:data:`APPROACH_STALL`, a feasibility approach's; status ``Stalled``), and the next guess is tried. A cold
    Eq. 16 solve ends, failed, when its base-pinned solve does (:func:`_base_pinned_first`). ``tightened``: rows held
    tighter than the NLP's own (:mod:`planner.phases.approach_bounds`: its clearance or rates between via points).
    """
    t0 = time.perf_counter()
    warm_start, result, iterations = _base_pinned_first(problem, state, warm_start, tracking_speed_scale,
                                                        skip_guesses, deadline, max_iterations)
    if result is not None:  # no optimum at the base-offset guess: free starts reach only the minima the pin avoids
        return replace(result, iterations=iterations, solve_time_s=time.perf_counter() - t0)
    if scan is None or not scan.serves(state, max_starts):
        scan = ScanOnDemand(problem.scenario, problem.spline, state, max_starts)
    for attempt, (w0, guess, angle) in enumerate(islice(_starts(warm_start, scan, skip_guesses, deadline),
                                                        max_starts + int(warm_start is not None))):
        if attempt > 0 and (time.perf_counter() - t0 > problem.scenario.solver.max_wall_s or deadline.passed):
            break
        left = None if max_iterations is None else max_iterations - iterations
        if left is not None and left <= 0:
            break
        cold = guess is not None
        limit = _start_limit(COLD_START_ITERATIONS if cold else None, left)
        lbw, ubw = _meeting_time_box(problem, w0, meeting_time_box_s, _avoided_s(avoid, angle))
        if lbw is None:
            continue
        result = _solve_once(problem, state, w0, tracking_speed_scale, lbw, ubw, cold=cold, max_iterations=limit,
                             deadline=deadline, tightened=tightened)
        if cold:
            result = replace(result, start_guess=guess)
        iterations += result.iterations
        budget_spent = problem.budget.budget_exhausted and left is not None and limit == left
        # stopped for time (its start's deadline too): the grasp search, not this loop, goes on from the next guess
        if result.success or budget_spent or problem.budget.out_of_time:
            break
    if result is None:
        return _no_start(problem, _no_guess_status(problem, scan, skip_guesses, deadline),
                         problem.scenario.base_offset_guess_m, time.perf_counter() - t0)
    return replace(result, iterations=iterations, solve_time_s=time.perf_counter() - t0)


def _no_guess_status(problem: ApproachProblem, scan: ScanOnDemand, skip_guesses: int,
                     deadline: Deadline) -> SolveOutcome:
    """Why no NLP start was made: guesses meeting too early for a live plan (after the first ``skip_guesses``), or a
    scan of the window still in time that reached nothing, else none left."""
    rescanned = scan.scenario.phases.min_start_delay_s > problem.scenario.phases.min_start_delay_s
    too_early = scan.made and any(not meets_in_time(g.start_delay_s, deadline)
                                  for g in scan.result.guesses[skip_guesses:])
    return SolveOutcome.NO_GUESS_IN_TIME if too_early or rescanned else SolveOutcome.NO_GUESS_LEFT


def _starts(warm_start: ApproachParameters | ApproachSolution | None, scan: ScanOnDemand, skip_guesses: int,
            deadline: Deadline) -> Iterator[tuple[Array, int | None, float | None]]:
    """The NLP starts in order, each ``(w0, scanned guess index or None for the warm start, its angle about a free
    grasp axis)``: the warm start, then each scanned guess after the first ``skip_guesses`` once, but those meeting
    before a live plan's answer can come (:func:`meets_in_time`: they take no start; the scan is made only when a
    guess is asked for)."""
    if warm_start is not None:
        yield decision_vector(warm_start), None, None
    for index in range(skip_guesses, len(scan.result.guesses)):
        guess = scan.result.guesses[index]
        if not meets_in_time(guess.start_delay_s, deadline):
            continue
        yield decision_vector(guess), index, guess.free_axis_angle_rad


def solve_approach_near(problem: ApproachProblem, state: TargetState, anchor: ApproachSolution, radius_m: float,
                        tracking_speed_scale: float | Array, max_iterations: int | None,
                        deadline: Deadline = NO_DEADLINE) -> ApproachSolution:
    """The approach NLP warm from ``anchor`` with its meeting time kept (the start delay pinned) and the base offset
    θ_b(0) within ``radius_m`` [m] of the anchor's per axis (``inf``: the scenario's bounds only), within
    ``max_iterations`` IPOPT iterations: a trust-region step of a costed plan (:mod:`planner.plan_costed`)."""
    lbw, ubw = _base_box(problem, anchor.base_offset_m, radius_m)
    delay = problem.decision.slice("start_delay_s")
    lbw[delay] = ubw[delay] = anchor.start_delay_s
    return _solve_once(problem, state, decision_vector(anchor), tracking_speed_scale, lbw, ubw,
                       max_iterations=max_iterations, deadline=deadline)


def _base_box(problem: ApproachProblem, centre_m: Array, radius_m: float) -> tuple[Array, Array]:
    """The problem's bounds ``(lbw, ubw)`` (copies) with θ_b(0) also within ``radius_m`` [m] of ``centre_m`` [m] (x, z)
    per axis (0: fixed there; ``inf``: the scenario's bounds only)."""
    lbw, ubw = problem.lbw.copy(), problem.ubw.copy()
    base = problem.decision.slice("base_offset_m")
    lbw[base] = np.maximum(lbw[base], centre_m - radius_m)
    ubw[base] = np.minimum(ubw[base], centre_m + radius_m)
    return lbw, ubw


def _avoided_s(avoid: tuple[TriedGrasp, ...], angle_rad: float | None) -> tuple[float, ...]:
    """The meeting times [s] of the grasps in ``avoid`` a start holding the handle at ``angle_rad`` keeps clear of:
    those at about its angle (all of them when an angle is unknown)."""
    return tuple(t.start_delay_s for t in avoid if not angles_apart(t.free_axis_angle_rad, angle_rad))


def _meeting_time_box(problem: ApproachProblem, w0: Array, box_s: float | None,
                      avoid_s: tuple[float, ...]) -> tuple[Array, Array] | tuple[None, None]:
    """The problem's bounds ``(lbw, ubw)``, the start delay within ``box_s`` [s] of ``w0``'s (None: as they are) and
    :data:`AVOID_GAP_S` clear of each delay in ``avoid_s`` on ``w0``'s side of it; ``(None, None)`` when nothing is
    left (``w0``'s own delay that close to one avoided)."""
    if box_s is None:
        return problem.lbw, problem.ubw
    lbw, ubw = problem.lbw.copy(), problem.ubw.copy()
    delay = problem.decision.slice("start_delay_s").start
    lo, hi = max(lbw[delay], w0[delay] - box_s), min(ubw[delay], w0[delay] + box_s)
    for avoided in avoid_s:
        if abs(w0[delay] - avoided) < AVOID_GAP_S:
            return None, None
        lo, hi = (max(lo, avoided + AVOID_GAP_S), hi) if w0[delay] > avoided else (lo, min(hi, avoided - AVOID_GAP_S))
    if lo > hi:
        return None, None
    lbw[delay], ubw[delay] = lo, hi
    return lbw, ubw


def approach_cost(problem: ApproachProblem, state: TargetState, start: ApproachParameters | ApproachSolution) -> float:
    """The NLP's weighted cost (Eq. 14-16) of ``start``'s decision parameters for ``state``."""
    return problem.objective_at(decision_vector(start), state)


def _base_pinned_first(problem: ApproachProblem, state: TargetState,
                       warm_start: ApproachParameters | ApproachSolution | None,
                       tracking_speed_scale: float | Array, skip_guesses: int, deadline: Deadline,
                       max_iterations: int | None,
                       ) -> tuple[ApproachParameters | ApproachSolution | None, ApproachSolution | None, int]:
    """``(warm start, failed pinned solve, iterations)`` after the base-pinned solve a first solve with the
    approach-energy cost makes first (no solve otherwise), from :data:`PINNED_STARTS` guesses each within
    :data:`PINNED_START_ITERATIONS`, all within ``max_iterations`` (the whole solve's, which the free starts then
    share); the failed pinned solve is given only for a cold solve, which then ends.

    Eq. 16 is smallest at the base-offset guess, but free-base starts lead IPOPT into local minima where the
    stopping room and the tracking rates hold the base away: solve with the base pinned first; if that
    succeeds, the free solve starts at its optimum; if not, there is no such optimum to start from.
    """
    if not problem.scenario.costs.approach_energy > 0 or skip_guesses != 0:
        return warm_start, None, 0
    pinned = _solve_base_pinned(problem, state, tracking_speed_scale, deadline, max_iterations)
    if warm_start is not None:  # a neighbour's plan ended in a local minimum θ_b(0) ≈ 0.27-0.9 m; kept as a fallback
        return (pinned if pinned.success else warm_start), None, pinned.iterations
    return (pinned, None, pinned.iterations) if pinned.success else (None, pinned, pinned.iterations)


def _no_start(problem: ApproachProblem, status: SolveOutcome, base_offset_m: tuple[float, float],
              elapsed_s: float) -> ApproachSolution:
    """A failed solution for when no NLP start exists (``status`` says why)."""
    return ApproachSolution(np.zeros(problem.n_params), np.asarray(base_offset_m, dtype=float), 0.0,
                            np.zeros((len(TRACKING_NODES), problem.robot.n_joints)), False, status, 0, elapsed_s,
                            np.inf, np.nan)


def _solve_base_pinned(problem: ApproachProblem, state: TargetState, tracking_speed_scale: float | Array,
                       deadline: Deadline, max_iterations: int | None) -> ApproachSolution:
    """The NLP with θ_b(0) fixed at the scenario's base-offset guess, from the best :data:`PINNED_STARTS` guesses made
    for that base."""
    return solve_approach_from_base(problem, state, problem.scenario.base_offset_guess_m, PINNED_STARTS,
                                    tracking_speed_scale, deadline, max_iterations,
                                    start_iterations=PINNED_START_ITERATIONS)


def solve_approach_from_base(problem: ApproachProblem, state: TargetState, base_offset_m: Array, max_starts: int,
                             tracking_speed_scale: float | Array, deadline: Deadline = NO_DEADLINE,
                             max_iterations: int | None = None, radius_m: float = 0.0,
                             start_iterations: int | None = None) -> ApproachSolution:
    """The NLP with θ_b(0) within ``radius_m`` [m] of ``base_offset_m`` [m] (x, z) per axis (0: fixed there), from up
    to ``max_starts`` guesses scanned for that base, the first success; each start within ``start_iterations``
    (default: :data:`COLD_START_ITERATIONS` with ``max_iterations``, else the scenario's ``max_iter``), all within
    ``max_iterations``. Status ``NO_PINNED_START`` when no meeting time is reachable from that base,
    ``NO_GUESS_IN_TIME`` when every one reachable comes before a live plan's answer can."""
    t0 = time.perf_counter()
    bx, bz = (float(v) for v in base_offset_m)
    pinned = replace(problem.scenario, base_offset_bounds_m=((bx, bx), (bz, bz)),
                     base_offset_guess_m=np.array([bx, bz]))
    lbw, ubw = _base_box(problem, np.array([bx, bz]), radius_m)
    result, iterations = None, 0
    guesses, reached = _guesses_in_time(pinned, problem, state, max_starts, deadline)
    cap = COLD_START_ITERATIONS if start_iterations is None and max_iterations is not None else start_iterations
    for g in guesses:
        limit = _start_limit(cap, None if max_iterations is None else max_iterations - iterations)
        result = _solve_once(problem, state, decision_vector(g), tracking_speed_scale, lbw, ubw, cold=True,
                             max_iterations=limit, deadline=deadline)
        iterations += result.iterations
        if result.success or time.perf_counter() - t0 > problem.scenario.solver.max_wall_s or deadline.passed \
                or (max_iterations is not None and iterations >= max_iterations):
            break
    if result is None:
        why = SolveOutcome.NO_GUESS_IN_TIME if reached else SolveOutcome.NO_PINNED_START
        return _no_start(problem, why, (bx, bz), time.perf_counter() - t0)
    return replace(result, iterations=iterations, solve_time_s=time.perf_counter() - t0)


def _start_limit(cap: int | None, left: int | None) -> int | None:
    """IPOPT iterations the next start may take: at most ``cap`` a start and the ``left`` of a solve's budget (None:
    that one does not bound it; both None: the scenario's ``max_iter`` alone)."""
    return min((n for n in (cap, left) if n is not None), default=None)


def _guesses_in_time(scenario: Scenario, problem: ApproachProblem, state: TargetState, count: int,
                     deadline: Deadline) -> tuple[list[ApproachGuess], bool]:
    """Up to ``count`` guesses scanned for ``scenario`` that meet in time under ``deadline`` (those of the whole
    window's scan, else of the window still in time: :func:`~planner.phases.scan_in_time.scan_in_time`), and whether
    the whole window's scan reached a meeting time at all."""
    whole = ScanOnDemand(scenario, problem.spline, state, count, held_angles=False)
    reached = bool(whole.result.guesses)
    in_time = scan_in_time(whole, deadline).result.guesses
    return [g for g in in_time if meets_in_time(g.start_delay_s, deadline)][:count], reached


def _solve_once(problem: ApproachProblem, state: TargetState, w0: Array, tracking_speed_scale: float | Array,
                lbw: Array | None = None, ubw: Array | None = None, cold: bool = False,
                max_iterations: int | None = None, deadline: Deadline = NO_DEADLINE,
                tightened: ApproachBounds = AS_SOLVED) -> ApproachSolution:
    """One IPOPT run from ``w0`` ``(n_w,)``; ``cold``: starting in the restoration phase; ``tightened``: as
    :func:`solve_approach`'s."""
    p = problem.parameter_layout.pack({"attitude_wxyz": state.attitude_wxyz,
                                       "omega_body_rad_s": state.omega_body_rad_s})
    lbw, ubw = _live_bounds(problem, w0, lbw, ubw, deadline)
    lbg, ubg = problem.lbg.copy(), problem.ubg.copy()
    lbw, ubw = one_side_of_singularities(problem, np.clip(w0, lbw[: problem.n_w], ubw[: problem.n_w]), lbw, ubw,
                                         lbg, ubg)
    w0 = np.clip(w0, lbw[: problem.n_w], ubw[: problem.n_w])  # the bounds only narrowed: one clip for both
    if problem.n_extra:  # the distance slack of Eq. 15 starts at 0
        w0 = np.concatenate([w0, [0.0]])
    t0 = time.perf_counter()
    rates = problem.constraints.slice("tracking_rates")
    per_row = np.repeat(np.broadcast_to(tracking_speed_scale, (len(TRACKING_NODES),)), problem.robot.n_joints)
    lbg[rates] *= per_row
    ubg[rates] *= per_row
    tightened.applied(problem, lbg, ubg)
    solver = problem.cold_solver if cold else problem.solver
    problem.budget.arm(lbg, ubg, stop_when_feasible=False, max_iterations=max_iterations,
                       deadline=start_deadline(problem, ubw, deadline), stall=_stall_rule(problem, cold))
    sol = solver(x0=w0, p=p, lbx=lbw, ubx=ubw, lbg=lbg, ubg=ubg)
    elapsed = time.perf_counter() - t0
    stats = solver.stats()
    return _solution(problem, np.asarray(sol["x"]).ravel(), np.asarray(sol["g"]).ravel(), float(sol["f"]), stats,
                     elapsed)


def _stall_rule(problem: ApproachProblem, cold: bool) -> StallRule | None:
    """:data:`APPROACH_STALL` for a start from a scanned guess of a feasibility approach (another guess is there to
    try), else None: a costed approach's violation is not its only progress, and a warm start has no next guess."""
    return APPROACH_STALL if cold and not problem.scenario.costs.weights_approach else None


def start_deadline(problem: ApproachProblem, ubw: Array, deadline: Deadline) -> Deadline:
    """``deadline``, or for a live plan the instant :data:`~planner.deadline.START_LEAD_S` before the latest start
    delay the bounds ``ubw`` allow, if that comes first: solved on past it, the grasp could not be tracked, braked and
    answered before its approach starts (a query's re-solve ran 47 s towards a start 28 s after the observation, and
    every other meeting time passed meanwhile)."""
    return deadline.in_time_for(float(ubw[problem.decision.slice("start_delay_s").start]), lead_s=START_LEAD_S)


def _live_bounds(problem: ApproachProblem, w0: Array, lbw: Array | None, ubw: Array | None,
                 deadline: Deadline) -> tuple[Array, Array]:
    """Bounds ``(lbw, ubw)`` (None: the problem's) with the start delay bounded below by ``deadline`` from where the NLP
    starts: ``w0``'s start delay [s] clipped to those bounds (:meth:`~planner.deadline.Deadline.start_bound_s`)."""
    lbw, ubw = problem.lbw if lbw is None else lbw, problem.ubw if ubw is None else ubw
    delay = problem.decision.slice("start_delay_s").start
    return _not_before(problem, lbw, ubw, deadline.start_bound_s(float(np.clip(w0[delay], lbw[delay], ubw[delay]))))


def _not_before(problem: ApproachProblem, lbw: Array, ubw: Array, earliest_s: float) -> tuple[Array, Array]:
    """Bounds ``(lbw, ubw)`` with the start delay no earlier than ``earliest_s`` [s] (a live plan's answer cannot come
    sooner: :meth:`~planner.deadline.Deadline.start_bound_s`) but within its upper bound (then pinned there: such a
    solve ends at once, :func:`start_deadline`)."""
    if not np.isfinite(earliest_s):
        return lbw, ubw
    delay = problem.decision.slice("start_delay_s").start
    lbw = lbw.copy()
    lbw[delay] = min(max(lbw[delay], earliest_s), ubw[delay])
    return lbw, ubw


def _solution(problem: ApproachProblem, w: Array, g: Array, cost: float, stats: dict,
              elapsed_s: float) -> ApproachSolution:
    """The solution read off IPOPT's answer ``w`` and constraint values ``g``."""
    d = problem.decision
    stopped = _planner_stop(problem)
    dists = g[problem.constraints.slice("collision")]
    return ApproachSolution(
        params=w[d.slice("spline_params")],
        base_offset_m=w[d.slice("base_offset_m")],
        start_delay_s=_within_window(problem, float(w[d.slice("start_delay_s").start])),
        q_tracking=w[d.slice("tracking_nodes")].reshape(len(TRACKING_NODES), -1),
        success=bool(stats["success"]) and stopped is None,
        status=stopped or SolveOutcome.from_ipopt(str(stats["return_status"])),
        iterations=int(stats["iter_count"]),
        solve_time_s=elapsed_s,
        cost=cost,
        min_distance_m=float(dists[problem.held_to_margin].min()),
    )


def _within_window(problem: ApproachProblem, start_delay_s: float) -> float:
    """``start_delay_s`` [s] inside the start-delay window: an iterate ended early (a deadline, the feasibility stop)
    may sit up to IPOPT's bound relaxation (1e-8 relative) outside it, and no start before the earliest exists."""
    return float(np.clip(start_delay_s, *problem.scenario.phases.start_delay_window_s))


def _planner_stop(problem: ApproachProblem) -> SolveOutcome | None:
    """Why the planner's callback ended the last solve, if it did: its iteration budget, its stall rule
    (:func:`_stall_rule`) or its deadline (the plan's, or its start's: :func:`start_deadline`)."""
    if problem.budget.budget_exhausted:
        return SolveOutcome.ITERATION_BUDGET_EXHAUSTED
    if problem.budget.stalled:
        return SolveOutcome.STALLED
    return SolveOutcome.OUT_OF_TIME if problem.budget.out_of_time else None
