"""One grasp the approach reached, ready to brake: its approach, tracking and compound state at the grasp, and
whether its approach holds (a grasp verify would refuse whatever its braking is not braked while another remains)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.deadline import NO_DEADLINE, Deadline
from planner.model.freefloating import FreeFloatingModel
from planner.model.target import TargetMotion, TargetState
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.feasibility_stop import StallRule
from planner.nlp.outcome import SolveOutcome
from planner.phases.approach import ApproachProblem, ApproachSolution
from planner.phases.approach_clearance import ApproachClearance
from planner.phases.stabilization import GraspState, StabilizationProblem, StabilizationSolution, smooth_stop_params
from planner.phases.stabilization_solve import solve_stabilization
from planner.phases.tracking import TrackingResult
from planner.plan_samples import PhaseSamples
from planner.verify.before_grasp import failed_before_grasp
from planner.verify.verifiable import VerifiablePlan
from planner.verify.verifier import verify

Array = NDArray[np.float64]


class PhasePlanner(Protocol):
    """What the search needs of :class:`planner.plan.Planner`."""

    scenario: Scenario
    approach: ApproachProblem
    stabilization_spline: UniformCubicBSpline

    @property
    def stabilization_problem(self) -> StabilizationProblem: ...

    @property
    def approach_clearance(self) -> ApproachClearance: ...

    def approach_and_tracking(self, app: ApproachSolution,
                              motion: TargetMotion) -> tuple[PhaseSamples, TrackingResult]: ...

    def candidate_from(self, app: ApproachSolution, samples: PhaseSamples, tr: TrackingResult,
                       motion: TargetMotion) -> GraspCandidate: ...

    def assemble(self, state: TargetState, c: GraspCandidate, stab: StabilizationSolution,
                 timings: dict[str, float], notes: list[str]) -> VerifiablePlan: ...


@dataclass
class GraspCandidate:
    """One grasp the approach reached: its approach, tracking and grasp state, ready to stabilize."""

    planner: PhasePlanner
    app: ApproachSolution
    approach_samples: PhaseSamples
    tracking: TrackingResult
    grasp: GraspState
    T_body_grasp_used: Array  # (4, 4)
    compound: FreeFloatingModel  # the compound chaser + target of this grasp
    # why the approach does not hold ("" when it does): verify refuses such a grasp whatever its braking
    unheld_because: str = ""

    @property
    def approach_holds(self) -> bool:
        """False when the approach failed, or its tracking asks for more than the tolerated joint rates (or dips
        below its clearance between via points) and the re-solve did not mend it, or the tracking IK's arm dips below
        its clearance."""
        return not self.unheld_because

    @property
    def grasp_time_s(self) -> float:
        """Grasp instant [s since the observation]."""
        ph = self.planner.scenario.phases
        return self.app.start_delay_s + ph.approach_s + ph.tracking_s

    def smooth_stop_params(self) -> Array:
        """The stabilization parameters of the smooth stop from this grasp (a cold solve's start), without an NLP."""
        return smooth_stop_params(self.planner.stabilization_spline, self.planner.scenario.robot, self.grasp)

    def unbraked(self, status: SolveOutcome) -> StabilizationSolution:
        """The smooth stop from this grasp as its stabilization, unsolved (``success`` False, ``status``)."""
        return replace(StabilizationSolution.given(self.smooth_stop_params()), success=False, status=status)

    def refused_before_braking(self, state: TargetState) -> list[str]:
        """What verify refuses in this grasp's plan (observed ``state``) before the grasp, one line a check (empty:
        nothing): judged with the unsolved smooth stop, since no braking changes it
        (:mod:`planner.verify.before_grasp`)."""
        plan = self.planner.assemble(state, self, self.unbraked(SolveOutcome.GIVEN), {}, [])
        return [f"{c.name} {c.value:.3g} {c.unit} against {c.limit:.3g}" for c in failed_before_grasp(verify(plan))]

    @property
    def problem(self) -> StabilizationProblem:
        """The scenario's stabilization NLP (built on first use, kept by the planner)."""
        return self.planner.stabilization_problem

    def stabilize(self, warm_params: Array | None, max_iterations: int | None, screen_iterations: int | None = None,
                  deadline: Deadline = NO_DEADLINE, stall: StallRule | None = None) -> StabilizationSolution:
        """The stabilization from this grasp, within ``max_iterations`` (None: the scenario's limit only),
        screened by its coarse NLP within ``screen_iterations`` (None: no screen), ended at ``deadline`` (and, warm,
        once it has stalled by ``stall``)."""
        return solve_stabilization(self.problem, self.grasp, warm_params, max_iterations, screen_iterations, deadline,
                                   stall)


def accumulated(new: ApproachSolution, old: ApproachSolution) -> ApproachSolution:
    """``new``, with solve time and iterations accumulated over both solves (a warm re-solve keeps the
    scanned guess ``old`` descends from)."""
    return replace(new, solve_time_s=new.solve_time_s + old.solve_time_s, iterations=new.iterations + old.iterations,
                   start_guess=new.start_guess if new.start_guess >= 0 else old.start_guess)
