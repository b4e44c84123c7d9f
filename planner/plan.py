"""``plan_grasp``: the three phases chained into one grasp plan (paper §4; DESIGN §5).

approach NLP → dense re-simulation of the approach → tracking IK → compound momentum at the grasp →
stabilization NLP → dense re-simulation of the stabilization. The approach NLP carries a proxy of the
tracking constraints (configurations at the tracking nodes); the IK caps its joint rates (a short lag the
pose feedback recovers), but if it asked for more than :data:`RATE_DEMAND_TOLERATED` × a limit, f, the
approach is re-solved with its tracking-rate bounds tightened by 1/f (warm-started), up to
:data:`TIGHTENING_ROUNDS` times. Whether the stabilization is feasible depends strongly on the grasp (its
configuration and joint rates), so a cold plan whose stabilization fails tries the grasps of the approach's
next scanned meeting times (see :meth:`Planner.plan`). Times are seconds since the observation.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from planner.config.scenario import Scenario
from planner.model.compound import compound_robot
from planner.model.freefloating import FreeFloatingModel
from planner.model.rotation import axis_angle_to_matrix
from planner.model.target import TargetMotion, TargetState
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.phase_spline import approach_vertices, stabilization_vertices
from planner.phases.approach import ApproachProblem, ApproachSolution
from planner.phases.approach_guess import ReachScan, forget_last_scan, reach_scan, target_motion
from planner.phases.stabilization import (
    GraspState,
    StabilizationProblem,
    StabilizationSolution,
    grasp_momentum_world,
    stabilization_spline,
)
from planner.phases.tracking import TrackingController, TrackingResult
from planner.plan_parameters import PlanParameters

Array = NDArray[np.float64]

SAMPLE_STEP_S = 0.01  # dense re-simulation step of the approach and stabilization (s)
TIGHTENING_ROUNDS = 2
# the IK's rate cap absorbs a demand up to this × the limit; beyond it the lag grows and the approach is
# re-solved instead. Measured: scenarios I and II asked for 1.14 and 1.10 and, capped, still met the grasp
# to 2-3e-5 m, rad, m/s and rad/s — 20-50 times inside the grasp thresholds verify applies
RATE_DEMAND_TOLERATED = 1.25
# A cold plan whose stabilization fails tries the grasps reached from the approach's next scanned guesses,
# up to this many guesses in all (the approach's own default number of starts).
GRASP_GUESSES = 3
# IPOPT iterations (coarse + full NLP) a stabilization gets while another grasp remains to be tried. Measured
# on nine scenario II states: successful cold solves took 5-74 iterations (one took 319), failing ones
# 324-712, 90-290 s; from another meeting time the (0°, 3°/s) state that fails from its first grasp is
# feasible in 5 iterations.
STABILIZATION_BUDGET = 120


# A retry's approach (from the next scanned guesses) gets this many times the first approach's iterations, at
# least APPROACH_RETRY_MIN: a neighbouring meeting time is about as hard to reach as the first. Measured: the
# default states' cold approaches take 11 (scenario II) and 29 (I) iterations; the retries of a scenario II state
# no grasp of which stabilizes (yaw 200°) ran to IPOPT's 400-iteration limit, 119 s of its 170 s plan.
APPROACH_RETRY_FACTOR = 3
APPROACH_RETRY_MIN = 60


def approach_retry_budget(first_iterations: int) -> int:
    """IPOPT iterations for the approach solve of a retry, from the first approach's iteration count."""
    return max(APPROACH_RETRY_MIN, APPROACH_RETRY_FACTOR * first_iterations)


class OutOfReach(Exception):
    """A cold plan found no meeting time in the start-delay window where the arm reaches the grasp: the state
    is infeasible, and there is no trajectory to verify. ``str()`` says why; ``elapsed_s`` is how long it took."""

    def __init__(self, scan: ReachScan, elapsed_s: float) -> None:
        self.scan = scan
        self.elapsed_s = elapsed_s
        super().__init__(scan.reason())


@dataclass
class GraspPlan:
    """One planned grasp: decision parameters, dense trajectory, metrics, solver statistics (SI)."""

    scenario: Scenario
    target_state: TargetState
    approach: ApproachSolution
    tracking: TrackingResult
    stabilization: StabilizationSolution
    grasp: GraspState
    T_body_grasp_used: Array  # grasp frame in the target body frame, free-axis angle applied
    phases: dict[str, tuple[float, float]]
    t: Array  # dense samples (s since the observation), approach start to stabilization end
    q: Array
    qd: Array
    x_base: Array  # [p_world_base, quat_world_base]
    phase_index: Array  # 0 approach, 1 tracking, 2 stabilization
    timings_s: dict[str, float] = field(default_factory=dict)
    solver_ok: bool = True
    notes: list[str] = field(default_factory=list)

    @property
    def t_grasp(self) -> float:
        return self.phases["tracking"][1]

    @property
    def parameters(self) -> PlanParameters:
        """The decision parameters this plan is re-simulated from."""
        return PlanParameters(self.approach.parameters, self.stabilization.params)


class Planner:
    """The symbolic problems of one scenario, built once; :meth:`plan` solves one target state."""

    def __init__(self, scenario: Scenario) -> None:
        t0 = time.perf_counter()
        self.scenario = scenario
        self.ff = FreeFloatingModel(scenario.robot, compile_rk4=True)
        self.approach = ApproachProblem(scenario, self.ff)
        self.tracking = TrackingController(scenario, self.ff)
        self._stabilization: StabilizationProblem | None = None
        self.stabilization_spline = stabilization_spline(scenario)
        self.build_time_s = time.perf_counter() - t0

    @property
    def stabilization_problem(self) -> StabilizationProblem:
        """The scenario's stabilization NLP (every grasp geometry is a parameter of it), built on first use."""
        if self._stabilization is None:
            self._stabilization = StabilizationProblem(self.scenario)
        return self._stabilization

    def plan(self, state: TargetState, warm_start: PlanParameters | GraspPlan | None = None) -> GraspPlan:
        """Plan the grasp for the observed ``state``; ``warm_start`` seeds both NLPs.

        A cold plan whose scan of meeting times reaches none raises :class:`OutOfReach` at once. A cold plan
        whose stabilization fails from the first grasp tries the grasps the approach reaches from its next
        scanned guesses (other meeting times), giving each stabilization :data:`STABILIZATION_BUDGET`
        iterations; when none succeeds, the first grasp's stabilization is solved again without that budget,
        so the plan is never worse than from the first grasp alone. A warm plan keeps its grasp (a table's
        neighbours stay in one family of solutions).
        """
        t_start = time.perf_counter()
        self._forget_scans()
        warm = warm_start.parameters if isinstance(warm_start, GraspPlan) else warm_start
        if warm is None:
            self._raise_if_out_of_reach(state, t_start)
        notes: list[str] = []
        motion = self._motion(state)
        app = self.approach.solve(state, warm.approach if warm is not None else None)
        candidate = first = self._grasp_candidate(state, app, motion, notes)
        approach_s, stab_s = candidate.app.solve_time_s, 0.0  # NLP time, tracking-rate re-solves included
        warm_stab = warm.stabilization_params if warm is not None else None

        def stabilize(c: GraspCandidate, budget: int | None) -> StabilizationSolution:
            nonlocal stab_s
            t0 = time.perf_counter()  # the phase's wall time: NLP builds (if new) and solves
            result = c.stabilize(warm_stab, budget)
            stab_s += time.perf_counter() - t0
            return result

        while True:
            more = warm is None and candidate.app.success and 0 <= candidate.app.start_guess < GRASP_GUESSES - 1
            # budgeted while another grasp remains, or the first grasp remains to fall back to
            budget = STABILIZATION_BUDGET if more or candidate is not first else None
            stab = stabilize(candidate, budget)
            if stab.success or budget is None:
                break
            failed = f"stabilization from the grasp at t = {candidate.grasp_time_s:.1f} s failed within {budget} " \
                     f"iterations ({stab.status})"
            notes.append(failed + ("; trying the approach's next guess" if more else ""))
            if not more:
                break
            nxt = self.approach.solve(state, None, max_starts=GRASP_GUESSES,
                                      skip_guesses=candidate.app.start_guess + 1,
                                      max_iterations=approach_retry_budget(first.app.iterations))
            if not nxt.success:
                approach_s += nxt.solve_time_s
                notes.append(f"the approach from its next guesses failed ({nxt.status})")
                break
            candidate = self._grasp_candidate(state, nxt, motion, notes)
            approach_s += candidate.app.solve_time_s
        if not stab.success and budget is not None:
            # a budgeted failure is never the answer: the first grasp gets its whole solve
            notes.append("no other grasp stabilized within the budget: the first grasp's stabilization is solved "
                         "again without it")
            candidate = first
            stab = stabilize(first, None)
        timings = {"approach_s": approach_s, "stabilization_s": stab_s}
        c = candidate
        plan = self._assemble(state, c.app, c.approach_samples, c.tracking, c.grasp, c.T_body_grasp_used, stab,
                              timings, notes)
        plan.timings_s["total_s"] = time.perf_counter() - t_start
        return plan

    def _forget_scans(self) -> None:
        """Scans are kept for one plan's retries only: planning a state again costs what a new state costs (and
        a benchmark repeating one state measures that)."""
        self.approach.forget_scan()
        forget_last_scan()

    def _raise_if_out_of_reach(self, state: TargetState, t_start: float) -> None:
        """:class:`OutOfReach` when the scan of meeting times reaches none (the approach then starts from this
        same, kept scan; without a reachable time its NLP would only search from θ_in for minutes)."""
        scan = reach_scan(self.scenario, self.approach.spline, state, GRASP_GUESSES)
        if not scan.reachable:
            raise OutOfReach(scan, time.perf_counter() - t_start)

    def _grasp_candidate(self, state: TargetState, app: ApproachSolution, motion: TargetMotion,
                         notes: list[str]) -> GraspCandidate:
        """Approach → tracking (re-solving the approach with tightened tracking rates if the IK asked for
        too much) → the compound's state at the grasp and its stabilization problem."""
        for round_ in range(TIGHTENING_ROUNDS + 1):
            approach_samples, tr = self._approach_and_tracking(app, motion)
            ratio = tr.peak_rate_demand
            if ratio <= RATE_DEMAND_TOLERATED or round_ == TIGHTENING_ROUNDS or not app.success:
                break
            scale = self.approach.tracking_speed_scale / ratio * 0.97
            notes.append(f"tracking joint rate {ratio:.3f}× the limit: approach re-solved with its tracking-rate "
                         f"bounds scaled by {scale:.3f}")
            retry = self.approach.solve(state, app.parameters, tracking_speed_scale=scale)
            if not retry.success:
                # keep the first solution (the verifier will name its rate excess), but count the time
                app = replace_timing(app, retry)
                notes.append(f"the re-solve failed ({retry.status}); the first approach is kept")
                break
            app = replace_timing(retry, app)
        grasp, T_body_grasp_used = self._grasp_state(tr, motion)
        return GraspCandidate(self, app, approach_samples, tr, grasp, T_body_grasp_used)

    def simulate(self, state: TargetState, given: PlanParameters) -> GraspPlan:
        """The plan that given parameters produce for ``state``, without solving (table queries).

        The approach parameters are used as they are; the tracking IK runs from where they end; the
        stabilization parameters are applied to Eq. 24 from the actual grasp state. ``verify`` decides.
        """
        t_start = time.perf_counter()
        motion = self._motion(state)
        app = ApproachSolution.given(given.approach)
        approach_samples, tr = self._approach_and_tracking(app, motion)
        grasp, T_body_grasp_used = self._grasp_state(tr, motion)
        params = given.stabilization_params
        if params is None:
            params = self.stabilization_problem.initial_params(grasp)
        # given parameters need no NLP: a query that only simulates and verifies never builds one
        stab = StabilizationSolution(np.asarray(params, dtype=float), True, "given", 0, 0.0, 0.0, 0.0, float("nan"),
                                     float("nan"))
        plan = self._assemble(state, app, approach_samples, tr, grasp, T_body_grasp_used, stab,
                              {"approach_s": 0.0, "stabilization_s": 0.0}, ["simulated from given parameters"])
        plan.timings_s["total_s"] = time.perf_counter() - t_start
        return plan

    def _motion(self, state: TargetState) -> TargetMotion:
        ph = self.scenario.phases
        return target_motion(self.scenario, state,
                             ph.max_start_delay_s + ph.approach_s + ph.tracking_s + ph.stabilization_s + 1.0)

    def _approach_and_tracking(self, app: ApproachSolution, motion: TargetMotion) -> tuple[tuple, TrackingResult]:
        samples = self._approach_samples(app)
        _, q_app, _, x_app = samples
        tr = self.tracking.simulate(motion, app.start_delay_s + self.scenario.phases.approach_s, q_app[-1],
                                    x_app[-1], app.q_tracking)
        return samples, tr

    def _assemble(self, state: TargetState, app: ApproachSolution, approach_samples: tuple, tr: TrackingResult,
                  grasp: GraspState, T_body_grasp_used: Array, stab: StabilizationSolution, timings: dict[str, float],
                  notes: list[str]) -> GraspPlan:
        sc = self.scenario
        tf1, tf2, tf3 = sc.phases.approach_s, sc.phases.tracking_s, sc.phases.stabilization_s
        t_app, q_app, qd_app, x_app = approach_samples
        t_st, q_st, qd_st, x_st = self._stabilization_samples(stab, grasp)
        t0 = app.start_delay_s
        phases = {"approach": (t0, t0 + tf1), "tracking": (t0 + tf1, t0 + tf1 + tf2),
                  "stabilization": (t0 + tf1 + tf2, t0 + tf1 + tf2 + tf3)}
        t = np.concatenate([t_app + t0, tr.t[1:], t_st[1:] + phases["stabilization"][0]])
        q = np.vstack([q_app, tr.q[1:], q_st[1:]])
        qd = np.vstack([qd_app, tr.qd[1:], qd_st[1:]])
        x = np.vstack([x_app, tr.x_base[1:], x_st[1:]])
        phase_index = np.concatenate([np.zeros(len(t_app)), np.ones(len(tr.t) - 1), np.full(len(t_st) - 1, 2)])
        return GraspPlan(sc, state, app, tr, stab, grasp, T_body_grasp_used, phases, t, q, qd, x,
                         phase_index.astype(int), dict(timings), app.success and stab.success, notes)

    # ---- dense re-simulation -----------------------------------------------------------------

    def _approach_samples(self, app: ApproachSolution) -> tuple[Array, Array, Array, Array]:
        sc = self.scenario
        spline = self.approach.spline
        V = approach_vertices(spline, sc.q_initial, app.params)
        return _spline_samples(spline, V, self.ff, np.array([app.base_offset_m[0], 0.0, app.base_offset_m[1],
                                                            1.0, 0.0, 0.0, 0.0]), np.zeros(6))

    def _grasp_state(self, tr: TrackingResult, motion: TargetMotion) -> tuple[GraspState, Array]:
        """Compound state at the grasp, its momentum, and the grasp frame used (free-axis angle applied)."""
        sc = self.scenario
        T_bg = sc.target.grasp.T_body_grasp.copy()
        axis = sc.target.grasp.free_axis
        if axis is not None:
            T_bg[:3, :3] = T_bg[:3, :3] @ axis_angle_to_matrix(axis, tr.free_axis_angle_rad)
        T_ee_target = np.linalg.inv(T_bg)  # the ee frame coincides with the grasp frame at the grasp
        q, qd, x = tr.q[-1], tr.qd[-1], tr.x_base[-1]
        h_world = grasp_momentum_world(self.ff, FreeFloatingModel(compound_robot(sc, T_ee_target)), q, qd, x)
        qdd = tr.qdd_end if sc.stabilization.start_acceleration == "continuous" else np.zeros_like(qd)
        return GraspState(q, qd, qdd, x, h_world, T_ee_target), T_bg

    def _stabilization_samples(self, stab: StabilizationSolution,
                               grasp: GraspState) -> tuple[Array, Array, Array, Array]:
        spline = self.stabilization_spline
        V = stabilization_vertices(spline, grasp.q, grasp.qd, grasp.qdd, stab.params)
        ff_c = FreeFloatingModel(compound_robot(self.scenario, grasp.T_ee_target))
        return _spline_samples(spline, V, ff_c, grasp.x_base, grasp.h_world)


@dataclass
class GraspCandidate:
    """One grasp the approach reached: its approach, tracking and grasp state, ready to stabilize."""

    planner: Planner
    app: ApproachSolution
    approach_samples: tuple
    tracking: TrackingResult
    grasp: GraspState
    T_body_grasp_used: Array

    @property
    def grasp_time_s(self) -> float:
        """Grasp instant (s since the observation)."""
        ph = self.planner.scenario.phases
        return self.app.start_delay_s + ph.approach_s + ph.tracking_s

    @property
    def problem(self) -> StabilizationProblem:
        """The scenario's stabilization NLP (built on first use, kept by the planner)."""
        return self.planner.stabilization_problem

    def stabilize(self, warm_params: Array | None, max_iterations: int | None) -> StabilizationSolution:
        return self.problem.solve(self.grasp, warm_params, max_iterations)


def replace_timing(new: ApproachSolution, old: ApproachSolution) -> ApproachSolution:
    """``new``, with solve time and iterations accumulated over both solves (a warm re-solve keeps the
    scanned guess ``old`` descends from)."""
    return replace(new, solve_time_s=new.solve_time_s + old.solve_time_s, iterations=new.iterations + old.iterations,
                   start_guess=new.start_guess if new.start_guess >= 0 else old.start_guess)


def _spline_samples(spline: UniformCubicBSpline, V: Array, ff: FreeFloatingModel, x0: Array,
                    h_world: Array) -> tuple[Array, Array, Array, Array]:
    """Joint positions/velocities and the RK4-integrated base pose at :data:`SAMPLE_STEP_S`."""
    T = spline.duration_s
    n = int(np.ceil(T / SAMPLE_STEP_S))
    t = np.linspace(0.0, T, n + 1)
    q = spline.evaluate(V, t)
    qd = spline.evaluate(V, t, 1)
    mids = 0.5 * (t[:-1] + t[1:])
    x = ff.integrate_base_sampled(t, q, qd, spline.evaluate(V, mids), spline.evaluate(V, mids, 1), x0, h_world)
    return t, q, qd, x


def plan_grasp(scenario: Scenario, target_state: TargetState, warm_start: GraspPlan | None = None) -> GraspPlan:
    """Plan one grasp (builds the scenario's problems; reuse a :class:`Planner` for many states)."""
    return Planner(scenario).plan(target_state, warm_start)
