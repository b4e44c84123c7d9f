"""Re-plan on a newer estimate: the previous plan as the warm start, a plan continuous with the one the chaser
has started (it waits, arm at its start configuration, base at the previous plan's offset).

The new estimate is of the target's state at its own observation, ``since_s`` seconds after the previous
one, before the previous approach begins (``since_s`` < its start delay). The new plan's times count from the
new observation. First the previous plan itself, its start delay less ``since_s``, is re-simulated at the
new state and verified: if it is feasible it is the answer (the maneuver does not change at all). Otherwise
a solve warm-started from it, with the approach NLP's base offset θ_b(0) pinned at the previous plan's
(:mod:`lut.query.pinned_solve`), runs in a child process like a query's refine: its plan ends at the budget (less
the time to verify it there) and the process is killed at it; the plan is re-simulated and verified here, and
replaces the shifted one if it is feasible. With less than :data:`MIN_SOLVE_S` left no solve starts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from lut.query.pinned_solve import PINNED_SOLVER
from lut.solve.point_process import run_point
from lut.table.point_result import PointStatus
from planner.errors import LutgenError

if TYPE_CHECKING:
    from planner.config.scenario import Scenario
    from planner.model.target import TargetState
    from planner.plan import GraspPlan
    from planner.plan_parameters import PlanParameters
    from planner.verify.verifier import VerifyReport

FINISH_RESERVE_S = 5.0  # kept back from the budget to re-simulate, verify and export the new plan [s]
BASE_PIN_TOL_M = 1e-9  # the new base offset must be the previous one (pinned bounds) [m]
MIN_SOLVE_S = 5.0  # a re-solve with less time than this cannot finish a solve: not started [s]


@dataclass(frozen=True)
class Replan:
    """The new plan (times from the new observation), its verification, and how its schedule moved."""

    plan: GraspPlan
    report: VerifyReport
    start_shift_s: float  # new approach start − previous one, both on the previous observation's clock [s]
    solve_s: float
    source: str  # "previous plan" (shifted, unchanged) or "re-solved" (base offset pinned)
    solve_failure: str = ""  # why a solve that was needed gave no feasible plan
    solve_notes: tuple[str, ...] = ()  # what the re-solve noted (its grasps, re-solves, budget), when it answered


def replan(scenario: Scenario, previous: PlanParameters, state: TargetState, since_s: float,
           budget_s: float, observed_at_s: float | None = None) -> Replan:
    """The module docstring's re-plan of ``state`` (observed ``since_s`` [s] after the previous estimate, at
    ``observed_at_s``, a ``time.monotonic()`` instant: its re-solve's approach starts after its answer can come;
    None: now)."""
    from planner.plan import Planner
    from planner.verify.verifier import verify

    tau = previous.approach.start_delay_s
    if not (np.isfinite(since_s) and 0.0 <= since_s < tau):
        raise LutgenError(f"--since-s: the new estimate must come after the previous one and before its approach "
                          f"starts at {tau:.3f} s, got {since_s}")
    t0 = time.perf_counter()
    if budget_s - FINISH_RESERVE_S < MIN_SOLVE_S:
        raise LutgenError(f"--budget-s: a re-plan needs at least {FINISH_RESERVE_S + MIN_SOLVE_S:g} s, "
                          f"got {budget_s:g}")
    planner = Planner(scenario)
    shifted = planner.simulate(state, previous.with_start_delay(tau - since_s))
    shifted_report = verify(shifted)
    if shifted_report.feasible:
        return Replan(shifted, shifted_report, 0.0, time.perf_counter() - t0, "previous plan")
    room = budget_s - FINISH_RESERVE_S - (time.perf_counter() - t0)
    if room < MIN_SOLVE_S:
        return Replan(shifted, shifted_report, 0.0, time.perf_counter() - t0, "previous plan",
                      f"no time left to re-solve within --budget-s {budget_s:g} s")
    # as a query's refine: each NLP gets at most half the time, the plan ends before the kill with its best, verified
    solved = run_point(PINNED_SOLVER, str(scenario.source), -1, state, previous, -since_s, timeout_s=room,
                       max_wall_s=max(1.0, room / 2), plan_budget_s=room, timeout_name="--budget-s",
                       solver_kwargs={"observed_at_s": time.monotonic() if observed_at_s is None else observed_at_s})
    if solved.status not in (PointStatus.FEASIBLE, PointStatus.INFEASIBLE) or solved.parameters is None:
        return Replan(shifted, shifted_report, 0.0, time.perf_counter() - t0, "previous plan",
                      solved.failure_reason or solved.status.value)
    new = solved.parameters
    gap = float(np.abs(np.asarray(new.approach.base_offset_m) - np.asarray(previous.approach.base_offset_m)).max())
    if gap > BASE_PIN_TOL_M:  # the pinned bounds hold it: anything else is a broken solve, not a plan to fly
        raise LutgenError(f"the re-plan moved the base offset by {gap:.3g} m although it was pinned")
    plan = planner.simulate(state, new)
    plan.notes.extend(solved.notes)  # how the re-solve went (its grasps, re-solves, budget): printed and kept
    report = verify(plan)
    if not report.feasible:
        return Replan(shifted, shifted_report, 0.0, time.perf_counter() - t0, "previous plan",
                      "the re-solved plan is infeasible too: " + "; ".join(report.violations)[:200])
    return Replan(plan, report, since_s + new.approach.start_delay_s - tau, time.perf_counter() - t0, "re-solved",
                  solve_notes=solved.notes)
