"""Which failures of a table's plan a warm re-solve of its stabilization alone can repair (issue 21).

A table's plan re-simulated at a state between grid points reaches its grasp through the tracking IK, which closes
the loop on the true grasp frame; what cannot adapt is the stabilization spline, applied unchanged from a grasp
state that differs from its corners'. When every failed check lies in the stabilization (from the grasp on), the
stabilization NLP solved warm from the table's spline at the grasp reached repairs it in a few iterations, in
process: no approach NLP, no child process. The approach, and with it the plan's cost terms (Eq. 14-16), stay the
table's.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from planner.deadline import NO_DEADLINE, Deadline
from planner.nlp.feasibility_stop import StallRule
from planner.verify.before_grasp import judged_before_grasp
from planner.verify.verifier import VerifyReport, verify

if TYPE_CHECKING:
    from planner.plan import GraspPlan, Planner

# IPOPT iterations a repair gets: the repairs that succeeded took 0-5 (flat_spin_I_energy's off-grid queries), the ones
# that failed ran to 116-120 (24-32 s each; the demo's query spent 45 s on three of them, 18 s with this cap)
REPAIR_ITERATIONS = 15
# a repair whose violation has not halved over its last five iterations rarely succeeds within its iterations: given
# up, it frees the time for the next plan (README, "The measurements behind the planner's constants")
REPAIR_STALL = StallRule(after=5, over=5, ratio=0.5)


def stabilization_only(report: VerifyReport) -> bool:
    """True when ``report`` failed and every failed check is a stabilization one whose worst value lies at or after
    the grasp (a check failing before it as well is caught when the repaired plan is verified)."""
    failed = [c for c in report.checks.values() if not c.passed]
    return bool(failed) and all(c.t_s is not None and not judged_before_grasp(c, report.t_grasp_s) for c in failed)


# the checks of the grasp wrench: a braking too harsh for the grasp it starts from
BRAKING = frozenset({"grasp_torque", "grasp_force"})


def single_cause(report: VerifyReport) -> bool:
    """True when ``report`` failed only from the grasp on and from one cause: the grasp wrench alone (the arm's
    motion within its limits and clear), or the arm's path alone (a joint limit, a collision) with the wrench within
    its limits. A repair must then change one side of the braking and mostly succeeds; one that must make the
    braking both gentler and take another path mostly fails, at the full :data:`REPAIR_ITERATIONS` (docs/table.md,
    Query)."""
    failed = {c.name for c in report.checks.values() if not c.passed}
    return stabilization_only(report) and (failed <= BRAKING or not failed & BRAKING)


def repaired_plan(planner: Planner, made: GraspPlan, report: VerifyReport,
                  deadline: Deadline = NO_DEADLINE) -> tuple[GraspPlan, VerifyReport] | None:
    """``made`` (a plan ``planner`` simulated from given parameters) with its stabilization re-solved warm at its grasp
    (within :data:`REPAIR_ITERATIONS` iterations, given up once stalled by :data:`REPAIR_STALL`, ended at
    ``deadline``; its approach and tracking reused), when ``report`` (its verification) failed only from the grasp on
    and the repaired plan verifies feasible: ``(plan, its report)``; else None."""
    if not stabilization_only(report):
        return None
    plan = planner.restabilized(made, REPAIR_ITERATIONS, deadline, REPAIR_STALL)
    if not plan.stabilization.success:
        return None
    repaired = verify(plan)
    return (plan, repaired) if repaired.feasible else None
