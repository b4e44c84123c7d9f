"""Which failed checks of a verified plan no braking can change: those that judge what precedes the grasp.

The samples up to the grasp (the approach, the tracking, the grasp instant itself, whose rates verify takes by
one-sided differences inside the tracking) do not depend on the stabilization spline, so a check failed there stays
failed whatever the braking. A query repairs only plans that fail from the grasp on; a plan's grasp search brakes no
grasp that verify already refuses before it.
"""

from __future__ import annotations

from planner.verify.checks import CheckResult
from planner.verify.kinematics import TIME_TOL_S
from planner.verify.verifier import VerifyReport

# checks that judge the approach, the tracking or the grasp itself, wherever their worst value lies
BEFORE_THE_GRASP = frozenset({"grasp_position", "grasp_orientation", "grasp_velocity", "grasp_angular_velocity",
                              "momentum_chaser", "join_velocity_approach_tracking", "joint_rate_consistency"})


def judged_before_grasp(check: CheckResult, t_grasp_s: float) -> bool:
    """True when ``check`` judges what precedes the grasp instant ``t_grasp_s`` [s since the observation]: by its
    name (:data:`BEFORE_THE_GRASP`), or its worst value lies before that instant."""
    return check.name in BEFORE_THE_GRASP or (check.t_s is not None and check.t_s < t_grasp_s - TIME_TOL_S)


def failed_before_grasp(report: VerifyReport) -> list[CheckResult]:
    """The failed checks of ``report`` that no braking can change (:func:`judged_before_grasp`), in report order."""
    return [c for c in report.checks.values() if not c.passed and judged_before_grasp(c, report.t_grasp_s)]
