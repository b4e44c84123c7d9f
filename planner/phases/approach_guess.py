"""Initial guess of the approach NLP: when to meet, where to put the base, which arm configuration.

The NLP has many local minima (paper §1); a cold start from θ_in with an arbitrary delay often fails.
So we scan candidate meeting times over the admissible delay window, solve a small inverse-kinematics
least-squares problem for the pre-grasp pose at each (joints within limits, base offset within its
bounds, the base frozen — the arm is ~8 % of the chaser's mass, so the free-floating drift during the
approach is small and the NLP corrects it), keep the reachable, collision-free candidate with the
largest clearance, and fit Eq. 23's parameters to a smooth joint motion from θ_in to it.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.nlp_scene import build_scene, world_poses
from planner.collision.scene_distances import CollisionScene
from planner.config.scenario import Scenario
from planner.model.robot import fk_function
from planner.model.rotation import axis_angle_to_matrix
from planner.model.target import TargetMotion, TargetState
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.costs import manipulability
from planner.nlp.phase_spline import fit_approach_params
from planner.phases.approach_drift import correct_for_base_drift, ik_jacobian
from planner.phases.approach_ik import PoseIK
from planner.phases.tracking import free_axis_angle
from planner.phases.tracking_profile import TRACKING_NODES, backoff_m, smoothstep5

Array = NDArray[np.float64]

DELAY_STEP_S = 2.0  # candidate meeting times are this far apart
IK_SEED = 20261122  # fixed: same inputs, same guesses
IK_EXTRA_STARTS = 4
MIN_SEPARATION_S = 6.0  # alternative starts differ at least this much in meeting time
# node-to-node mean joint speed ≤ this × the limit, per tracking segment: the first segment follows the
# quintic blend, whose peak rate is 15/8 of its mean; later ones track the grasp frame almost uniformly
TRACKING_SPEED_MARGIN = (0.6, 0.8, 0.8)


@dataclass(frozen=True)
class ApproachGuess:
    """One NLP start: the approach's decision parameters, with the pose IK's answers it was fitted to."""

    params: Array  # (7·(N−5),) Eq. 23 free parameters, planner.nlp.phase_spline layout [rad, rad/s³]
    base_offset_m: Array  # (2,) θ_b(0): (x, z) [m]
    start_delay_s: float  # [s]
    q_pregrasp: Array  # (7,) [rad]
    q_tracking: Array  # (len(TRACKING_NODES), 7) [rad]
    clearance_m: float  # smallest distance of its configurations [m]


class MeetingOutcome(Enum):
    """What the scan found at one candidate meeting time."""

    REACHED = "reached"  # pre-grasp and tracking poses solved: a candidate NLP start
    BEYOND_REACH = "beyond reach"  # the pre-grasp is farther than the arm reaches from every admissible base offset
    IK_UNSOLVED = "IK unsolved"  # within that bound, but the bounded IK found no pre-grasp or tracking pose


@dataclass(frozen=True)
class ReachScan:
    """The scan of meeting times over the start-delay window: its NLP starts and what it found at each time."""

    guesses: list[ApproachGuess]
    window_s: float  # the start-delay window [0, window_s] [s]
    outcomes: tuple[MeetingOutcome, ...]  # one per scanned meeting time, DELAY_STEP_S apart

    @property
    def reachable(self) -> bool:
        """True when at least one meeting time gave an NLP start."""
        return MeetingOutcome.REACHED in self.outcomes

    def reason(self) -> str:
        """Why nothing was reachable, in one sentence (for an infeasible answer)."""
        beyond = self.outcomes.count(MeetingOutcome.BEYOND_REACH)
        unsolved = self.outcomes.count(MeetingOutcome.IK_UNSOLVED)
        return (f"out of reach: no meeting time within the start-delay window [0, {self.window_s:g}] s is reachable "
                f"(of {len(self.outcomes)} scanned every {DELAY_STEP_S:g} s, the pre-grasp is beyond the arm's reach "
                f"at {beyond}; at {unsolved} the arm cannot take the pre-grasp and tracking poses)")


@dataclass(frozen=True)
class _Candidate:
    """A reached meeting time, scored as an NLP start (higher: better)."""

    score: float
    clearance_m: float
    configs: list[Array]  # pre-grasp then tracking nodes, each [q (7,), b_x, b_z]
    start_delay_s: float


@dataclass(frozen=True)
class _Scan:
    """What every meeting time of one scan shares."""

    sc: Scenario
    motion: TargetMotion
    fk: ca.Function
    scene: CollisionScene
    ik: PoseIK
    S_pre: Array
    x_home: Array
    extra_starts: list[Array]


def initial_guesses(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState,
                    count: int = 3) -> list[ApproachGuess]:
    """Scan meeting times, solve the pre-grasp and tracking-node IK at each; return the ``count`` best
    NLP starts (meeting times at least :data:`MIN_SEPARATION_S` apart), best first."""
    return reach_scan(scenario, spline, state, count).guesses


def reach_scan(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int = 3) -> ReachScan:
    """:func:`initial_guesses` with what the scan found at each meeting time (deterministic)."""
    return _scan(scenario, spline, state, count)


class ScanOnDemand:
    """The scan of one target state's meeting times, made when first asked for and kept by this object.

    A plan holds one for its reach check, its approach's starts and its retries from the next guesses; a new
    plan makes a new one, so planning a state again costs what a new state costs.
    """

    def __init__(self, scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int) -> None:
        self.scenario, self.spline, self.state, self.count = scenario, spline, state, count
        self._result: ReachScan | None = None

    def serves(self, state: TargetState, count: int) -> bool:
        """True when this is the scan of ``state`` for at least ``count`` guesses (the first ``count`` serve)."""
        return count <= self.count and np.array_equal(state.attitude_wxyz, self.state.attitude_wxyz) \
            and np.array_equal(state.omega_body_rad_s, self.state.omega_body_rad_s)

    @property
    def result(self) -> ReachScan:
        """The scan (made on the first call)."""
        if self._result is None:
            self._result = reach_scan(self.scenario, self.spline, self.state, self.count)
        return self._result


def _scan(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int) -> ReachScan:
    sc = scenario
    robot = sc.robot
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    motion = sc.target.motion(state, sc.phases.max_start_delay_s + tf + t2 + 1.0)
    free = sc.target.grasp.free_axis
    # a few fixed, seeded extra starts: the IK has local minima (folded vs stretched arm)
    rng = np.random.default_rng(IK_SEED)
    extra_starts = [np.concatenate([rng.uniform(0.6 * robot.q_min, 0.6 * robot.q_max), sc.base_offset_guess_m])
                    for _ in range(IK_EXTRA_STARTS)]
    ctx = _Scan(sc, motion, fk_function(robot), build_scene(sc), PoseIK.shared(sc),
                np.eye(3) if free is None else np.column_stack([free, np.zeros(3), np.zeros(3)]),
                np.concatenate([sc.q_initial, sc.base_offset_guess_m]), extra_starts)
    x_prev = ctx.x_home
    candidates: list[_Candidate] = []
    outcomes: list[MeetingOutcome] = []
    for tau in np.arange(0.0, sc.phases.max_start_delay_s + 1e-9, DELAY_STEP_S):
        outcome, configs = _poses_at(ctx, float(tau), x_prev)
        outcomes.append(outcome)
        if configs:
            x_prev = configs[0]  # the next time's pre-grasp starts here, even if this time's tracking failed
        if outcome is MeetingOutcome.REACHED:
            candidates.append(_scored(ctx, float(tau), configs))
    if not candidates:
        # nothing reachable: hand the NLP the initial configuration and let it report infeasibility
        candidates.append(_Candidate(-np.inf, -np.inf, [ctx.x_home] * (1 + len(TRACKING_NODES)), 0.0))
    return ReachScan(_best_guesses(ctx, spline, candidates, count), sc.phases.max_start_delay_s, tuple(outcomes))


def _poses_at(ctx: _Scan, tau: float, x_prev: Array) -> tuple[MeetingOutcome, list[Array]]:
    """The pre-grasp and tracking-node configurations ``[q, b_x, b_z]`` for meeting at ``tau`` + t_f¹, as far
    as they were solved (all of them when the outcome is :attr:`MeetingOutcome.REACHED`)."""
    sc, ik = ctx.sc, ctx.ik
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    free = sc.target.grasp.free_axis
    R_g, p_g = (a[0] for a in ctx.motion.grasp_pose(tau + tf))
    p_pre = p_g - sc.approach.pregrasp_backoff_m * R_g[:, 2]
    if ik.out_of_reach(p_pre, None, (np.zeros(3), np.eye(3))):
        return MeetingOutcome.BEYOND_REACH, []
    x_pre = ik.solve(p_pre, R_g, ctx.S_pre, [x_prev, ctx.x_home, *ctx.extra_starts])
    if x_pre is None:
        return MeetingOutcome.IK_UNSOLVED, []
    b = x_pre[7:]
    R_free = np.eye(3)
    if free is not None:
        R_free = axis_angle_to_matrix(free, free_axis_angle(R_g, np.asarray(ctx.fk(x_pre[:7])[-2]), free))
    configs, x_node = [x_pre], x_pre
    for frac in TRACKING_NODES:
        t_node = frac * t2
        R_n, p_n = (a[0] for a in ctx.motion.grasp_pose(tau + tf + t_node))
        R_G = R_n @ R_free
        x_node = ik.solve(p_n - backoff_m(sc.approach.pregrasp_backoff_m, t_node, t2) * R_G[:, 2], R_G,
                          np.eye(3), [x_node, *(np.concatenate([s[:7], b]) for s in (ctx.x_home, *ctx.extra_starts))],
                          base_fixed=b)
        if x_node is None:
            return MeetingOutcome.IK_UNSOLVED, configs
        configs.append(x_node)
    return MeetingOutcome.REACHED, configs


def _scored(ctx: _Scan, tau: float, configs: list[Array]) -> _Candidate:
    """One reached meeting time as a scored NLP start."""
    sc, robot = ctx.sc, ctx.sc.robot
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    x_pre = configs[0]
    node_times = [0.0, *(f * t2 for f in TRACKING_NODES)]
    speeds = [np.abs(configs[j + 1][:7] - configs[j][:7]).max() / (node_times[j + 1] - node_times[j])
              / robot.qd_max.max() for j in range(len(TRACKING_NODES))]
    manip = np.inf
    frames: dict[str, list[Array]] = {}
    for j, x in enumerate(configs):
        R_t, _ = ctx.motion.body_pose(tau + tf + node_times[j])
        T_target = np.eye(4)
        T_target[:3, :3] = R_t[0]
        T_target[:3, 3] = sc.target.p_world_com
        poses = world_poses(robot, ctx.fk(x[:7]), np.eye(3), np.array([x[7], 0.0, x[8]]), T_target)
        for name, T in poses.items():
            frames.setdefault(name, []).append(T)
        manip = min(manip, manipulability(np.asarray(ik_jacobian(sc, x[:7]))))
    # every configuration's pairs in one sweep: the engine's cost is per call
    clearance = float(ctx.scene.sweep({name: np.array(Ts) for name, Ts in frames.items()}).distance_m.min())
    # the quintic approach path peaks at 15/8 of its mean rate: travel / t_f¹ · 15/8 ≤ the limit
    travel = float((np.abs(x_pre[:7] - sc.q_initial) / robot.qd_max).max()) * 15 / 8 / tf
    speed_excess = sum(max(s / m - 1.0, 0.0) for s, m in zip(speeds, TRACKING_SPEED_MARGIN, strict=True))
    # clearance first (capped: beyond 0.3 m it buys nothing), conditioning, then the rate limits
    score = min(clearance, 0.3) + 2.0 * min(manip, 0.1) - speed_excess - max(travel - 0.9, 0.0)
    return _Candidate(score, clearance, [c.copy() for c in configs], tau)


def _best_guesses(ctx: _Scan, spline: UniformCubicBSpline, candidates: list[_Candidate],
                  count: int) -> list[ApproachGuess]:
    """The ``count`` best candidates at least :data:`MIN_SEPARATION_S` apart, as NLP starts, best first."""
    sc, ik, motion, S_pre = ctx.sc, ctx.ik, ctx.motion, ctx.S_pre
    tf = sc.phases.approach_s
    candidates.sort(key=lambda c: -c.score)
    chosen: list[_Candidate] = []
    for cand in candidates:
        if all(abs(cand.start_delay_s - c.start_delay_s) >= MIN_SEPARATION_S for c in chosen):
            chosen.append(cand)
        if len(chosen) == count:
            break
    guesses = []
    for cand in chosen:
        configs, tau, clearance = cand.configs, cand.start_delay_s, cand.clearance_m
        if np.isfinite(clearance):
            configs = correct_for_base_drift(sc, ik, motion, configs, tau, S_pre)
        x = configs[0]
        times = np.linspace(0.0, tf, 4 * spline.n_vertices)
        q_path = sc.q_initial + np.outer(smoothstep5(times / tf), x[:7] - sc.q_initial)
        params = fit_approach_params(spline, sc.q_initial, times, q_path)
        q_tracking = np.array([c[:7] for c in configs[1:]])
        guesses.append(ApproachGuess(params, x[7:].copy(), tau, x[:7].copy(), q_tracking, clearance))
    return guesses
