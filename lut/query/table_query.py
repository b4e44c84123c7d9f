"""``lutgen query``: observed target state → table lookup → interpolation → verify → refine (docs/table.md, Query).

1. The state is mapped to grid coordinates (flat spin: rate, spin-axis angle, phase) and its cell; a state
   off the grid's family (an estimator's flat spin is never exact) or beyond an axis' bounds is answered at
   the nearest grid coordinates, and the result says so (:mod:`lut.table.grid_projection`).
2. The feasible corners of the cell, carried to the state (the same spin angle at the meeting), are interpolated —
   only mutually consistent ones at the cell's lowest cost (:mod:`lut.query.interpolation`). Without a feasible
   corner the nearest feasible point of the table is used. The table's plans farther from the state than a plan of
   its kind carries (:mod:`lut.query.carry`) are not tried: the query goes to step 5's cold solve at once.
3. The interpolated parameters are re-simulated at the true state (tracking IK, stabilization from the
   actual grasp state) and verified densely.
4. If the interpolated plan is not feasible only from its grasp on, its stabilization is re-solved warm at the grasp
   it reached, in process (:mod:`lut.query.stabilization_repair`; source ``repaired``). Otherwise, or if that fails,
   the corners' own plans (carried to the state; the cheapest, then the heaviest first) are re-simulated and verified
   the same way (each repaired so if needed), and the first feasible one is the answer (source ``corner`` or
   ``repaired``). A plan that fails from one cause (only the grasp wrench, or only the arm's path) is repaired at
   once; one whose braking is too harsh while its arm also hits a limit or a body only once every corner was verified
   (those repairs mostly fail, seconds each).
5. If that is not feasible either, or refinement was asked for, a warm-started solve runs in a child process
   within what is left of the time budget (killed at it); a feasible refined plan replaces the
   interpolated one. If there is still no feasible plan, a cold solve gets what is left after that.
6. The answer carries the scenario's weighted cost terms of its plan and of each corner used
   (:mod:`lut.table.plan_costs`), so an optimal table's query shows how far it is from its corners' optima.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from lut.query.carry import (
    Displacement,
    nearest_displacement,
    off_flat_spin_family,
    outside_flat_spin_grid,
    rate_and_axis,
)
from lut.query.corner_stage import FINISH_RESERVE_S, MIN_REFINE_S, Attempt, CornerStage
from lut.query.interpolation import Candidate, cheapest, consistent_group, mean_of_group
from lut.query.least_violating import violates_less
from lut.query.result import QueryResult, QuerySource, TableAnswer
from lut.query.stabilization_repair import repaired_plan
from lut.query.table_checks import check_parameters, parameter_shapes
from lut.query.table_start import placed_start_s, table_period_s
from lut.solve.point_process import DEFAULT_SOLVER, run_point
from lut.solve.point_worker import WARM_SHARE
from lut.table.grid import Grid
from lut.table.grid_config import load_grid_text
from lut.table.grid_projection import project_to_grid
from lut.table.model_identity import table_hash
from lut.table.plan_costs import CostBreakdown, CostScorer
from lut.table.point_result import PointResult, PointStatus
from lut.table.records import from_record
from lut.table.schema import TableError
from lut.table.store import Table
from planner.config.scenario import Scenario, load_scenario
from planner.deadline import ANSWER_LEAD_S, Deadline
from planner.model.target import TargetState
from planner.phases.approach_guess import reach_scan
from planner.plan import GraspPlan, NoPlan, OutOfReach, Planner
from planner.plan_grasps import GRASP_GUESSES
from planner.plan_parameters import PlanParameters
from planner.verify.verifier import VerifyReport, verify

# a warm refine of an infeasible interpolated plan gets the build's WARM_SHARE of the time left when a cold solve
# follows: a warm approach NLP from an interpolated plan in collision can stall for the whole budget, while the cold
# plan (its own guesses) would have found a feasible plan in the rest (docs/measurements.md, "Optimal tables")
# and at most this [s]: a warm refine that fails holds the cold solve back for its whole share, while those that
# succeed need far less, and a live cold solve begun later reaches fewer meeting times (README "Envelope tables")
WARM_REFINE_CAP_S = 12.0
# an optimal table's warm refine lowers its cost for as long as it is given (how a query keeps the optimum): the cap
# its queries were measured with (README "Optimal tables")
COSTED_WARM_REFINE_CAP_S = 30.0


class TableQuery:
    """A table opened for queries: its grid, point results and the planner of its scenario (built once)."""

    def __init__(self, table_path: str | Path, scenario_path: str | Path | None = None) -> None:
        t0 = time.perf_counter()
        self.table = Table.open(table_path)
        path = Path(scenario_path) if scenario_path is not None else self.table.scenario_file()
        self.scenario: Scenario = load_scenario(path)
        self.table.check_model(table_hash(self.scenario), str(path))
        config = load_grid_text(self.table.attrs["config_text"], str(table_path), path)
        self.grid = Grid(config, self.scenario.target.inertia_body_kg_m2, self.scenario.target_state.as_state())
        if self.grid.n_points != self.table.n_points:
            raise TableError(f"{table_path}: grid has {self.grid.n_points} points but the table {self.table.n_points}")
        self.scenario_path = path
        check_parameters(self.table, parameter_shapes(self.scenario))
        self.planner = Planner(self.scenario)
        self.points: dict[int, PointResult] = {p: from_record(self.table.record(p)) for p in range(self.table.n_points)}
        self.feasible = [p for p, r in self.points.items() if r.status is PointStatus.FEASIBLE]
        self.scorer = CostScorer(self.scenario, self.planner.ff, self.planner.approach.spline)
        self._corner_costs: dict[int, CostBreakdown] = {}  # point → its stored plan's cost terms (corner_costs)
        self.observed_at_s: float | None = None  # the query in progress's observation (time.monotonic())
        self.late: list[str] = []  # the query in progress's table plans not tried: they would start before its answer
        # what the solve that made the query in progress's plan noted; () while its plan is a table plan
        self.solve_notes: tuple[str, ...] = ()
        self.earliest_start_s: float | None = None  # [s after the observation] --earliest-start-s; None: the scenario's
        self.load_time_s = time.perf_counter() - t0

    # ---- lookup + interpolation ------------------------------------------------------------

    def interpolate(self, state: TargetState) -> TableAnswer | None:
        """The table's parameters for ``state``: its cell's consistent feasible corners averaged, else the
        nearest feasible point's; ``None`` when the table has no feasible point."""
        projection = project_to_grid(self.grid, state)
        coords = projection.coords
        period = self.period_s(state)
        candidates = self.corner_candidates(state)
        if candidates:
            group = consistent_group(cheapest(candidates), period)
            return TableAnswer(mean_of_group(group, period), [c.corner for c in group], QuerySource.INTERPOLATED,
                               projection.notes)
        if not self.feasible:
            return None
        nearest = min(self.feasible, key=lambda p: self.grid.normalised_distance(self.grid.coordinates(p), coords))
        stored = self.points[nearest].parameters
        carried = stored.with_start_delay(stored.approach.start_delay_s + self.phase_shift_s(nearest, coords))
        return TableAnswer(carried, [nearest], QuerySource.NEAREST, projection.notes)

    def corner_candidates(self, state: TargetState) -> list[Candidate]:
        """The feasible corners (weight > 0) of ``state``'s cell, their parameters carried to its spin phase."""
        coords = project_to_grid(self.grid, state).coords
        cell = self.grid.locate(coords)
        period = self.period_s(state)
        candidates = []
        for corner, weight in zip(cell.corners, cell.weights, strict=True):
            point = self.points[corner]
            if point.status is not PointStatus.FEASIBLE or weight <= 0:
                continue
            tau = point.parameters.approach.start_delay_s + self.phase_shift_s(corner, coords)
            carried = point.parameters.with_start_delay(tau % period if np.isfinite(period) else tau)
            cost = 0.0 if self.scorer.feasibility_only else self.corner_costs(corner).total
            candidates.append(Candidate(corner, float(weight), carried, cost))
        return candidates

    def period_s(self, state: TargetState) -> float:
        """The period [s] by which the table's plans may start later at ``state`` (:func:`table_period_s`)."""
        return table_period_s(state, self.scenario.target.inertia_body_kg_m2, self.grid.kind == "flat_spin")

    def phase_shift_s(self, point: int, coords: NDArray[np.float64]) -> float:
        """Start-delay shift [s] carrying grid point ``point``'s plan to ``coords`` (flat-spin symmetry): the target's
        spin angle at the end of the plan's approach kept, where the gripper must be at the pre-grasp."""
        meeting_s = self.points[point].parameters.approach.start_delay_s + self.scenario.phases.approach_s
        return self.grid.start_delay_shift_s(self.grid.coordinates(point), coords, meeting_s=meeting_s)

    # ---- the whole query ---------------------------------------------------------------------

    def query(self, state: TargetState, budget_s: float = 100.0, refine: bool = False,
              since_s: float | None = None) -> QueryResult:
        """Lookup → interpolate → re-simulate + verify → refine if needed (or asked), within ``budget_s`` [s]
        counted from ``since_s`` (a ``time.monotonic()`` instant; default: now).

        The refine runs in a child process whose plan ends at the budget less :data:`FINISH_RESERVE_S` (to
        re-simulate and verify its answer here) and which is killed there, so a query never overruns, whatever
        the solver does. A warm refine that is not asked for gets :data:`WARM_SHARE` of the time left, at most
        :attr:`warm_refine_cap_s`, so that the cold solve after it (if it gives no feasible plan) has the rest.
        """
        t_start = time.perf_counter()
        self.observed_at_s = time.monotonic() if since_s is None else since_s  # the observation: the refine's too
        deadline, self.late = Deadline.after(budget_s, since_s).observed(self.observed_at_s), []
        self.solve_notes = ()
        latency: dict[str, float] = {}
        found = self.interpolate(state)
        far = None if found is None else self.beyond_carry(state, found.corners)
        latency["lookup_interpolate_s"] = time.perf_counter() - t_start
        usable = None if far is not None else found  # the table's answer, where its plans may carry to the state
        made = None if usable is None else self.table_plan(state, usable, deadline, latency, refine)
        corners = made[2] if made is not None else [] if usable is None else usable.corners
        warm = None if usable is None else usable.parameters
        made, refine_failure = self.solved(state, warm, made, corners, deadline, latency, refine, t_start)
        if made is None:
            why = refine_failure or f"there was no time left to solve (budget {budget_s:g} s)"
            near = ("the table has no feasible point near this state" if not self.late else
                    f"the table's plans near this state would start too soon ({'; '.join(self.late)})")
            near = far.note() if far is not None else near
            raise NoPlan(f"no plan: {near} and the solve gave none: {why}")
        plan, report, corners, source = made
        costs = self.cost_breakdowns(plan, report, corners)
        latency["total_s"] = time.perf_counter() - t_start
        notes = (found.notes if found is not None else ()) + ((far.note(),) if far is not None else ())
        return QueryResult(plan, report, source, corners, latency, refine_failure, notes, costs, tuple(self.late),
                           self.solve_notes)

    def beyond_carry(self, state: TargetState, corners: list[int]) -> Displacement | None:
        """How far ``state`` is from the table's plans when they cannot carry that far (:mod:`lut.query.carry`), else
        None: a tumble table's, from the nearest of the grid points ``corners`` (None without corners); a flat-spin
        table's, from the state's nearest flat spin and that flat spin from the grid's box (None inside it)."""
        if self.grid.kind == "tumble":
            nearest = nearest_displacement(corners, state, self.grid.state)
        else:
            nearest = self._off_flat_spin_grid(state)
        return nearest if nearest is not None and nearest.beyond_carry else None

    def _off_flat_spin_grid(self, state: TargetState) -> Displacement:
        """How far ``state`` is from a flat-spin table's plans: from its nearest flat spin when beyond what a plan
        carries from its own state (a tumble), else how far outside the grid's box that flat spin lies (its phase: an
        exact time shift)."""
        projection = project_to_grid(self.grid, state)
        off = off_flat_spin_family(state, self.grid.state_at(projection.family))
        if off.beyond_carry:
            return off
        names = self.grid.axis_names
        return outside_flat_spin_grid(rate_and_axis(projection.family, names), rate_and_axis(projection.coords, names))

    def solved(self, state: TargetState, warm: PlanParameters | None, made: Attempt | None, corners: list[int],
               deadline: Deadline, latency: dict[str, float], refine: bool,
               t_start: float) -> tuple[Attempt | None, str]:
        """The query's solves after the table's plans: warm from ``warm`` (the table's answer, when given), then cold
        (with its retries over grasps), in child processes and what the budget has left, while the plan so far
        (``made``) is not feasible or a refine was asked for; a solved plan is the attempt of ``corners``. The warm
        start is ``warm`` placed as the table's plans are (:meth:`placed`: whole spin periods later where it would start
        before the answer), and none where no start is in time: its grasp has passed (docs/table.md, Query 5). Returns
        the better plan and why the last solve gave none ("" when none failed); ``t_start`` (``time.perf_counter()``)
        dates the query."""
        warm = None if warm is None else self.placed(state, warm)
        attempts = [(warm, QuerySource.REFINED)] if warm is not None else []
        attempts.append((None, QuerySource.SOLVED_COLD))
        best = made
        if (best is None or not best[1].feasible) and deadline.remaining_s() - FINISH_RESERVE_S >= MIN_REFINE_S:
            unreachable = self.out_of_reach(state, t_start)  # only where it can spare a solve
            if unreachable is not None and best is None:
                raise unreachable
            if unreachable is not None:  # no solve can reach the grasp: answer with the table's plan, infeasible
                return best, str(unreachable)
        refine_failure = ""
        for i, (start, label) in enumerate(attempts):
            remaining = deadline.remaining_s() - FINISH_RESERVE_S
            if not (best is None or not best[1].feasible or refine) or remaining < MIN_REFINE_S:
                break
            before_cold = i + 1 < len(attempts) and not refine  # the cold solve keeps the rest
            share_s = min(WARM_SHARE * remaining, self.warm_refine_cap_s) if before_cold else remaining
            t0 = time.perf_counter()
            refined = self.refine(state, start, max(MIN_REFINE_S, share_s))
            latency["refine_s"] = latency.get("refine_s", 0.0) + time.perf_counter() - t0
            if refined.status in (PointStatus.FEASIBLE, PointStatus.INFEASIBLE) and refined.parameters is not None:
                new_plan, new_report = self.simulate_and_verify(state, refined.parameters, {})
                if best is None or (new_report.feasible and refine) or violates_less(new_report, best[1]):
                    best, self.solve_notes = (new_plan, new_report, corners, label), refined.notes
                    new_plan.notes.extend(refined.notes)  # the plan file keeps how its parameters were solved
            else:
                refine_failure = refined.failure_reason
            refine = False  # an asked-for refine is the warm one; the cold solve only stands in for a missing plan
        return best, refine_failure

    @property
    def warm_refine_cap_s(self) -> float:
        """The most [s] a warm refine followed by a cold solve may take: :data:`WARM_REFINE_CAP_S` for a table of
        feasible plans, :data:`COSTED_WARM_REFINE_CAP_S` for a table of optimal plans (its refine descends the cost)."""
        return WARM_REFINE_CAP_S if self.scorer.feasibility_only else COSTED_WARM_REFINE_CAP_S

    def out_of_reach(self, state: TargetState, t_start: float) -> OutOfReach | None:
        """Why no solve can plan ``state`` when no meeting time of the window brings the grasp within the arm's reach
        (the cold plan's scan, seconds), else None; ``t_start`` (``time.perf_counter()``) dates the answer."""
        scan = reach_scan(self.scenario, self.planner.approach.spline, state, GRASP_GUESSES, held_angles=False)
        return None if scan.reachable else OutOfReach(scan, time.perf_counter() - t_start)

    def cost_breakdowns(self, plan: GraspPlan, report: VerifyReport,
                        corners: list[int]) -> tuple[CostBreakdown, ...]:
        """The plan's weighted cost terms, then each corner's from its stored parameters and verified clearance
        (a table without ``costs/min_distance_m`` scores that term NaN); ``()`` for a feasibility-only scenario."""
        if self.scorer.feasibility_only:
            return ()
        rows = [self.scorer.score("plan", plan.approach.parameters, float(np.min(report.min_distance_m)))]
        rows += [self.corner_costs(c) for c in corners if self.points[c].parameters is not None]
        return tuple(rows)

    def corner_costs(self, point: int) -> CostBreakdown:
        """The weighted cost terms of a feasible point's stored plan, from its parameters and verified clearance (NaN
        without ``costs/min_distance_m``), scored once per table."""
        if point not in self._corner_costs:
            self._corner_costs[point] = self.scorer.score_stored(f"corner {point}", self.points[point])
        return self._corner_costs[point]

    def table_plan(self, state: TargetState, found: TableAnswer, deadline: Deadline, latency: dict[str, float],
                   refine: bool) -> Attempt | None:
        """The table's own plan at ``state``: ``found`` re-simulated and verified (:meth:`verified`); unless a refine
        was asked for and while it is not feasible, the table's plans repaired (:meth:`repaired`): the nearest point's
        alone, an interpolation's with its corners' own plans (:meth:`corner_plan`). Returns the plan, its report, the
        corners it came from and its source: the first feasible one, else the least violating; None when every plan
        tried would start before the answer."""
        first = self.verified(state, found.parameters, found.corners, found.source, latency)
        if refine or (first is not None and first[1].feasible):
            return first
        t0 = time.perf_counter()
        latency["repair_s"] = 0.0
        if found.source is QuerySource.INTERPOLATED:
            best = self.corner_plan(state, found, first, deadline, latency)
            latency["corners_s"] = time.perf_counter() - t0
            return best
        fixed = None if first is None else self.repaired(first[0], first[1], deadline)
        latency["repair_s"] = time.perf_counter() - t0
        return first if fixed is None else (*fixed, found.corners, QuerySource.REPAIRED)

    def corner_plan(self, state: TargetState, found: TableAnswer, first: Attempt | None, deadline: Deadline,
                    latency: dict[str, float]) -> Attempt | None:
        """The corner stage at ``state`` (:class:`~lut.query.corner_stage.CornerStage`): ``first`` (the interpolated
        plan, verified; None when late) repaired, or the first of the cell's corners' own plans feasible there; else
        the least violating of those made; None when none was made."""
        return CornerStage(self, state, found, deadline, latency).run(first)

    def repaired(self, plan: GraspPlan, report: VerifyReport,
                 deadline: Deadline) -> tuple[GraspPlan, VerifyReport] | None:
        """``plan`` (a table plan as :meth:`simulate_and_verify` made it) with its stabilization re-solved warm at its
        grasp (within :data:`~lut.query.stabilization_repair.REPAIR_ITERATIONS` iterations, ended
        :data:`FINISH_RESERVE_S` before ``deadline``), when ``report`` (its verification) failed only from the grasp on
        and the repair verifies feasible; else None."""
        if deadline.remaining_s() < FINISH_RESERVE_S + MIN_REFINE_S:
            return None
        in_time = deadline.earlier(FINISH_RESERVE_S).in_time_for(plan.approach.start_delay_s)
        return repaired_plan(self.planner, plan, report, in_time)

    def verified(self, state: TargetState, parameters: PlanParameters, corners: list[int], source: QuerySource,
                 latency: dict[str, float]) -> Attempt | None:
        """The table plan of ``parameters`` placed in time (:meth:`placed`), re-simulated at ``state`` and verified, as
        the attempt of ``corners`` from ``source``; None, noted in :attr:`late`, when it would start before the
        answer."""
        placed = self.placed(state, parameters)
        if placed is None:
            tau = placed_start_s(parameters.approach.start_delay_s, self.period_s(state),
                                 self.scenario.phases.start_delay_window_s)
            self.late.append(f"the {source} plan of points {corners} at {tau:.2f} s")
            return None
        return (*self.simulate_and_verify(state, placed, latency), corners, source)

    def placed(self, state: TargetState, parameters: PlanParameters) -> PlanParameters | None:
        """A table plan's ``parameters`` (carried to ``state``'s phase) with the start :func:`placed_start_s` gives:
        in the window by whole periods (:meth:`period_s`) and, in a query, :data:`~planner.deadline.ANSWER_LEAD_S`
        after now and at :attr:`earliest_start_s` at least; the same object when unmoved; None when no such start is
        in the window."""
        earliest = Deadline(observed_at_s=self.observed_at_s).earliest_start_s(ANSWER_LEAD_S)
        tau = parameters.approach.start_delay_s
        if self.earliest_start_s is not None:
            earliest = max(earliest, self.earliest_start_s)
        placed = placed_start_s(tau, self.period_s(state), self.scenario.phases.start_delay_window_s, earliest)
        if placed is None:
            return None
        return parameters if placed == tau else parameters.with_start_delay(placed)

    def simulate_and_verify(self, state: TargetState, parameters: PlanParameters,
                             latency: dict[str, float]) -> tuple[GraspPlan, VerifyReport]:
        """The plan of ``parameters`` (its start delay as given) re-simulated at ``state``, verified."""
        t0 = time.perf_counter()
        plan = self.planner.simulate(state, parameters)
        latency["simulate_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        report = verify(plan)
        latency["verify_s"] = time.perf_counter() - t0
        return plan, report

    def refine(self, state: TargetState, warm: PlanParameters | None, budget_s: float) -> PointResult:
        """A solve warm-started from ``warm`` (cold without) in a child process with a hard time limit [s].

        The child's plan has a deadline inside that limit (:mod:`planner.deadline`): its solves end there with
        the best they have, verified, before the process would be killed. A warm solve's NLPs each get at most half
        the budget, so the approach cannot take the stabilization's time (a warm approach converges in a few
        iterations; a warm stabilization at a grasp between the table's may need many). A cold solve's keep the
        scenario's limit, as ``lutgen plan``'s do: it is that command's plan at the state (halved, an approach
        re-solved for its tracking's rates, 40 s of a 94 s budget, was cut at 47 s and its grasp lost).
        """
        max_wall_s = None if warm is None else max(1.0, budget_s / 2)
        return run_point(DEFAULT_SOLVER, str(self.scenario_path), -1, state, warm, 0.0, timeout_s=budget_s,
                         max_wall_s=max_wall_s, plan_budget_s=budget_s,
                         timeout_name="the refine's share of --budget-s",
                         solver_kwargs=self._solver_kwargs())

    def _solver_kwargs(self) -> dict[str, float]:
        """What a solve of the query in progress needs to know: its observation's instant, the operator's earliest
        start."""
        given = {"observed_at_s": self.observed_at_s, "earliest_start_s": self.earliest_start_s}
        return {k: v for k, v in given.items() if v is not None}

