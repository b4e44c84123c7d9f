"""The grasps one plan tries, in order: the approach's first, then those reached from its next scanned guesses.

Whether the stabilization is feasible depends strongly on the grasp (its configuration and joint rates). A
cold plan tries the grasp of the approach's first scanned guess, then those the approach reaches from its next
scanned guesses (other meeting times). While another grasp remains, each is screened: its coarse stabilization
NLP, then the full one from its answer, must be feasible within :data:`SCREEN_BUDGET` iterations each; a grasp
that passes has its stabilization (within :data:`STABILIZATION_BUDGET` iterations in all). A grasp screened
out is set aside, and the grasps set aside get that budgeted stabilization only when no later grasp
stabilized. When none succeeds, the first grasp's stabilization goes on without the budget from where its budgeted
solve ended (started again, IPOPT would retrace its iterates) until it succeeds or stalls, unless verify refuses that
grasp before it is braked (no braking can then make the plan feasible: the unsolved smooth stop is its answer). A warm
plan keeps its grasp.
Once the plan's deadline has passed (:mod:`planner.deadline`) no further grasp or solve is started: the last grasp
tried is the answer, and the plan's notes say so.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from planner.deadline import ANSWER_LEAD_S, NO_DEADLINE, START_LEAD_S, Deadline
from planner.grasp_candidate import GraspCandidate, PhasePlanner, accumulated
from planner.grasp_holds import RATE_DEMAND_TOLERATED, why_unheld
from planner.model.target import TargetMotion, TargetState
from planner.nlp.feasibility_stop import StallRule
from planner.nlp.outcome import SolveOutcome
from planner.out_of_reach import ReachableOnlyTooEarly
from planner.phases.approach import ApproachSolution
from planner.phases.approach_bounds import AS_SOLVED, ApproachBounds
from planner.phases.approach_guess import MIN_SEPARATION_S, ScanOnDemand
from planner.phases.approach_rates import lowered_rates
from planner.phases.approach_solve import COLD_START_ITERATIONS, TriedGrasp, solve_approach, solve_approach_from_base
from planner.phases.approach_start import BASE_OFFSET_GAP_M, other_base_offsets
from planner.phases.scan_in_time import scan_in_time
from planner.phases.stabilization import StabilizationSolution
from planner.phases.tracking import TrackingResult
from planner.phases.tracking_profile import TRACKING_NODES, node_segment
from planner.plan_parameters import ApproachParameters, PlanParameters
from planner.plan_samples import PhaseSamples

Array = NDArray[np.float64]

TIGHTENING_ROUNDS = 2
TIGHTENING_MARGIN = 0.97  # a tightened rate bound sits this far below what the IK asked for
# a cold plan whose stabilization fails tries the grasps reached from the approach's next scanned guesses, up
# to this many guesses in all: scenario II's grasps are mostly unbrakeable within ±10 N·m (screened out), and a
# later meeting time is the cheapest way to another grasp
GRASP_GUESSES = 5
# IPOPT iterations (coarse + full NLP) a stabilization gets while another grasp remains to be tried: successful
# cold solves take far fewer, failing ones several times more
STABILIZATION_BUDGET = 120
# while another grasp remains, a grasp whose coarse stabilization, or the full one from its answer, is not feasible
# within this many iterations is set aside for the next one (stabilizable grasps pass in a few; hopeless ones
# would spend the whole budget)
SCREEN_BUDGET = 20
# a retry's approach (from the next scanned guesses) gets this many times the first approach's iterations, at
# least APPROACH_RETRY_MIN: a neighbouring meeting time is about as hard to reach as the first
APPROACH_RETRY_FACTOR = 3
APPROACH_RETRY_MIN = 60
# a retry's approach keeps its meeting time within this of its guess's [s] and AVOID_GAP_S from the grasps already
# tried: free, the NLP drifted back to the grasp that had just failed (scenario II: grasps at 69.9, 70.0 and 68.9 s from
# guesses 6 s apart). The first approach stays free: boxed, scenario I's default state found no approach at all
MEETING_TIME_BOX_S = MIN_SEPARATION_S / 2
# scanned guesses an approach from another base offset starts from (within COLD_START_ITERATIONS), and how far from
# that offset θ_b(0) may end [m] per axis (half the grid's spacing or less: the next offset is another region)
BASE_OFFSET_STARTS = 1
BASE_OFFSET_BOX_M = 0.4
# the first grasp's last solve, resumed where its budgeted solve ended, is given up once its least violation has not
# halved over 50 iterations (from its 50th on; never below a 1e-3 violation, which a costed braking may leave a while)
RESUMED_STALL = StallRule(after=50, over=50, ratio=0.5, least_so_far=True, floor=1e-3)
# an approach solve that ended so made no NLP start: its scanned meeting times were none, or none in time
NO_START = frozenset({SolveOutcome.NO_GUESS_IN_TIME, SolveOutcome.NO_GUESS_LEFT, SolveOutcome.NO_PINNED_START})


def untightened_speed_scale() -> NDArray[np.float64]:
    """The scale of the approach's tracking-rate bounds, per tracking segment, before any is tightened: all 1."""
    return np.ones(len(TRACKING_NODES))


def approach_retry_budget(first_iterations: int) -> int:
    """IPOPT iterations for the approach solve of a retry, from the first approach's iteration count."""
    return max(APPROACH_RETRY_MIN, APPROACH_RETRY_FACTOR * first_iterations)


class GraspSearch:
    """One plan's search over grasps: its scan, tracking-rate scale, notes and phase times, for this plan only."""

    def __init__(self, planner: PhasePlanner, state: TargetState, warm: PlanParameters | None, scan: ScanOnDemand,
                 motion: TargetMotion, deadline: Deadline = NO_DEADLINE, resolve_iterations: int | None = None) -> None:
        """``resolve_iterations``: IPOPT iterations of each re-solve of an approach with tightened rates or raised
        clearances (None: the scenario's limit only)."""
        self.planner, self.state, self.warm, self.scan, self.motion = planner, state, warm, scan, motion
        self.deadline, self.resolve_iterations = deadline, resolve_iterations
        # of the approach's tracking-rate bounds, per tracking segment; tightened within this plan
        self.tracking_speed_scale = untightened_speed_scale()
        self.notes: list[str] = []
        self._base_offsets: list[Array] = []  # where the chaser may wait for the grasps still to try (cold plans)
        self._tried_offsets: list[Array] = []  # θ_b(0) of the grasps tried so far [m]
        self._next_guess = 0  # the scanned guess the next retry starts from (cold plans)
        self._approach_ends: list[SolveOutcome] = []  # how each approach solve of this search ended
        self._first_braked: StabilizationSolution | None = None  # the first grasp's last budgeted stabilization
        self.approach_s = 0.0  # NLP time, tracking-rate re-solves included [s]
        self.stabilization_s = 0.0  # the phase's wall time: NLP builds (if new) and solves [s]

    def timings_s(self) -> dict[str, float]:
        """The phases' solve times so far [s]."""
        return {"approach_s": self.approach_s, "stabilization_s": self.stabilization_s}

    def run(self) -> tuple[GraspCandidate, StabilizationSolution]:
        """The grasp the plan is made of and its stabilization, trying the grasps in order.

        While another grasp remains, a grasp is screened first (:data:`SCREEN_BUDGET`); the grasps screened out
        get their budgeted solve only when no grasp passed the screen and stabilized. Past the deadline the last
        grasp tried is the answer.
        """
        whole, t_start = self.scan, time.perf_counter()
        self.scan = scan_in_time(self.scan, self.deadline)  # a stage that came late (a costed plan's feasibility stage)
        app = self._solve_approach(self.warm.approach if self.warm is not None else None)
        first = self._candidate(app)
        self.approach_s += first.app.solve_time_s
        if self.warm is None:
            self._base_offsets = other_base_offsets(self.planner.scenario, first.app.base_offset_m)
        screened_out: list[GraspCandidate] = []
        last: tuple[GraspCandidate, StabilizationSolution] | None = None
        for candidate in self._grasps(first):
            more = self._another_grasp_remains()
            if more and not candidate.approach_holds:
                self._note_unheld(candidate)
                continue
            if not candidate.approach_holds and self._refused(candidate):
                if candidate is first:
                    return self._unbraked(first, whole, t_start)
                continue
            # budgeted while another grasp remains, or the first grasp remains to fall back to
            budget = STABILIZATION_BUDGET if more or candidate is not first else None
            last = self._braked(candidate, first, budget, SCREEN_BUDGET if more else None)
            if last[1].success or budget is None or self.deadline.passed:
                return self._answer(*last)
            if last[1].status == SolveOutcome.SCREENED_OUT:
                screened_out.append(candidate)
            self._note_failure(*last, ("trying the approach's next guess" if self._scanned_guess_remains()
                                       else "trying another grasp") if more else "")
        for candidate in screened_out:
            if self.deadline.passed:
                break
            last = self._braked(candidate, first, STABILIZATION_BUDGET)
            if last[1].success:
                return last
            self._note_failure(*last, "")
        if self.deadline.passed and last is not None:
            return self._answer(*last)
        if self._only_too_early() or self._refused(first):
            return self._unbraked(first, whole, t_start)
        return self._answer(first, self._resumed(first))

    def _braked(self, candidate: GraspCandidate, first: GraspCandidate, budget: int | None,
                screen: int | None = None) -> tuple[GraspCandidate, StabilizationSolution]:
        """``candidate`` with its stabilization (:meth:`_stabilize`), kept when ``candidate`` is ``first``: the last
        resort goes on from there (:meth:`_resumed`)."""
        stab = self._stabilize(candidate, budget, screen)
        if candidate is first:
            self._first_braked = stab
        return candidate, stab

    def _resumed(self, first: GraspCandidate) -> StabilizationSolution:
        """The first grasp's stabilization without the budget, once no other grasp stabilized: from where its budgeted
        solve ended (the full NLP, warm; from the start, the same IPOPT path would be solved twice), given up once
        stalled (:data:`RESUMED_STALL`); cold when it had no budgeted solve."""
        braked = self._first_braked
        resume = braked.params if braked is not None and braked.iterations > 0 else None
        self.notes.append("no other grasp stabilized within the budget: the first grasp's stabilization is solved "
                          + ("without the budget" if resume is None
                             else "on from where its budgeted solve ended, without the budget"))
        return self._stabilize(first, None, resume=resume)

    def _unbraked(self, first: GraspCandidate, whole: ScanOnDemand,
                  t_start: float) -> tuple[GraspCandidate, StabilizationSolution]:
        """The first grasp, not braked (verify refuses it before the grasp); but when no approach of this search made
        an NLP start, its meeting times all too early, :class:`~planner.out_of_reach.ReachableOnlyTooEarly` (``whole``:
        the scan of the whole window; ``t_start``: the search's start, ``time.perf_counter()``)."""
        if self._only_too_early():
            raise ReachableOnlyTooEarly(whole.result, self.deadline.earliest_start_s(), len(self._tried_offsets),
                                        time.perf_counter() - t_start)
        return first, first.unbraked(SolveOutcome.REFUSED_BEFORE_GRASP)

    def _answer(self, candidate: GraspCandidate, stab: StabilizationSolution) -> tuple[GraspCandidate,
                                                                                     StabilizationSolution]:
        """``(candidate, stab)`` as the plan's grasp, with a note when the deadline cut the search short."""
        if self.deadline.passed and not stab.success:
            self.notes.append(f"{self.deadline.what} ran out ({stab.status} after {stab.iterations} stabilization "
                              f"iterations): the plan is the grasp at t = {candidate.grasp_time_s:.1f} s as far as it "
                              "was solved")
        return candidate, stab

    def _note_failure(self, candidate: GraspCandidate, stab: StabilizationSolution, then: str) -> None:
        """Say in the plan's notes that the stabilization from ``candidate`` failed, and what comes next."""
        if stab.status == SolveOutcome.OUT_OF_TIME and not self.deadline.passed:  # its approach's start: noted
            return
        if stab.status == SolveOutcome.SCREENED_OUT:
            what = (f"was screened out (not feasible within {SCREEN_BUDGET} iterations of the coarse NLP, then of the "
                    f"full one: peak grasp torque {stab.peak_torque_nm:.3g} N·m, min distance "
                    f"{stab.min_distance_m:.3g} m after {stab.iterations})")
        else:
            what = f"failed within {stab.iterations} iterations ({stab.status})"
        self.notes.append(f"stabilization from the grasp at t = {candidate.grasp_time_s:.1f} s {what}"
                          + (f"; {then}" if then else ""))

    def _refused(self, candidate: GraspCandidate) -> bool:
        """True, and a note, when verify refuses ``candidate``'s plan before its grasp: no braking makes it feasible, so
        the plan's time is not spent braking it (before the deadline only: after it nothing is solved anyway)."""
        refused = [] if self.deadline.passed else candidate.refused_before_braking(self.state)
        if refused:
            self.notes.append(f"the grasp at t = {candidate.grasp_time_s:.1f} s is not braked: verify refuses its plan "
                              f"before the grasp, whatever the braking ({'; '.join(refused)})")
        return bool(refused)

    def _note_unheld(self, candidate: GraspCandidate) -> None:
        """Say in the plan's notes that ``candidate`` is not braked: its approach does not hold."""
        self.notes.append(f"the grasp at t = {candidate.grasp_time_s:.1f} s is not braked: {candidate.unheld_because}; "
                          "trying another grasp")

    def _another_grasp_remains(self) -> bool:
        """True when a cold plan has another grasp to try: a scanned guess left or another base offset."""
        return self._scanned_guess_remains() or self._next_base_offset(consume=False) is not None

    def _scanned_guess_remains(self) -> bool:
        """True when a cold plan's retries have a scanned guess left to start from."""
        return self.warm is None and 0 < self._next_guess < self._scanned_guesses()

    def _grasps(self, first: GraspCandidate) -> Iterator[GraspCandidate]:
        """``first``, then the grasps the approach reaches from its next scanned guesses while one remains (an approach
        that fails from one guess goes on from the guess after it), then those it reaches with the chaser waiting
        elsewhere (:func:`other_base_offsets`)."""
        tried = [TriedGrasp(first.app.start_delay_s, first.tracking.free_axis_angle_rad)]
        self._tried_offsets.append(first.app.base_offset_m)
        self._next_guess = first.app.start_guess + 1 if first.app.success else 0
        yield first
        while self._scanned_guess_remains() and not self.deadline.passed:
            skip = self._next_guess
            nxt = self._solve_approach(None, max_starts=GRASP_GUESSES, skip_guesses=skip,
                                       max_iterations=approach_retry_budget(first.app.iterations),
                                       meeting_time_box_s=MEETING_TIME_BOX_S, avoid=tuple(tried))
            self._next_guess = nxt.start_guess + 1 if nxt.start_guess >= skip else self._scanned_guesses()
            if not nxt.success:
                self.approach_s += nxt.solve_time_s
                self.notes.append(f"the approach from scanned guess {skip + 1} on failed ({self._failed(nxt)})")
                continue
            candidate = self._candidate(nxt)
            self.approach_s += candidate.app.solve_time_s
            self._tried_offsets.append(candidate.app.base_offset_m)
            tried.append(TriedGrasp(candidate.app.start_delay_s, candidate.tracking.free_axis_angle_rad))
            yield candidate
        yield from self._grasps_from_other_bases()

    def _scanned_guesses(self) -> int:
        """How many NLP starts the scan of this plan's state gave."""
        return len(self.scan.result.guesses)

    def _grasps_from_other_bases(self) -> Iterator[GraspCandidate]:
        """The grasps the approach reaches with θ_b(0) within :data:`BASE_OFFSET_BOX_M` of the next base offsets, each
        approach within :data:`COLD_START_ITERATIONS`."""
        while not self.deadline.passed and (offset := self._next_base_offset(consume=True)) is not None:
            app = solve_approach_from_base(self.planner.approach, self.state, offset, BASE_OFFSET_STARTS,
                                           self.tracking_speed_scale, self.deadline, COLD_START_ITERATIONS,
                                           BASE_OFFSET_BOX_M)
            self._approach_ends.append(app.status)
            self._tried_offsets.append(offset)
            where = f"θ_b(0) = ({offset[0]:+.2f}, {offset[1]:+.2f}) ± {BASE_OFFSET_BOX_M:g} m"
            if not app.success:
                self.approach_s += app.solve_time_s
                self.notes.append(f"the approach with the chaser waiting at {where} failed ({self._failed(app)})")
                continue
            self.notes.append(f"a grasp with the chaser waiting at {where}")
            candidate = self._candidate(app)
            self.approach_s += candidate.app.solve_time_s
            yield candidate

    def _next_base_offset(self, consume: bool) -> Array | None:
        """The next base offset still to try (removed from the list when ``consume``): offsets within
        :data:`BASE_OFFSET_GAP_M` of a grasp tried are dropped."""
        self._base_offsets = [b for b in self._base_offsets
                              if all(np.linalg.norm(b - t) >= BASE_OFFSET_GAP_M for t in self._tried_offsets)]
        if not self._base_offsets:
            return None
        return self._base_offsets.pop(0) if consume else self._base_offsets[0]

    def _solve_approach(self, warm: ApproachParameters | None, **options: object) -> ApproachSolution:
        """The approach NLP for this plan's state, scan, tracking-rate scale and deadline."""
        app = solve_approach(self.planner.approach, self.state, warm, tracking_speed_scale=self.tracking_speed_scale,
                             scan=self.scan, deadline=self.deadline, **options)
        self._approach_ends.append(app.status)
        return app

    def _only_too_early(self) -> bool:
        """True when no approach solve of this search made an NLP start and some had meeting times, all too early for
        this live plan (:class:`~planner.out_of_reach.ReachableOnlyTooEarly`)."""
        ends = self._approach_ends
        return bool(ends) and set(ends) <= NO_START and SolveOutcome.NO_GUESS_IN_TIME in ends

    def _failed(self, app: ApproachSolution) -> str:
        """Why ``app`` failed, for the notes: its status, and whether a live plan's solve stopped in time for its latest
        start before the plan's deadline (:func:`planner.phases.approach_solve.start_deadline`)."""
        cut = app.status == SolveOutcome.OUT_OF_TIME and not self.deadline.passed
        return f"{app.status}" + (f"; stopped {START_LEAD_S:g} s before the latest start its meeting time allows"
                                  if cut else "")

    def _stabilize(self, candidate: GraspCandidate, budget: int | None, screen: int | None = None,
                   resume: Array | None = None) -> StabilizationSolution:
        """The stabilization from ``candidate`` (this plan's warm start, iteration budget, screen and deadline; a
        live plan's ends :data:`~planner.deadline.ANSWER_LEAD_S` before ``candidate``'s approach starts: braked later,
        the plan would answer after its own start); ``resume``: the parameters an earlier solve of this grasp ended
        at, to go on from, given up once stalled (:data:`RESUMED_STALL`)."""
        in_time = self.deadline.in_time_for(candidate.app.start_delay_s)
        if in_time.passed:  # no NLP is built or solved: the smooth stop a cold solve starts from, unsolved
            result = candidate.unbraked(SolveOutcome.OUT_OF_TIME)
        else:
            t0 = time.perf_counter()
            warm = resume if resume is not None or self.warm is None else self.warm.stabilization_params
            result = candidate.stabilize(warm, budget, screen, in_time, None if resume is None else RESUMED_STALL)
            self.stabilization_s += time.perf_counter() - t0
        if result.status == SolveOutcome.OUT_OF_TIME and in_time is not self.deadline:
            self.notes.append(f"the braking from the grasp at t = {candidate.grasp_time_s:.1f} s stopped "
                              f"{ANSWER_LEAD_S:g} s before its approach's start ({candidate.app.start_delay_s:.1f} s "
                              "after the observation): braked later, the plan would answer after it")
        return result

    def _candidate(self, app: ApproachSolution) -> GraspCandidate:
        """Approach → tracking (re-solving the approach with tightened tracking rates if the IK asked for too much,
        or with raised collision bounds or lowered rate bounds where a distance dipped or a joint's rate peaked between
        via points) → the compound's state at the grasp."""
        tightened = AS_SOLVED  # this grasp's tighter via-point bounds, kept through its re-solves
        mended = True  # False once a re-solve failed: the first approach, still wanting, is kept
        checked = False  # True once the last approach was read between its via points and held there
        for round_ in range(TIGHTENING_ROUNDS + 1):
            samples, tr = self.planner.approach_and_tracking(app, self.motion)
            if round_ == TIGHTENING_ROUNDS or not app.success or self.deadline.passed:
                break
            if tr.peak_rate_demand > RATE_DEMAND_TOLERATED:
                self._tighten_rates(tr)
            else:
                more = self._between_via_points(app, samples, tightened)
                if more is None:
                    checked = True
                    break
                tightened = tightened.and_(more)
            # near the grasp whose demand was measured (free, a retry drifted back to a grasp that had failed); should
            # the warm start fail, only this grasp's own scanned guess (others are other grasps, tried in turn)
            own = app.start_guess
            retry = self._solve_approach(app.parameters, max_starts=1 if own >= 0 else 0,
                                         skip_guesses=max(own, 0), meeting_time_box_s=MEETING_TIME_BOX_S,
                                         tightened=tightened, max_iterations=self.resolve_iterations)
            if not retry.success:
                # keep the first solution (the verifier will name its rate excess), but count the time
                app = accumulated(app, retry)
                self.notes.append(f"the re-solve failed ({self._failed(retry)}); the first approach is kept")
                mended = False
                break
            app = accumulated(retry, app)
        return replace(self.planner.candidate_from(app, samples, tr, self.motion),
                       unheld_because=why_unheld(self.planner, self.motion, app, samples, tr, mended, checked))

    def _tighten_rates(self, tr: TrackingResult) -> None:
        """Scale the rate bounds of the tracking segment where ``tr``'s demand peaked by the excess, and say so."""
        ratio = tr.peak_rate_demand
        segment = node_segment(tr.peak_demand_time_s, self.planner.scenario.phases.tracking_s)
        self.tracking_speed_scale = self.tracking_speed_scale.copy()
        self.tracking_speed_scale[segment] *= TIGHTENING_MARGIN / ratio
        self.notes.append(f"tracking joint rate {ratio:.3f}× the limit at {tr.peak_demand_time_s:.2f} s into "
                          f"tracking: approach re-solved with the rate bounds of tracking segment {segment + 1} "
                          f"scaled by {self.tracking_speed_scale[segment]:.3f}")

    def _between_via_points(self, app: ApproachSolution, samples: PhaseSamples,
                            tightened: ApproachBounds) -> ApproachBounds | None:
        """The via-point bounds that hold ``app``'s clearances and joint rates between its via points (and a note), or
        None when nothing dips or peaks there (:mod:`planner.phases.approach_clearance`,
        :mod:`planner.phases.approach_rates`)."""
        raised, dips = self.planner.approach_clearance.raised_bounds(app, samples, self.motion)
        rates, peaks = lowered_rates(self.planner.approach, samples, tightened)
        if dips:
            worst = dips[0]
            self.notes.append(f"{worst.pair} {worst.distance_m:.4f} m (clearance {worst.clearance_m:.3g} m) between "
                              f"the approach's via points at t = {app.start_delay_s + worst.t_s:.2f} s ({len(dips)} "
                              "dip(s)): approach re-solved with those pairs' bounds raised at the via points around "
                              "them")
        if peaks:
            p = peaks[0]
            self.notes.append(f"joint {p.joint + 1} at {p.ratio:.3f}× its rate limit between the approach's via points "
                              f"at t = {app.start_delay_s + p.t_s:.2f} s ({len(peaks)} peak(s)): approach re-solved "
                              "with those joints' rate bounds lowered at the via points around them")
        if not dips and rates is None:
            return None
        raised_only = ApproachBounds(collision_raise_m=raised) if dips else AS_SOLVED
        return raised_only if rates is None else raised_only.and_(rates)
