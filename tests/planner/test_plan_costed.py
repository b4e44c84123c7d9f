"""A costed plan's descent (planner.plan_costed): its trust-region schedule and acceptance with stand-in solves, the
NLP's cost read back at a decision vector against Eq. 16 in closed form, and (slow) scenario II with the
approach-energy cost planned feasible, with a cost no higher than its feasibility plan's."""

from __future__ import annotations

import time
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

import planner.plan_costed as costed
from planner.config.settings import CostWeights
from planner.deadline import ANSWER_LEAD_S, NO_DEADLINE, START_LEAD_S, Deadline
from planner.nlp.costs import approach_energy

START_S = 30.0  # the grasp's start delay [s after the observation], kept by every step
QD_MAX = np.full(7, np.radians(20.0))  # the default chaser's joint-rate limits [rad/s]
_SAMPLES = SimpleNamespace(qd=np.zeros((3, 7)))  # an approach at rest: within every rate limit
ROBOT = SimpleNamespace(qd_max=QD_MAX)
UNLIMITED = SimpleNamespace(grasp_force_max_n=np.inf, grasp_torque_max_nm=np.inf)  # scenario I's grasp wrench
FEASIBILITY_WEIGHTS = CostWeights(manipulability=0.0, min_distance=0.0, approach_energy=0.0, attitude_disturbance=0.0,
                                  peak_wrench=0.0, overscale=1.0)
WRENCH_LIMITS = [SimpleNamespace(grasp_force_max_n=np.inf, grasp_torque_max_nm=10.0),  # scenario II's ±10 N·m
                 SimpleNamespace(grasp_force_max_n=50.0, grasp_torque_max_nm=np.inf)]  # a force limit alone


class _Stand:
    """A costed approach whose cost is ‖θ_b‖² and a stabilization that succeeds only within ``stable_m`` of the
    feasible grasp (per axis): the thin stabilizable set of scenario II, in one line."""

    def __init__(self, theta0: np.ndarray, stable_m: float) -> None:
        self.theta0, self.stable_m = theta0, stable_m
        self.radii: list[float] = []
        self.deadlines: list[Deadline] = []
        self.stalls: list = []  # the stall rule each step's braking was armed with
        self.approach = "costed NLP"

    def solve(self, problem, state, anchor, radius_m, scale, max_iterations, deadline):
        self.radii.append(radius_m)
        self.deadlines.append(deadline)
        theta = anchor.base_offset_m - np.clip(anchor.base_offset_m, -radius_m, radius_m)  # toward 0 inside the box
        return SimpleNamespace(success=True, base_offset_m=theta, cost=approach_energy(theta), solve_time_s=1.0,
                               start_delay_s=anchor.start_delay_s)

    def candidate(self, app):
        ok = bool(np.all(np.abs(app.base_offset_m - self.theta0) <= self.stable_m))
        stab = SimpleNamespace(success=ok, params=np.zeros(3), solve_time_s=1.0)

        def stabilize(warm, budget, screen, deadline, stall=None):
            self.stalls.append(stall)
            return stab

        return SimpleNamespace(app=app, tracking=SimpleNamespace(peak_rate_demand=1.0), approach_samples=_SAMPLES,
                               stabilize=stabilize)


def _descend(monkeypatch, stand: _Stand, deadline: Deadline = NO_DEADLINE,
             limits: SimpleNamespace = UNLIMITED) -> costed.CostDescent:
    monkeypatch.setattr(costed, "solve_approach_near", stand.solve)
    costs = replace(FEASIBILITY_WEIGHTS, approach_energy=1.0)
    planner = SimpleNamespace(approach=stand.approach, approach_and_tracking=lambda app, motion: (None, None),
                              candidate_from=lambda app, samples, tr, motion: stand.candidate(app),
                              approach_clearance=SimpleNamespace(raised_bounds=lambda app, samples, motion: (None, [])),
                              scenario=SimpleNamespace(costs=costs, limits=limits, robot=ROBOT))
    start = stand.candidate(SimpleNamespace(base_offset_m=stand.theta0.copy(), start_delay_s=START_S))
    cost = approach_energy(stand.theta0)
    out = costed.CostDescent(start, SimpleNamespace(params=np.ones(3)), {"approach_s": 0.0, "stabilization_s": 0.0},
                             [], cost, cost)
    costed._descend(planner, None, None, out, 1.0, deadline)
    return out


def test_full_step_kept_when_the_optimum_stabilizes(monkeypatch):
    """No stabilization limit near: the full step (r = ∞) reaches the optimum and the descent stops there."""
    stand = _Stand(np.array([-0.9, 0.9]), stable_m=10.0)
    d = _descend(monkeypatch, stand)
    assert stand.radii == [np.inf]
    assert d.cost_start == pytest.approx(1.62) and d.cost_end == 0.0 and (d.steps_kept, d.steps_refused) == (1, 0)


def test_thin_stabilizable_set_keeps_only_steps_inside_it(monkeypatch):
    """Stabilizable only within 0.03 m of the feasible grasp: the full step is refused, 0.02 m kept, 0.04 m refused,
    then the radius halves: the answer stays inside the set, cheaper than the start, and no refused step moves it."""
    theta0 = np.array([-0.9, 0.9])
    stand = _Stand(theta0, stable_m=0.03)
    d = _descend(monkeypatch, stand)
    assert stand.radii[:3] == [np.inf, costed.FIRST_RADIUS_M, 2 * costed.FIRST_RADIUS_M]
    theta = d.candidate.app.base_offset_m
    assert np.all(np.abs(theta - theta0) <= 0.03 + 1e-12)
    assert d.cost_end == pytest.approx(approach_energy(theta)) and d.cost_end < d.cost_start
    assert d.steps_kept >= 1 and d.steps_refused >= 2
    assert stand.stalls and all(rule is costed.STEP_STALL for rule in stand.stalls)  # a refused braking ends early
    assert min(r for r in stand.radii) >= costed.MIN_RADIUS_M
    assert len(stand.radii) <= costed.MAX_STEPS + 1


@pytest.mark.parametrize("limits", WRENCH_LIMITS)
def test_under_a_grasp_wrench_limit_no_full_step_is_tried(monkeypatch, limits):
    """Under a wrench limit (scenario II's ±10 N·m, or a force limit) the descent starts at the first radius: on the
    thin stabilizable set it tries exactly the steps the unlimited schedule tries after its refused full step and ends
    at the same grasp; where the full step would have been kept, the cost still falls, by bounded, doubling steps."""
    theta0 = np.array([-0.9, 0.9])
    full, limited = _Stand(theta0, stable_m=0.03), _Stand(theta0, stable_m=0.03)
    d_full = _descend(monkeypatch, full)
    d_limited = _descend(monkeypatch, limited, limits=limits)
    assert full.radii[0] == np.inf and limited.radii == full.radii[1:]
    assert np.array_equal(d_limited.candidate.app.base_offset_m, d_full.candidate.app.base_offset_m)
    assert (d_limited.steps_kept, d_limited.steps_refused) == (d_full.steps_kept, d_full.steps_refused - 1)
    wide = _Stand(theta0, stable_m=10.0)
    d = _descend(monkeypatch, wide, limits=limits)
    assert wide.radii[:3] == [costed.FIRST_RADIUS_M, 2 * costed.FIRST_RADIUS_M, 4 * costed.FIRST_RADIUS_M]
    assert np.all(np.isfinite(wide.radii)) and len(wide.radii) <= costed.MAX_STEPS and d.cost_end < d.cost_start


def test_nothing_stabilizes_keeps_the_feasible_grasp(monkeypatch):
    """No step stabilizes: the answer is the feasibility plan's grasp and stabilization, its cost unchanged."""
    stand = _Stand(np.array([0.5, -0.5]), stable_m=0.0)
    d = _descend(monkeypatch, stand)
    assert d.steps_kept == 0 and d.cost_end == d.cost_start == pytest.approx(0.5)
    assert np.array_equal(d.candidate.app.base_offset_m, [0.5, -0.5]) and np.array_equal(d.stabilization.params,
                                                                                          np.ones(3))


def test_past_the_deadline_no_step_is_tried(monkeypatch):
    stand = _Stand(np.array([0.5, -0.5]), stable_m=10.0)
    d = _descend(monkeypatch, stand, Deadline(0.0))
    assert stand.radii == [] and d.cost_end == d.cost_start


def test_a_live_descent_ends_the_lead_before_its_approach_starts(monkeypatch):
    """Every step keeps the meeting time, so a live plan's descent must end :data:`ANSWER_LEAD_S` before the approach's
    start (30 s after the observation), not at the budget's end (100 s): descending on, its answer would come after
    the start it plans. A table point (no observation) keeps its whole budget."""
    observed = time.monotonic()
    budget = Deadline.after(100.0, observed)
    stand = _Stand(np.array([-0.9, 0.9]), stable_m=10.0)
    _descend(monkeypatch, stand, budget.observed(observed))
    assert [d.at_s for d in stand.deadlines] == [observed + START_S - ANSWER_LEAD_S]
    stand = _Stand(np.array([-0.9, 0.9]), stable_m=10.0)
    _descend(monkeypatch, stand, budget)
    assert [d.at_s for d in stand.deadlines] == [budget.at_s]


def test_a_live_descent_whose_start_is_too_near_tries_no_step_and_says_why(monkeypatch):
    """Observed 26 s ago, an approach starting at 30 s leaves less than START_LEAD_S: a step's approach solve would end
    at once (``approach_solve.start_deadline``), so no step is started, and a note."""
    observed = time.monotonic() - (START_S - START_LEAD_S + 1.0)
    stand = _Stand(np.array([0.5, -0.5]), stable_m=10.0)
    d = _descend(monkeypatch, stand, Deadline.after(100.0, observed).observed(observed))
    assert stand.radii == [] and d.cost_end == d.cost_start
    assert any(f"the descent stopped {START_LEAD_S:g} s before the approach's start at 30.0 s" in n for n in d.notes)


class _Direct:
    """The stand-ins of a costed plan's stages: the costed approach's own optimum at ``cost``, braked or not, and a
    feasibility GraspSearch that records how it was made and returns a grasp at cost 0.5."""

    def __init__(self, monkeypatch, braked: bool, cost: float = 1e-9, limits: SimpleNamespace = UNLIMITED) -> None:
        self.approach_calls, self.searches, self.feasibility_built = [], [], False
        stab = SimpleNamespace(success=braked, params=np.zeros(3), solve_time_s=2.0)
        self.app = SimpleNamespace(success=True, cost=cost, solve_time_s=3.0, base_offset_m=np.zeros(2))
        self.candidate = SimpleNamespace(app=self.app, tracking=SimpleNamespace(peak_rate_demand=1.0),
                                         approach_samples=_SAMPLES, stabilize=lambda *args: stab)
        feasible_app = SimpleNamespace(success=True, base_offset_m=np.array([0.5, 0.5]))
        feasible = SimpleNamespace(app=feasible_app, stabilization=None)
        outer = self

        class Search:
            def __init__(self, *args):
                outer.searches.append(args)
                self.notes, self.tracking_speed_scale = ["feasibility note"], np.ones(3)

            def run(self):
                return feasible, SimpleNamespace(success=True, params=np.ones(3))

            def timings_s(self):
                return {"approach_s": 10.0, "stabilization_s": 20.0}

        monkeypatch.setattr(costed, "GraspSearch", Search)
        monkeypatch.setattr(costed, "solve_approach", self.solve)
        monkeypatch.setattr(costed, "approach_cost", lambda problem, state, app: approach_energy(app.base_offset_m))
        self.descents: list[Deadline] = []
        monkeypatch.setattr(costed, "_descend", lambda *args: self.descents.append(args[-1]))
        self.planner = SimpleNamespace(approach="costed NLP", approach_and_tracking=lambda app, motion: (None, None),
                                       candidate_from=lambda app, samples, tr, motion: self.candidate,
                                       approach_clearance=SimpleNamespace(raised_bounds=lambda *args: (None, [])),
                                       scenario=SimpleNamespace(robot=ROBOT, limits=limits))

    def solve(self, problem, state, warm, scan, max_iterations, deadline):
        self.approach_calls.append((problem, max_iterations, deadline))
        return self.app

    def plan(self, deadline: Deadline = NO_DEADLINE, grasp_by: Deadline | None = None) -> costed.CostDescent:
        return costed.plan_costed(self.planner, self.feasibility, None, None, "scan", None, deadline, grasp_by)

    def feasibility(self) -> str:
        self.feasibility_built = True
        return "feasibility"


def test_a_braked_costed_optimum_needs_no_feasibility_plan(monkeypatch):
    """Scenario I: the costed approach's own optimum can be braked, so it is the plan's grasp at once (the
    feasibility stage cost 68-99 s at some flat spins and its grasp is then dropped anyway)."""
    d = _Direct(monkeypatch, braked=True)
    out = d.plan()
    assert d.searches == [] and not d.feasibility_built  # not even built (1.9 s of a cold plan)
    assert out.candidate is d.candidate and out.cost_start == out.cost_end == 1e-9
    assert d.approach_calls == [("costed NLP", costed.COSTED_APPROACH_ITERATIONS, NO_DEADLINE)]
    assert out.timings_s == {"approach_s": 3.0, "stabilization_s": 2.0}
    assert "no feasibility plan needed" in out.notes[0] and "at the costed approach's own optimum" in out.notes[-1]


def test_an_unbraked_costed_optimum_falls_back_to_the_feasibility_plan(monkeypatch):
    """Scenario II: the costed optimum cannot be braked; the feasibility stage gives the grasp the descent starts
    from, and the costed optimum is not solved a second time. The feasibility stage caps its re-solves: with tightened
    rates they ran 496-759 iterations (68-99 s) at scenario I flat spins."""
    d = _Direct(monkeypatch, braked=False)
    out = d.plan()
    assert len(d.approach_calls) == 1 and len(d.searches) == 1
    assert d.searches[0][0] == "feasibility" and d.searches[0][-1] == costed.FEASIBILITY_RESOLVE_ITERATIONS
    assert 0 < costed.FEASIBILITY_RESOLVE_ITERATIONS < 496
    assert out.cost_start == out.cost_end == pytest.approx(0.5)
    assert out.timings_s == {"approach_s": 13.0, "stabilization_s": 22.0}
    assert "feasibility note" in out.notes and "at the feasibility plan's grasp" in out.notes[-1]


@pytest.mark.parametrize("limits", WRENCH_LIMITS)
@pytest.mark.parametrize("braked", [False, True])
def test_under_a_grasp_wrench_limit_the_costed_optimum_is_not_tried(monkeypatch, limits, braked):
    """Scenario II's ±10 N·m (or a force limit): the costed approach's own optimum lies outside the grasps that can be
    braked, so no costed solve is made, even where it would have been braked; the feasibility plan's grasp comes
    first, with all of the time, and the note says why."""
    d = _Direct(monkeypatch, braked=braked, limits=limits)
    out = d.plan(Deadline.after(100.0))
    assert d.approach_calls == [] and len(d.searches) == 1 and d.feasibility_built
    assert out.cost_start == pytest.approx(0.5) and out.timings_s == {"approach_s": 10.0, "stabilization_s": 20.0}
    assert "is not tried under the grasp-wrench limit" in out.notes[0]


def test_the_costed_optimum_gets_half_of_a_bounded_budget(monkeypatch):
    """Where it cannot be braked, the feasibility plan keeps the other half of what is left; without a budget it is
    unbounded."""
    d = _Direct(monkeypatch, braked=True)
    d.plan(Deadline.after(100.0))
    d.plan()
    bounded, unbounded = d.approach_calls[0][2], d.approach_calls[1][2]
    assert bounded.remaining_s() == pytest.approx(50.0, abs=0.5) and not unbounded.bounded


def test_a_live_costed_optimum_leaves_the_feasibility_stage_a_meeting_in_time(monkeypatch):
    """Scenario II's default state meets only between 16 and 40 s: a live plan's costed optimum ends 20 s after the
    observation, not at half the budget (50 s: no meeting left for the feasibility plan). Offline it keeps its half;
    a share that ends sooner is kept."""
    d = _Direct(monkeypatch, braked=True)
    observed = time.monotonic()
    budget = Deadline.after(100.0, observed)
    d.plan(budget.observed(observed))
    d.plan(budget)
    d.plan(Deadline.after(30.0, observed).observed(observed))
    live, offline, short = (call[2] for call in d.approach_calls)
    assert live.at_s == observed + costed.LIVE_DIRECT_S and live.observed_at_s == observed
    assert offline.remaining_s() == pytest.approx(50.0, abs=0.5) and short.remaining_s() == pytest.approx(15.0, abs=0.5)


@pytest.mark.parametrize("braked", [True, False])
def test_the_grasp_is_due_by_grasp_by_and_the_descent_runs_to_the_deadline(monkeypatch, braked):
    """A warm plan that a cold one follows (a build point) must find its braked grasp within its share: the costed
    optimum gets half of that share, the feasibility search all of it; the descent from the grasp found still runs
    to the plan's deadline."""
    d = _Direct(monkeypatch, braked=braked)
    deadline, grasp_by = Deadline.after(100.0), Deadline.after(40.0)
    d.plan(deadline, grasp_by)
    assert d.approach_calls[0][2].remaining_s() == pytest.approx(20.0, abs=0.5)
    assert [s[5] for s in d.searches] == ([] if braked else [grasp_by])
    assert d.descents == [deadline]


def test_a_spent_budget_solves_no_costed_optimum(monkeypatch):
    """The budget already spent (a build point at its timeout): no costed solve starts, and the feasibility search,
    which ends at once past its deadline with the unsolved grasp it has, still gives the answer."""
    d = _Direct(monkeypatch, braked=True)
    out = d.plan(Deadline(0.0))
    assert d.approach_calls == [] and len(d.searches) == 1 and d.feasibility_built
    assert out.timings_s == {"approach_s": 10.0, "stabilization_s": 20.0} and "feasibility note" in out.notes


@pytest.fixture(scope="module")
def energy_problem():
    from planner.config.scenario import load_scenario
    from planner.phases.approach import ApproachProblem

    return ApproachProblem(load_scenario("configs/scenarios/scenario_I_energy.toml"))


def test_objective_at_is_eq16_for_the_energy_variant(energy_problem):
    """The NLP's cost read back at a decision vector equals ‖θ_b(0)‖² (Eq. 16, weight 1) for any θ_b, the arm's
    parameters and the state playing no part."""
    from planner.config.scenario import load_scenario

    state = load_scenario("configs/scenarios/scenario_I.toml").target_state.as_state()
    rng = np.random.default_rng(16)
    p = energy_problem
    for theta in (np.zeros(2), np.array([-1.0, 1.0]), rng.uniform(-1, 1, 2)):
        w = np.clip(rng.uniform(-0.3, 0.3, p.n_w), p.lbw[: p.n_w], p.ubw[: p.n_w])
        w[p.decision.slice("base_offset_m")] = theta
        assert p.objective_at(w, state) == pytest.approx(approach_energy(theta), rel=1e-12, abs=1e-15)


@pytest.mark.slow
def test_scenario_II_energy_plans_feasible_no_costlier_than_its_feasibility_plan():
    """Scenario II with Eq. 16: feasible by verify (the costed approach alone ends at a grasp no ±10 N·m braking
    exists from), with θ_b(0) no farther from the origin than the feasibility plan's."""
    from planner.config.scenario import load_scenario
    from planner.plan import Planner
    from planner.verify.verifier import verify

    sc = load_scenario("configs/scenarios/scenario_II_energy.toml")
    state = sc.target_state.as_state()
    plan = Planner(sc).plan(state)
    feasible = Planner(replace(sc, costs=sc.costs.without_approach_terms())).plan(state)
    assert verify(plan).feasible, verify(plan).violations
    assert approach_energy(plan.approach.base_offset_m) <= approach_energy(feasible.approach.base_offset_m) + 1e-12


@pytest.mark.slow
def test_scenario_II_energy_planned_live_answers_before_its_approach_starts():
    """Planned live (its observation at the call), scenario II with Eq. 16 verifies feasible and its approach starts
    after the plan and its verification are done: before, its costed optimum ran to half the budget, past every
    meeting time the default state reaches (16-40 s), and the plan was refused as late."""
    from planner.config.scenario import load_scenario
    from planner.plan import Planner
    from planner.verify.verifier import verify

    sc = load_scenario("configs/scenarios/scenario_II_energy.toml")
    planner = Planner(sc)
    observed = time.monotonic()
    plan = planner.plan(sc.target_state.as_state(), deadline=Deadline.after(100.0, observed).observed(observed))
    assert verify(plan).feasible, verify(plan).violations
    assert plan.approach.start_delay_s > time.monotonic() - observed


def test_the_feasibility_stage_shares_all_but_the_approach_nlp():
    """The costed plan's first stage differs from the costed planner only by its approach costs: one models, tracking
    and stabilization NLP between them (built once), its own approach NLP without costs, the costed one untouched."""
    from planner.config.scenario import load_scenario
    from planner.plan import Planner

    costed_planner = Planner(load_scenario("configs/scenarios/scenario_II_energy.toml"))
    stage = costed_planner.feasibility_planner
    assert stage is costed_planner.feasibility_planner
    assert stage.ff is costed_planner.ff and stage.tracking is costed_planner.tracking
    assert stage.stabilization_problem is costed_planner.stabilization_problem
    assert stage.approach is not costed_planner.approach and stage.approach.ff is costed_planner.ff
    assert not stage.scenario.costs.weights_approach and costed_planner.scenario.costs.approach_energy == 1.0
    assert stage.scenario.costs.without_approach_terms() == stage.scenario.costs


@pytest.mark.parametrize(("rate", "approach_rate", "dips", "kept"), [
    (1.0, 0.97, [], True),  # on the via points' bound
    (1.0, 1.0, [], True),  # at the limit itself
    (1.3, 0.5, [], False),  # the tracking asks too much
    (1.0, 1.0 + 1e-9, [], False),  # the approach's spline past a rate limit between its via points
    (1.0, -1.03, [], False),  # the same in the negative direction (scenario II's safety descent: 1.03× the limit)
    (1.0, 0.5, ["a dip"], False),  # a dip below the clearance between via points
])
def test_a_costed_grasp_must_track_and_keep_its_limits_between_via_points(rate, approach_rate, dips, kept):
    planner = SimpleNamespace(approach_clearance=SimpleNamespace(raised_bounds=lambda app, samples, motion: (None,
                                                                                                            dips)),
                              scenario=SimpleNamespace(robot=ROBOT))
    qd = np.zeros((5, 7))
    qd[2, 6] = approach_rate * QD_MAX[6]  # joint 7, mid-approach
    candidate = SimpleNamespace(app=None, approach_samples=SimpleNamespace(qd=qd),
                                tracking=SimpleNamespace(peak_rate_demand=rate))
    assert costed._trackable(planner, candidate, None) is kept


@pytest.mark.parametrize(("weights", "cost", "floor"), [
    ({"approach_energy": 1.0}, 3e-9, True),  # Eq. 16 alone is ≥ 0: nothing left to gain
    ({"approach_energy": 1.0}, 0.0727, False),
    ({"approach_energy": 1.0}, costed.RELATIVE_GAIN_MIN, False),  # exactly what a step must gain: still tried
    ({"approach_energy": 1.0, "manipulability": 1.0}, 3e-9, False),  # −manipulability has no floor
    ({"min_distance": 1.0}, -0.5, False),
])
def test_the_descent_stops_only_where_no_step_can_gain(weights, cost, floor):
    costs = replace(FEASIBILITY_WEIGHTS, **weights)
    assert costed._at_its_floor(SimpleNamespace(scenario=SimpleNamespace(costs=costs)), cost) is floor
