"""``lutgen query --robust``: among the plans a query can produce inside its budget, the one that absorbs a
given observation error best (``lutgen robustness``'s success probability, on the same draws for each).

The candidates, in order: the plain query's answer (exactly what ``lutgen query`` would return: interpolated,
nearest, refined or solved), each feasible corner of the cell carried to the state's phase (those within what a plan
of the table's kind carries, :mod:`lut.query.carry`), and, while the
budget allows and the plain answer was not already solved, a warm-started solve from the table's answer.
Each is re-simulated and verified at the observed state; a feasible one is executed against the same drawn
true states (common random numbers, so the comparison is paired), and the highest success probability
wins; a tie keeps the earlier candidate, so the plain answer is replaced only by a strictly more robust
plan. The plain query runs within the budget less the time its judgement is expected to take
(:data:`JUDGE_RUN_S` a run), so the plain answer is judged inside the budget; a judgement that no longer fits
is not started (the answer is then the plain one, said not judged).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from lut.query.result import QuerySource
from lut.robustness.error_model import ErrorModel, perturbed_states, standard_draws
from lut.robustness.execution import register_planner, run_states
from lut.robustness.statistics import SuccessEstimate, success_estimate
from lut.table.point_result import PointStatus

if TYPE_CHECKING:
    from lut.query.table_query import TableQuery
    from planner.model.target import TargetState
    from planner.plan import GraspPlan
    from planner.verify.verifier import VerifyReport

FINISH_RESERVE_S = 3.0  # kept back from the budget to print and export the chosen plan [s]
MIN_REFINE_S = 5.0  # a refine with less time than this cannot finish a solve: not started [s]
JUDGE_RUN_S = 2.5  # expected wall time of one drawn run per worker before any was measured: scenario II's simulate
# + verify is 1.1 s on an idle core and ~2.5 s on one loaded twice over [s]


@dataclass(frozen=True)
class RobustRequest:
    """The error the choice is made at, and how many drawn runs judge each candidate."""

    model: ErrorModel
    samples: int
    seed: int
    jobs: int
    step_s: float = 0.02  # verify's step for every run [s]


@dataclass(frozen=True)
class RobustCandidate:
    """One plan the query could give: where it came from, its verification at the observed state, and its
    success estimate at the requested error (None: infeasible as observed, not drawn)."""

    label: str
    source: QuerySource
    plan: GraspPlan
    report: VerifyReport
    estimate: SuccessEstimate | None
    not_judged: str = ""  # why a candidate feasible as observed was not drawn (the budget), "" when it was


@dataclass(frozen=True)
class RobustChoice:
    """The chosen candidate (the plain answer when none is feasible at the observed state) and every one judged."""

    chosen: RobustCandidate
    candidates: list[RobustCandidate]
    corners: list[int]
    elapsed_s: float
    refine_failure: str = ""  # why a refine the budget allowed gave no plan ("" when none failed)


def candidate_lines(choice: RobustChoice) -> list[str]:
    """One line per judged candidate: verdict at the observed state and success estimate; the chosen one marked."""
    lines = []
    for c in choice.candidates:
        mark = "→" if c is choice.chosen else " "
        if c.not_judged:
            lines.append(f"{mark} {c.label:<14} feasible at the observed state, not judged: {c.not_judged}")
            continue
        if c.estimate is None:
            why = "; ".join(c.report.violations)[:80]
            lines.append(f"{mark} {c.label:<14} infeasible at the observed state ({why})")
            continue
        e = c.estimate
        lines.append(f"{mark} {c.label:<14} success {e.successes}/{e.runs} = {e.probability:.3f}, "
                     f"Wilson 95 % [{e.low:.3f}, {e.high:.3f}]")
    if choice.refine_failure:
        lines.append(f"  refined        no plan: {choice.refine_failure}")
    return lines


def robust_query(tq: TableQuery, state: TargetState, request: RobustRequest, budget_s: float,
                 refine: bool = True) -> RobustChoice:
    """The module docstring's choice for ``state``: the plain query first, within ``budget_s`` [s] less its expected
    judgement, then the other candidates while what is left covers the dearest judgement so far; ``refine``
    False leaves out the warm-started solve (the table's own candidates only)."""
    t0 = time.perf_counter()
    register_planner(str(tq.scenario_path), tq.planner)
    states = perturbed_states(state, request.model, standard_draws(request.samples, request.seed), 1.0)
    cost_s = request.samples * JUDGE_RUN_S / max(request.jobs, 1)  # a judgement's expected cost, then its dearest

    def time_left() -> float:
        return budget_s - (time.perf_counter() - t0) - FINISH_RESERVE_S

    plain = tq.query(state, budget_s=max(budget_s - FINISH_RESERVE_S - cost_s, 1.0))
    c0 = time.perf_counter()
    judged = [_judge(tq, states, f"plain {plain.source}", plain.source, plain.plan, plain.report, request,
                     time_left() >= cost_s)]
    if judged[0].estimate is not None:
        cost_s = max(cost_s, time.perf_counter() - c0)
    for c in tq.corner_candidates(state):
        if time_left() < cost_s:
            break
        if tq.beyond_carry(state, [c.corner]) is not None:
            continue  # a plan from this far does not verify (lut.query.carry): not worth its simulation
        c0 = time.perf_counter()
        made = tq.verified(state, c.parameters, [c.corner], QuerySource.NEAREST, {})
        if made is not None:  # else it would start before the answer
            judged.append(_judge(tq, states, f"corner {c.corner}", QuerySource.NEAREST, *made[:2], request))
        cost_s = max(cost_s, time.perf_counter() - c0)
    found, failure = tq.interpolate(state), ""
    if refine and found is not None and plain.source not in (QuerySource.REFINED, QuerySource.SOLVED_COLD) \
            and time_left() - cost_s >= MIN_REFINE_S:
        refined = tq.refine(state, found.parameters, time_left() - cost_s)
        if refined.status in (PointStatus.FEASIBLE, PointStatus.INFEASIBLE) and refined.parameters is not None:
            judged.append(_judge(tq, states, "refined", QuerySource.REFINED,
                                 *tq.simulate_and_verify(state, refined.parameters, {}), request))
        else:
            failure = refined.failure_reason or refined.status.value
    return RobustChoice(most_robust(judged), judged, plain.corners_used, time.perf_counter() - t0, failure)


def most_robust(judged: list[RobustCandidate]) -> RobustCandidate:
    """The judged candidate with the highest success probability, the earliest of a tie (the plain answer, first,
    is replaced only by a strictly more robust plan); the plain answer when none was judged."""
    feasible = [c for c in judged if c.estimate is not None]
    return max(feasible, key=lambda c: c.estimate.probability if c.estimate else -1.0, default=judged[0])


def _judge(tq: TableQuery, states: list[TargetState], label: str, source: QuerySource, plan: GraspPlan,
           report: VerifyReport, request: RobustRequest, in_time: bool = True) -> RobustCandidate:
    """One candidate, verified at the observed state, executed against ``states`` if it is feasible there and the
    judgement fits in the time left (``in_time``)."""
    if not report.feasible:
        return RobustCandidate(label, source, plan, report, None)
    if not in_time:
        return RobustCandidate(label, source, plan, report, None, "the budget left no time to draw its runs")
    outcomes, _ = run_states(str(tq.scenario_path), plan.parameters, states, request.step_s, request.jobs)
    return RobustCandidate(label, source, plan, report, success_estimate(outcomes))
