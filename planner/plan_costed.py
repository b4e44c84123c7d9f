"""A costed plan (paper Eq. 14-16): the costed approach's own optimum where it can be braked, else a feasible grasp
first, then its approach cost lowered in trust-region steps that each keep the whole plan feasible.

The approach NLP with a cost, solved on its own, optimises the approach alone: in scenario II its optimum is a grasp
from which no braking within ±10 N·m exists, and the stabilization NLP can only fail there. So a costed plan first
solves the costed approach as it stands and keeps that grasp if it can be tracked and braked (scenario I: no
feasibility plan is needed); under a grasp-wrench limit it does not try (scenario II), and else the feasibility plan
finds a stabilized grasp. Then it lowers the approach cost step by step from the grasp kept: each step re-solves the
costed approach warm from the current grasp with the meeting time kept and θ_b(0) inside a box of radius r around the
current one, tracks, and re-solves the stabilization warm from the current spline; the step is kept only if that
stabilization succeeds. The full step
(r = ∞) is tried first, except under a grasp-wrench limit; then r starts at :data:`FIRST_RADIUS_M`, doubles after a
kept step and halves after a refused one. The plan is feasible as soon as its first grasp is braked, and its cost
only falls while steps are kept and time remains."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.deadline import START_LEAD_S, Deadline
from planner.grasp_candidate import GraspCandidate, PhasePlanner
from planner.grasp_holds import RATE_DEMAND_TOLERATED
from planner.model.target import TargetMotion, TargetState
from planner.nlp.feasibility_stop import StallRule
from planner.phases.approach_guess import ScanOnDemand
from planner.phases.approach_solve import (
    COLD_START_ITERATIONS,
    approach_cost,
    solve_approach,
    solve_approach_near,
)
from planner.phases.stabilization import StabilizationSolution
from planner.plan_grasps import (
    SCREEN_BUDGET,
    STABILIZATION_BUDGET,
    GraspSearch,
    untightened_speed_scale,
)
from planner.plan_parameters import PlanParameters

FIRST_RADIUS_M = 0.02  # scenario II's default grasp: a 0.02 m box kept the braking feasible, 0.05 m did not
MIN_RADIUS_M = 0.005  # below this a step moves the base by less than the NLPs' constraint back-off
MAX_STEPS = 8  # trust-region steps after the full one (if tried): each is an approach and a stabilization solve
STEP_APPROACH_ITERATIONS = 100  # the full step with the meeting time kept took 52 (scenario II)
STEP_STABILIZATION_ITERATIONS = 30  # steps that kept the braking feasible re-solved it in 8-14
# a step's braking whose violation has not halved over its last 5 iterations after 15 is given up: of 45 such solves
# traced (seeded scenario II flat spins), the 18 that succeeded took at most 15 and every one of the 27 that failed
# ran to its 30 (README, "The measurements behind the planner's constants")
STEP_STALL = StallRule(after=15, over=5, ratio=0.5)
RELATIVE_GAIN_MIN = 1e-4  # a step must lower the cost by this fraction of max(|cost|, 1)
# the costed approach's own optimum gets this many iterations, its base-pinned start included: scenario I flat spins
# needed 60 (11 pinned + 49 free) and lost their optimum when cut there
COSTED_APPROACH_ITERATIONS = COLD_START_ITERATIONS
# the feasibility stage's re-solves of an approach with tightened tracking rates (or raised clearances) get this many
# IPOPT iterations: at scenario I flat spins they ran 496-759 (68-99 s of a 100 s budget) where the costed approach's
# own optimum needed no tightening and was braked in seconds (docs/measurements.md, "Optimal tables")
FEASIBILITY_RESOLVE_ITERATIONS = COLD_START_ITERATIONS
DIRECT_SHARE = 0.5  # of a bounded budget, for the costed approach's own optimum before any feasibility plan
# a live plan's costed optimum ends this long after the observation at the latest [s]: where it is braked (scenario
# I's default state) it took 9-10 s in all; where not (scenario II's default state) its approach ran its whole share
# (6-51 s) and the meeting times the feasibility plan can reach (16-40 s) had passed
LIVE_DIRECT_S = 20.0


@dataclass
class CostDescent:
    """A costed plan's grasp and stabilization as the stages left them, the approach cost at the feasibility plan's
    grasp and now, and what the stages did (steps, phase times [s], notes)."""

    candidate: GraspCandidate
    stabilization: StabilizationSolution
    timings_s: dict[str, float]  # "approach_s", "stabilization_s": every stage's solves [s]
    notes: list[str]
    cost_start: float = float("nan")
    cost_end: float = float("nan")
    steps_kept: int = 0
    steps_refused: int = 0
    first_grasp: str = "the feasibility plan's grasp"  # where the descent started

    @property
    def stabilized(self) -> bool:
        """True when the current grasp has an approach and a stabilization that succeeded."""
        return self.candidate.app.success and self.stabilization.success

    def keep(self, candidate: GraspCandidate, stab: StabilizationSolution, cost: float) -> None:
        """A cheaper grasp whose stabilization succeeded becomes the current one."""
        self.candidate, self.stabilization, self.cost_end = candidate, stab, cost

    def summary(self) -> str:
        """One line for the plan's notes."""
        return (f"costed plan: approach cost {self.cost_start:.6g} at {self.first_grasp}, "
                f"{self.cost_end:.6g} in the end ({self.steps_kept} trust-region steps kept, {self.steps_refused} "
                "refused; a step keeps the meeting time and is kept only if the stabilization stays feasible)")


def plan_costed(planner: PhasePlanner, feasibility: Callable[[], PhasePlanner], state: TargetState,
                warm: PlanParameters | None, scan: ScanOnDemand, motion: TargetMotion,
                deadline: Deadline, grasp_by: Deadline | None = None) -> CostDescent:
    """The grasp of ``planner``'s costed scenario for ``state`` (module docstring): the costed approach's own
    optimum (not under a grasp-wrench limit: :func:`_wrench_limited`), kept if it can be braked; else the planner
    ``feasibility()`` gives (the same scenario without approach costs, called only then) finds a stabilized grasp, warm
    from ``warm`` when given; both by ``grasp_by`` (default ``deadline``); then the descent from the grasp kept, until
    ``deadline``."""
    grasp_by = deadline if grasp_by is None else grasp_by
    timings_s = {"approach_s": 0.0, "stabilization_s": 0.0}
    limited = _wrench_limited(planner)
    out = None if limited else _direct_attempt(planner, state, warm, scan, motion, _direct_deadline(grasp_by),
                                               timings_s)
    scale = untightened_speed_scale()
    if out is None:
        search = GraspSearch(feasibility(), state, warm, scan, motion, grasp_by, FEASIBILITY_RESOLVE_ITERATIONS)
        candidate, stab = search.run()
        found = search.timings_s()
        why = ("is not tried under the grasp-wrench limit (it lies outside the grasps that can be braked)" if limited
               else "could not be braked (or none converged with the base pinned at its guess, or it was not solved "
                    "in its share of the budget)")
        out = CostDescent(candidate, stab, {k: timings_s[k] + found[k] for k in timings_s},
                          [f"costed plan: the costed approach's own optimum {why}: the feasibility plan's grasp first",
                           *search.notes])
        if not out.stabilized:
            return out
        out.cost_start = out.cost_end = approach_cost(planner.approach, state, candidate.app)
        scale = search.tracking_speed_scale
    _descend(planner, state, motion, out, scale, deadline)
    out.notes.append(out.summary())
    return out


def _direct_deadline(deadline: Deadline) -> Deadline:
    """The costed approach's own optimum gets :data:`DIRECT_SHARE` of what is left of a bounded budget, so that the
    feasibility plan that follows where it cannot be braked keeps the rest; a live plan's ends no later than
    :data:`LIVE_DIRECT_S` after the observation, so that the feasibility plan can still meet in time."""
    if not deadline.bounded:
        return deadline
    share = deadline.earlier((1.0 - DIRECT_SHARE) * max(deadline.remaining_s(), 0.0))
    if deadline.observed_at_s is None or deadline.observed_at_s + LIVE_DIRECT_S >= share.at_s:
        return share
    return Deadline(deadline.observed_at_s + LIVE_DIRECT_S, share.what, deadline.observed_at_s)


def _direct_attempt(planner: PhasePlanner, state: TargetState, warm: PlanParameters | None, scan: ScanOnDemand,
                    motion: TargetMotion, deadline: Deadline,
                    timings_s: dict[str, float]) -> CostDescent | None:
    """The costed approach NLP as it stands (its optimum over every meeting time, the paper's sequence) within
    :data:`COSTED_APPROACH_ITERATIONS`, its grasp tracked and braked within :data:`STABILIZATION_BUDGET` after
    the screen: the descent's start when that succeeds (scenario I), else None (scenario II: no ±10 N·m braking from
    there; a tracking that asks too much is not repaired here); its solve times are added to ``timings_s``."""
    if deadline.passed:
        return None
    app = solve_approach(planner.approach, state, None if warm is None else warm.approach, scan=scan,
                         max_iterations=COSTED_APPROACH_ITERATIONS, deadline=deadline)
    timings_s["approach_s"] += app.solve_time_s
    if not app.success or deadline.passed:
        return None
    candidate = planner.candidate_from(app, *planner.approach_and_tracking(app, motion), motion)
    if not _trackable(planner, candidate, motion):
        return None
    stab = candidate.stabilize(None if warm is None else warm.stabilization_params, STABILIZATION_BUDGET,
                               SCREEN_BUDGET, deadline)
    timings_s["stabilization_s"] += stab.solve_time_s
    if not stab.success:
        return None
    return CostDescent(candidate, stab, timings_s, ["costed plan: the costed approach's own optimum can be braked: it "
                                                    "is kept (no feasibility plan needed)"],
                       app.cost, app.cost, first_grasp="the costed approach's own optimum")


def _descend(planner: PhasePlanner, state: TargetState, motion: TargetMotion, out: CostDescent,
             tracking_speed_scale: NDArray[np.float64], deadline: Deadline) -> None:
    """Trust-region steps from the current grasp: the full step first (not under a grasp-wrench limit:
    :func:`_wrench_limited`), then from :data:`FIRST_RADIUS_M`, doubled after a kept step and halved after a refused
    one; stops after :data:`MAX_STEPS` and the full step, below :data:`MIN_RADIUS_M`, when a step gains nothing, or
    at ``deadline`` (for a live plan, no step starts later than
    :data:`~planner.deadline.START_LEAD_S` before its approach's start, which every step keeps: the step's approach
    solve ends then, its braking :data:`~planner.deadline.ANSWER_LEAD_S` before the start)."""
    in_time = deadline.in_time_for(out.candidate.app.start_delay_s)
    steps_by = deadline.in_time_for(out.candidate.app.start_delay_s, lead_s=START_LEAD_S)
    full_step = not _wrench_limited(planner)
    radius = np.inf if full_step else FIRST_RADIUS_M
    for _ in range(MAX_STEPS + full_step):
        if steps_by.passed or radius < MIN_RADIUS_M or _at_its_floor(planner, out.cost_end):
            break
        kept = _step(planner, state, motion, out, radius, tracking_speed_scale, in_time)
        if kept is None:  # converged: the cost does not fall inside this radius
            break
        if kept:
            radius = 2 * radius if np.isfinite(radius) else 0.0  # a full step kept is this meeting time's optimum
        else:
            radius = FIRST_RADIUS_M if not np.isfinite(radius) else radius / 2
    if steps_by.passed and steps_by is not deadline:
        out.notes.append(f"costed plan: the descent stopped {START_LEAD_S:g} s before the approach's start at "
                         f"{out.candidate.app.start_delay_s:.1f} s after the observation, so that the plan answers "
                         "before it")


def _wrench_limited(planner: PhasePlanner) -> bool:
    """True when the scenario limits the grasp wrench. Then the grasps that can be braked are a few centimetres of
    θ_b(0) wide (docs/measurements.md, "Optimal tables"), and the costed approach's own optimum, over every meeting time
    or at the descent's (its full step), lies decimetres away: in scenario II none was kept (the energy variant's
    base-pinned starts converged at none of the states traced, the safety variant's optimum was not kept at its default
    state, the full step was refused at 15 of 15), each attempt a solve for nothing (4-20 s); without a limit (scenario
    I) they are how the optimum is reached in one go."""
    limits = planner.scenario.limits
    return bool(np.isfinite(limits.grasp_torque_max_nm) or np.isfinite(limits.grasp_force_max_n))


def _at_its_floor(planner: PhasePlanner, cost: float) -> bool:
    """True when no step can lower ``cost`` by :data:`RELATIVE_GAIN_MIN`: Eq. 16 weighted alone is ≥ 0 (a scenario I
    optimum is ~1e-9 m²; four refused steps there cost a table point 60 s), the other terms have no floor."""
    c = planner.scenario.costs
    only_energy = c.approach_energy > 0 and not c.weights_arm_motion
    return only_energy and cost < RELATIVE_GAIN_MIN


def _step(planner: PhasePlanner, state: TargetState, motion: TargetMotion, out: CostDescent, radius_m: float,
          tracking_speed_scale: NDArray[np.float64], deadline: Deadline) -> bool | None:
    """One trust-region step: True if kept, False if refused (the approach failed, the tracking asked too much, or
    the stabilization failed), None if the approach gained nothing."""
    app = solve_approach_near(planner.approach, state, out.candidate.app, radius_m, tracking_speed_scale,
                              STEP_APPROACH_ITERATIONS, deadline)
    out.timings_s["approach_s"] += app.solve_time_s
    if app.success and app.cost > out.cost_end - RELATIVE_GAIN_MIN * max(abs(out.cost_end), 1.0):
        return None
    kept = False
    if app.success:
        candidate = planner.candidate_from(app, *planner.approach_and_tracking(app, motion), motion)
        if _trackable(planner, candidate, motion):
            stab = candidate.stabilize(out.stabilization.params, STEP_STABILIZATION_ITERATIONS, None, deadline,
                                       STEP_STALL)
            out.timings_s["stabilization_s"] += stab.solve_time_s
            kept = bool(stab.success)
            if kept:
                out.keep(candidate, stab, app.cost)
    out.steps_kept += kept
    out.steps_refused += not kept
    return kept


def _trackable(planner: PhasePlanner, candidate: GraspCandidate, motion: TargetMotion) -> bool:
    """True when ``candidate``'s tracking asks for no more than the tolerated joint rates and its approach keeps its
    joint-rate limits and its clearance between the via points (a costed step is refused otherwise, not repaired: the
    feasibility plan's grasp stays the answer). Manipulability and clearance costs drive the approach's rates onto
    their bound: the NLP holds them at its nodes (``ApproachProblem._rate_nodes``), this check at every sample."""
    if candidate.tracking.peak_rate_demand > RATE_DEMAND_TOLERATED:
        return False
    if np.any(np.abs(candidate.approach_samples.qd) > planner.scenario.robot.qd_max):
        return False
    _, dips = planner.approach_clearance.raised_bounds(candidate.app, candidate.approach_samples, motion)
    return not dips
