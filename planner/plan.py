"""``plan_grasp``: the three phases chained into one grasp plan (paper §4; see docs/data-flow.md).

approach NLP → dense re-simulation of the approach → tracking IK → compound momentum at the grasp →
stabilization NLP → dense re-simulation of the stabilization. The approach NLP carries a proxy of the
tracking constraints (configurations at the tracking nodes); the IK caps its joint rates (a short lag the
pose feedback recovers), but if it asked for more than :data:`RATE_DEMAND_TOLERATED` × a limit, f, the
approach is re-solved with its tracking-rate bounds tightened by 1/f (warm-started), up to
:data:`TIGHTENING_ROUNDS` times. Whether the stabilization is feasible depends strongly on the grasp (its
configuration and joint rates), so a cold plan whose stabilization fails tries the grasps of the approach's
next scanned meeting times (:mod:`planner.plan_grasps`). Times are seconds since the observation.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.deadline import NO_DEADLINE, Deadline
from planner.grasp_candidate import GraspCandidate
from planner.model.freefloating import FreeFloatingModel
from planner.model.target import TargetMotion, TargetState
from planner.nlp.feasibility_stop import StallRule
from planner.out_of_reach import OutOfReach, ReachableOnlyTooEarly
from planner.phases.approach import ApproachProblem, ApproachSolution
from planner.phases.approach_clearance import ApproachClearance
from planner.phases.approach_guess import ScanOnDemand
from planner.phases.stabilization import (
    GraspState,
    StabilizationProblem,
    StabilizationSolution,
    stabilization_spline,
)
from planner.phases.tracking import TrackingController, TrackingResult
from planner.plan_costed import plan_costed
from planner.plan_grasps import (
    GRASP_GUESSES,
    RATE_DEMAND_TOLERATED,
    STABILIZATION_BUDGET,
    TIGHTENING_ROUNDS,
    GraspSearch,
    approach_retry_budget,
)
from planner.plan_parameters import PlanParameters
from planner.plan_samples import PhaseSamples, approach_samples, grasp_state, joined, stabilization_samples

Array = NDArray[np.float64]

__all__ = ["GRASP_GUESSES", "RATE_DEMAND_TOLERATED", "STABILIZATION_BUDGET", "TIGHTENING_ROUNDS", "GraspCandidate",
           "GraspPlan", "OutOfReach", "Planner", "ReachableOnlyTooEarly", "approach_retry_budget", "plan_grasp"]


class NoPlan(Exception):
    """No plan was made for a valid state (``str()`` says why: no time left to solve, or the solve itself gave
    none): the state is answered infeasible, and there is no trajectory to verify or export."""


@dataclass
class GraspPlan:
    """One planned grasp: decision parameters, dense trajectory, metrics, solver statistics (SI)."""

    scenario: Scenario
    target_state: TargetState
    approach: ApproachSolution
    tracking: TrackingResult
    stabilization: StabilizationSolution
    grasp: GraspState
    T_body_grasp_used: Array  # (4, 4) grasp frame in the target body frame, free-axis angle applied
    phases: dict[str, tuple[float, float]]  # phase name → (start, end) [s since the observation]
    t: Array  # (n,) dense samples [s since the observation], approach start to stabilization end
    q: Array  # (n, 7) [rad]
    qd: Array  # (n, 7) [rad/s]
    x_base: Array  # (n, 7) [p_world_base [m], quat_world_base]
    phase_index: Array  # (n,) 0 approach, 1 tracking, 2 stabilization
    timings_s: dict[str, float] = field(default_factory=dict)
    solver_ok: bool = True
    notes: list[str] = field(default_factory=list)
    # the grasp it was assembled from (approach, tracking, compound), so that its braking can be re-solved without
    # simulating the approach and tracking again (:meth:`Planner.restabilized`)
    candidate: GraspCandidate | None = field(default=None, repr=False, compare=False)

    @property
    def t_grasp(self) -> float:
        """Grasp instant [s since the observation]."""
        return self.phases["tracking"][1]

    @property
    def parameters(self) -> PlanParameters:
        """The decision parameters this plan is re-simulated from."""
        return PlanParameters(self.approach.parameters, self.stabilization.params)


class Planner:
    """The symbolic problems of one scenario, built once; :meth:`plan` solves one target state.

    It holds only what the scenario fixed: a plan's scan of meeting times and its tracking-rate scale live
    in that plan's :class:`~planner.plan_grasps.GraspSearch`.
    """

    def __init__(self, scenario: Scenario) -> None:
        t0 = time.perf_counter()
        self.scenario = scenario
        self.ff = FreeFloatingModel(scenario.robot, compile_rk4=True)
        self.approach = ApproachProblem(scenario, self.ff)
        self.tracking = TrackingController(scenario, self.ff)
        self._stabilization: StabilizationProblem | None = None
        self._clearance: ApproachClearance | None = None
        self._feasibility: Planner | None = None
        self.stabilization_spline = stabilization_spline(scenario)
        self.build_time_s = time.perf_counter() - t0

    @property
    def approach_clearance(self) -> ApproachClearance:
        """The approach's dense clearance check on the NLP's own engine (built on first use)."""
        if self._clearance is None:
            self._clearance = ApproachClearance(self.approach)
        return self._clearance

    @property
    def stabilization_problem(self) -> StabilizationProblem:
        """The scenario's stabilization NLP (every grasp geometry is a parameter of it), built on first use."""
        if self._stabilization is None:
            self._stabilization = StabilizationProblem(self.scenario)
        return self._stabilization

    def plan(self, state: TargetState, warm_start: PlanParameters | GraspPlan | None = None,
             deadline: Deadline = NO_DEADLINE, grasp_by: Deadline | None = None) -> GraspPlan:
        """Plan the grasp for the observed ``state``; ``warm_start`` seeds both NLPs.

        A cold plan whose scan of meeting times reaches none raises :class:`OutOfReach` at once (without a
        reachable time the approach NLP would only search from θ_in for minutes), and a live one whose every reachable
        meeting time, from every base offset tried, comes before its answer can raises
        :class:`ReachableOnlyTooEarly` (no approach was started). A cold plan whose
        stabilization fails from the first grasp tries the grasps the approach reaches from its next scanned
        guesses (:class:`~planner.plan_grasps.GraspSearch`). A warm plan keeps its grasp (a table's neighbours
        stay in one family of solutions). With approach costs (Eq. 14-16) the plan is the costed approach's own
        optimum where it can be braked, else that feasibility plan's grasp, its cost then lowered from there
        (:mod:`planner.plan_costed`). Past ``deadline`` no new solve starts and
        a running one ends: the plan is what was found by then (its notes say so; verify judges it). ``grasp_by``
        (default ``deadline``) is the instant by which a braked grasp must be found: a costed plan's descent may go
        on to ``deadline`` after it; a caller with a cold plan to follow a warm one gives the warm one a share.
        """
        t_start = time.perf_counter()
        warm = warm_start.parameters if isinstance(warm_start, GraspPlan) else warm_start
        scan = ScanOnDemand(self.scenario, self.approach.spline, state, GRASP_GUESSES)
        if warm is None and not scan.result.reachable:
            raise OutOfReach(scan.result, time.perf_counter() - t_start)
        if deadline.bounded and not deadline.passed:
            self._build_stabilization(cold=warm is None)
        grasp_by = deadline if grasp_by is None else grasp_by
        if self.scenario.costs.weights_approach:
            plan = self._plan_costed(state, warm, scan, deadline, grasp_by)
        else:
            search = GraspSearch(self, state, warm, scan, self.motion(state), grasp_by)
            candidate, stab = search.run()
            plan = self.assemble(state, candidate, stab, search.timings_s(), search.notes)
        plan.timings_s["total_s"] = time.perf_counter() - t_start
        return plan

    def _plan_costed(self, state: TargetState, warm: PlanParameters | None, scan: ScanOnDemand,
                     deadline: Deadline, grasp_by: Deadline) -> GraspPlan:
        """A plan with approach costs: the costed approach's own optimum if it can be braked, else the feasibility
        plan's grasp (warm from ``warm`` when given), found by ``grasp_by``, then its cost lowered from there until
        ``deadline`` (:mod:`planner.plan_costed`)."""
        # the feasibility planner is built only where the costed optimum cannot be braked (1.9 s of a cold plan)
        out = plan_costed(self, lambda: self.feasibility_planner, state, warm, scan, self.motion(state), deadline,
                          grasp_by)
        return self.assemble(state, out.candidate, out.stabilization, out.timings_s, out.notes)

    @property
    def feasibility_planner(self) -> Planner:
        """This scenario without its approach costs, sharing this planner's stabilization NLP: the first stage of
        a costed plan (built on first use)."""
        if self._feasibility is None:
            stabilization = self.stabilization_problem  # built before the copy, so both hold the one NLP
            feasibility = copy.copy(self)  # the models, tracking and stabilization do not depend on approach costs
            feasibility.scenario = replace(self.scenario, costs=self.scenario.costs.without_approach_terms())
            feasibility.approach = ApproachProblem(feasibility.scenario, self.ff)
            feasibility._stabilization, feasibility._feasibility, feasibility._clearance = stabilization, None, None
            self._feasibility = feasibility
        return self._feasibility

    def _build_stabilization(self, cold: bool) -> None:
        """Build the stabilization NLPs a plan will solve now, while its time is left: a build cannot be cut short
        at a deadline (a cold solve also uses the coarse NLP)."""
        problem = self.stabilization_problem
        if cold and problem.coarse_via_points > 0:
            problem.coarse_problem()

    def simulate(self, state: TargetState, given: PlanParameters, resolve_iterations: int | None = None,
                 deadline: Deadline = NO_DEADLINE, stall: StallRule | None = None) -> GraspPlan:
        """The plan that given parameters produce for ``state``, without solving (table queries).

        The approach parameters are used as they are; the tracking IK runs from where they end; the
        stabilization parameters are applied to Eq. 24 from the actual grasp state. ``verify`` decides.
        With ``resolve_iterations`` the stabilization is what the flight software would fly once grasped: its NLP
        solved warm from the given parameters at the actual grasp state within that many IPOPT iterations
        (:meth:`resolved_stabilization`), ended at ``deadline`` or once it has stalled by ``stall``; approach and
        tracking are the same as without.
        """
        t_start = time.perf_counter()
        app, motion = ApproachSolution.given(given.approach), self.motion(state)
        candidate = self.candidate_from(app, *self.approach_and_tracking(app, motion), motion)
        params = given.stabilization_params
        if params is None:
            params = candidate.smooth_stop_params()
        # given parameters need no NLP: a query that only simulates and verifies never builds one
        return self._braked(state, candidate, np.asarray(params, dtype=float), resolve_iterations, deadline, stall,
                            t_start)

    def restabilized(self, plan: GraspPlan, resolve_iterations: int, deadline: Deadline = NO_DEADLINE,
                     stall: StallRule | None = None) -> GraspPlan:
        """``simulate(plan.target_state, plan.parameters, resolve_iterations, deadline, stall)`` for a plan this planner
        assembled: the same plan, with its grasp's approach and tracking reused instead of simulated again."""
        if plan.candidate is None:
            raise ValueError("restabilized needs a plan a planner assembled (it has no grasp candidate)")
        return self._braked(plan.target_state, plan.candidate, plan.stabilization.params, resolve_iterations, deadline,
                            stall, time.perf_counter())

    def _braked(self, state: TargetState, candidate: GraspCandidate, params: Array, resolve_iterations: int | None,
                deadline: Deadline, stall: StallRule | None, t_start: float) -> GraspPlan:
        """The plan of ``candidate`` braked by the given spline ``params``, or by its NLP re-solved warm from them
        within ``resolve_iterations`` (:meth:`simulate`)."""
        stab, notes = StabilizationSolution.given(params), ["simulated from given parameters"]
        t_stab = time.perf_counter()
        if resolve_iterations is not None:
            stab, note = self.resolved_stabilization(candidate, stab.params, resolve_iterations, deadline, stall)
            notes.append(note)
        timings = {"approach_s": 0.0, "stabilization_s": time.perf_counter() - t_stab}
        plan = self.assemble(state, candidate, stab, timings, notes)
        plan.timings_s["total_s"] = time.perf_counter() - t_start
        return plan

    def resolved_stabilization(self, candidate: GraspCandidate, planned: Array, max_iterations: int,
                               deadline: Deadline = NO_DEADLINE,
                               stall: StallRule | None = None) -> tuple[StabilizationSolution, str]:
        """The stabilization NLP solved warm from ``planned`` at ``candidate``'s grasp within ``max_iterations`` (ended
        at ``deadline``, or once it has stalled by ``stall``), and
        a note: its answer when the solve succeeds, else the ``planned`` spline (the flight software flies what it
        has; such a solution keeps the failed solve's status and iterations, with ``success`` False)."""
        solved = candidate.stabilize(planned, max_iterations, deadline=deadline, stall=stall)
        if solved.success:
            return solved, f"stabilization re-solved warm at the grasp ({solved.iterations} iterations)"
        kept = replace(StabilizationSolution.given(planned), success=False, status=solved.status,
                       iterations=solved.iterations, solve_time_s=solved.solve_time_s)
        return kept, (f"the warm re-solve of the stabilization failed ({solved.status} after {solved.iterations} "
                      "iterations): the planned spline is flown")

    def motion(self, state: TargetState) -> TargetMotion:
        """The target's motion from the observed ``state`` to past the latest stabilization end."""
        ph = self.scenario.phases
        return self.scenario.target.motion(
            state, ph.max_start_delay_s + ph.approach_s + ph.tracking_s + ph.stabilization_s + 1.0)

    def approach_and_tracking(self, app: ApproachSolution,
                              motion: TargetMotion) -> tuple[PhaseSamples, TrackingResult]:
        """``app`` re-simulated densely, and the tracking IK from where it ends."""
        samples = approach_samples(self.scenario, self.approach.spline, self.ff, app)
        tr = self.tracking.simulate(motion, app.start_delay_s + self.scenario.phases.approach_s, samples.q[-1],
                                    samples.x_base[-1], app.q_tracking)
        return samples, tr

    def candidate_from(self, app: ApproachSolution, samples: PhaseSamples, tr: TrackingResult,
                       motion: TargetMotion) -> GraspCandidate:
        """The grasp ``app`` and its tracking ``tr`` lead to, with the compound's state there."""
        return GraspCandidate(self, app, samples, tr, *grasp_state(self.scenario, self.ff, tr, motion))

    def assemble(self, state: TargetState, c: GraspCandidate, stab: StabilizationSolution,
                 timings: dict[str, float], notes: list[str]) -> GraspPlan:
        """The plan of grasp ``c`` stabilized by ``stab``: the phases joined into one dense trajectory."""
        stab_samples = stabilization_samples(self.stabilization_spline, c.compound, stab, c.grasp)
        traj = joined(self.scenario, c.app.start_delay_s, c.approach_samples, c.tracking, stab_samples)
        return GraspPlan(self.scenario, state, c.app, c.tracking, stab, c.grasp, c.T_body_grasp_used, traj.phases,
                         traj.t, traj.q, traj.qd, traj.x_base, traj.phase_index, dict(timings),
                         c.app.success and stab.success, notes, c)


def plan_grasp(scenario: Scenario, target_state: TargetState, warm_start: GraspPlan | None = None) -> GraspPlan:
    """Plan one grasp (builds the scenario's problems; reuse a :class:`Planner` for many states)."""
    return Planner(scenario).plan(target_state, warm_start)
