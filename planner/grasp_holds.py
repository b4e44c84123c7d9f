"""Whether a grasp's approach and tracking hold before any braking: what the planner's own samples show verify would
refuse (a tracking that misses the grasp, a clearance or a joint rate broken between the approach's via points)."""

from __future__ import annotations

from planner.grasp_candidate import PhasePlanner
from planner.model.target import TargetMotion
from planner.phases.approach import ApproachSolution
from planner.phases.approach_rates import rate_peaks
from planner.phases.tracking import TrackingResult
from planner.phases.tracking_clearance import tracking_dip
from planner.plan_samples import PhaseSamples
from planner.verify.checks import (
    GRASP_ANGULAR_VELOCITY_TOL_RAD_S,
    GRASP_ORIENTATION_TOL_RAD,
    GRASP_POSITION_TOL_M,
    GRASP_VELOCITY_TOL_M_S,
)

# the IK's rate cap absorbs a demand up to this × the limit (capped, the feedback still meets the grasp far
# inside verify's thresholds); beyond it the lag grows and the approach is re-solved instead
RATE_DEMAND_TOLERATED = 1.25
# a tracking still asking for more after its re-solve holds if, capped, it met the grasp within this fraction of
# verify's grasp tolerances (scenario II tumbles at 1.34-1.69× met it within 0.02-0.39 of them)
GRASP_MET_FRACTION = 0.5


def met_grasp(tr: TrackingResult) -> bool:
    """True when the tracking ``tr`` met the grasp within :data:`GRASP_MET_FRACTION` of verify's grasp tolerances
    (position, orientation, relative velocity and angular velocity at the grasp instant)."""
    errors = (tr.position_error_m, tr.orientation_error_rad, tr.relative_velocity_m_s,
              tr.relative_angular_velocity_rad_s)
    tolerances = (GRASP_POSITION_TOL_M, GRASP_ORIENTATION_TOL_RAD, GRASP_VELOCITY_TOL_M_S,
                  GRASP_ANGULAR_VELOCITY_TOL_RAD_S)
    return all(e <= GRASP_MET_FRACTION * tol for e, tol in zip(errors, tolerances, strict=True))


def why_unheld(planner: PhasePlanner, motion: TargetMotion, app: ApproachSolution, samples: PhaseSamples,
               tr: TrackingResult, mended: bool, checked: bool) -> str:
    """Why the grasp ``app`` (sampled densely as ``samples``) and its tracking ``tr`` reach does not hold, "" when it
    does; ``mended``: False when a re-solve failed and the first approach was kept; ``checked``: True when ``app``'s
    clearance and joint rates were read between its via points and held (else they are read here: the rounds of
    re-solves can end on an approach re-solved for its tracking's rates, a scenario II flat spin's 3 cm into the
    target)."""
    if not app.success:
        return f"its approach failed ({app.status})"
    over = tr.peak_rate_demand > RATE_DEMAND_TOLERATED
    if over and not met_grasp(tr):
        return (f"its tracking asks {tr.peak_rate_demand:.3g}× a joint's rate limit after its re-solve and, "
                f"capped, misses the grasp by {tr.position_error_m:.2g} m, {tr.orientation_error_rad:.2g} rad, "
                f"{tr.relative_velocity_m_s:.2g} m/s, {tr.relative_angular_velocity_rad_s:.2g} rad/s")
    peaks = [] if checked else rate_peaks(planner.approach, samples, above=1.0)
    if peaks:
        p = peaks[0]
        return (f"its approach asks {p.ratio:.3f}× joint {p.joint + 1}'s rate limit between via points "
                f"(t = {app.start_delay_s + p.t_s:.2f} s)" + ("" if mended else " after its re-solve"))
    dips = [] if checked else planner.approach_clearance.raised_bounds(app, samples, motion)[1]
    if dips and dips[0].distance_m < dips[0].clearance_m:  # the deepest first; one within the re-solves' 1 mm holds
        return (f"its approach dips below its clearance between via points ({dips[0].pair} {dips[0].distance_m:.4f} m, "
                f"clearance {dips[0].clearance_m:.3g} m)" + ("" if mended else " after its re-solve"))
    dip = tracking_dip(planner.approach_clearance, tr, motion)
    if dip is not None:
        return (f"its tracking IK's arm dips below its clearance ({dip.pair} {dip.distance_m:.4f} m, clearance "
                f"{dip.clearance_m:.3g} m, {dip.t_s:.2f} s into the tracking at t = {tr.t[0] + dip.t_s:.2f} s)")
    return ""
