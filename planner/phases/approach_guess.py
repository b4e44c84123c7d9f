"""Initial guess of the approach NLP: when to meet, where to put the base, which arm configuration.

The NLP has many local minima (paper §1); a cold start from θ_in with an arbitrary delay often fails.
So we scan candidate meeting times over the admissible delay window, solve a small inverse-kinematics
least-squares problem for the pre-grasp pose at each (joints within limits, base offset within its
bounds, the base frozen — the arm is ~8 % of the chaser's mass, so the free-floating drift during the
approach is small and the NLP corrects it), keep the reachable, collision-free candidate with the
largest clearance, and fit Eq. 23's parameters to a smooth joint motion from θ_in to it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

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
from planner.phases.approach_start import StartClearance, starts_elsewhere_in_box
from planner.phases.pregrasp_pose import at_own_angle, free_axis_turn, pregrasp_position
from planner.phases.reach_proof import reach_proof
from planner.phases.reach_scan_result import ApproachGuess, MeetingOutcome, ReachScan, scan_times_s
from planner.phases.tracking import free_axis_angle
from planner.phases.tracking_profile import TRACKING_NODES, backoff_m, smoothstep5

Array = NDArray[np.float64]

IK_SEED = 20261122  # fixed: same inputs, same guesses
IK_EXTRA_STARTS = 4
# a scan whose IK reached no meeting time from near the base-offset guess scans again, starting also from each point of
# this square grid over the base-offset box: started near the guess alone, a scenario I flat spin answered out of reach
# planned feasible in 5.8 s with the guess moved to (1, 0) m
BASE_STARTS_PER_AXIS = 3
MIN_SEPARATION_S = 6.0  # alternative starts differ at least this much in meeting time
# node-to-node mean joint speed ≤ this × the limit, per tracking segment: the first segment follows the
# quintic blend, whose peak rate is 15/8 of its mean; later ones track the grasp frame almost uniformly
TRACKING_SPEED_MARGIN = (0.6, 0.8, 0.8)
# a grasp free about an axis is also scanned held at these angles about it (from the configured grasp frame): the
# angle the arm holds the handle at decides whether braking fits the wrench and joint limits, and the IK's own choice
# follows one branch across the whole window; each angle adds one guess after the scan's own
FREE_AXIS_ANGLES_DEG = (0.0, 90.0, 180.0, 270.0)
ANGLE_SEPARATION_RAD = np.radians(20.0)  # guesses this far apart about the free axis reach different grasps


@dataclass(frozen=True)
class _Candidate:
    """A reached meeting time, scored as an NLP start (higher: better)."""

    score: float
    clearance_m: float
    configs: list[Array]  # pre-grasp then tracking nodes, each [q (7,), b_x, b_z]
    start_delay_s: float
    free_axis_angle_rad: float | None  # about a free grasp axis, from the configured grasp frame [rad]
    ctx: _Scan  # the scan it was found in (its grasp frame)
    # θ_in at its base offset is clear of the target at the approach's start (planner.phases.approach_start)
    start_clear: bool = True

    @property
    def rank(self) -> tuple[bool, float]:
        """Sort key, best first: a clear start before any other, then the score."""
        return not self.start_clear, -self.score


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
    state: TargetState
    start: StartClearance  # θ_in's clearance from the target at the approach's start
    held_rad: float | None = None  # the angle about the free grasp axis the grasp frame is held at [rad]
    # per other point of the base-offset box, the starts with the base there: a scan that reached no meeting time
    # from near the guess scans again with them
    base_starts: tuple[list[Array], ...] = ()


def initial_guesses(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState,
                    count: int = 3) -> list[ApproachGuess]:
    """Scan meeting times, solve the pre-grasp and tracking-node IK at each; return the ``count`` best
    NLP starts (meeting times at least :data:`MIN_SEPARATION_S` apart), best first."""
    return reach_scan(scenario, spline, state, count).guesses


def reach_scan(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int = 3,
               held_angles: bool = True) -> ReachScan:
    """:func:`initial_guesses` with what the scan found at each meeting time (deterministic). ``held_angles``: for a
    free grasp axis, also the guesses held at :data:`FREE_AXIS_ANGLES_DEG` (a reach check or a search that starts from
    the best few alone does not need them; they do not change the reach verdict)."""
    return _scan(scenario, spline, state, count, held_angles)


class ScanOnDemand:
    """The scan of one target state's meeting times, made when first asked for and kept by this object.

    A plan holds one for its reach check, its approach's starts and its retries from the next guesses; a new
    plan makes a new one, so planning a state again costs what a new state costs.
    """

    def __init__(self, scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int,
                 held_angles: bool = True) -> None:
        """``held_angles``: as :func:`reach_scan`'s."""
        self.scenario, self.spline, self.state, self.count = scenario, spline, state, count
        self.held_angles = held_angles
        self._result: ReachScan | None = None

    def serves(self, state: TargetState, count: int) -> bool:
        """True when this is the scan of ``state`` for at least ``count`` guesses (the first ``count`` serve)."""
        return count <= self.count and np.array_equal(state.attitude_wxyz, self.state.attitude_wxyz) \
            and np.array_equal(state.omega_body_rad_s, self.state.omega_body_rad_s)

    @property
    def made(self) -> bool:
        """True once the scan has been made."""
        return self._result is not None

    @property
    def result(self) -> ReachScan:
        """The scan (made on the first call)."""
        if self._result is None:
            self._result = reach_scan(self.scenario, self.spline, self.state, self.count, self.held_angles)
        return self._result


def _scan(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int,
          held_angles: bool) -> ReachScan:
    sc = scenario
    proof = reach_proof(sc, state)
    if proof.proven:  # no plan reaches the grasp at any meeting time: the IK need not be asked
        return ReachScan([], sc.phases.start_delay_window_s, (), proof)
    robot = sc.robot
    free = sc.target.grasp.free_axis
    # a few fixed, seeded extra starts: the IK has local minima (folded vs stretched arm)
    rng = np.random.default_rng(IK_SEED)
    extra_starts = [np.concatenate([rng.uniform(0.6 * robot.q_min, 0.6 * robot.q_max), sc.base_offset_guess_m])
                    for _ in range(IK_EXTRA_STARTS)]
    motion, scene = sc.target.motion(state, _horizon_s(sc)), build_scene(sc)
    x_home = np.concatenate([sc.q_initial, sc.base_offset_guess_m])
    ctx = _Scan(sc, motion, fk_function(robot), scene, PoseIK.shared(sc),
                np.eye(3) if free is None else np.column_stack([free, np.zeros(3), np.zeros(3)]),
                x_home, extra_starts, state, StartClearance(sc, scene, motion))
    times = scan_times_s(sc.phases.start_delay_window_s)
    candidates, outcomes = _scan_window(ctx, times)
    if not candidates:  # before answering out of reach, the IK starts from the rest of the base-offset box too
        elsewhere = starts_elsewhere_in_box(sc, [x_home, *extra_starts], BASE_STARTS_PER_AXIS)
        candidates, outcomes = _scan_window(replace(ctx, base_starts=tuple(elsewhere)), times)
    if not candidates:
        # nothing reachable: hand the NLP the initial configuration and let it report infeasibility
        candidates.append(_Candidate(-np.inf, -np.inf, [ctx.x_home] * (1 + len(TRACKING_NODES)), 0.0, None, ctx))
    reached = [c.start_delay_s for c in candidates if np.isfinite(c.score)]
    held = [] if free is None or not reached or not held_angles else \
        [_scan_window(_held_at(ctx, np.radians(a)), reached)[0] for a in FREE_AXIS_ANGLES_DEG]
    return ReachScan(_best_guesses(spline, _diverse(candidates, held, count)), sc.phases.start_delay_window_s,
                     tuple(outcomes), proof)


def _horizon_s(sc: Scenario) -> float:
    """How far the scan predicts the target [s]: the start-delay window, the approach and the tracking, and 1 s."""
    return sc.phases.max_start_delay_s + sc.phases.approach_s + sc.phases.tracking_s + 1.0


def _held_at(ctx: _Scan, angle_rad: float) -> _Scan:
    """``ctx`` with its grasp frame turned by ``angle_rad`` about the free grasp axis and held there (the IK then
    matches the whole orientation)."""
    sc = ctx.sc
    grasp = sc.target.grasp
    T_body_grasp = grasp.T_body_grasp.copy()
    T_body_grasp[:3, :3] = T_body_grasp[:3, :3] @ axis_angle_to_matrix(grasp.free_axis, angle_rad)
    body = replace(sc.target.body(), T_body_grasp=T_body_grasp)
    return replace(ctx, motion=TargetMotion(body, ctx.state, _horizon_s(sc)), S_pre=np.eye(3), held_rad=angle_rad)


def _scan_window(ctx: _Scan, times_s: list[float]) -> tuple[list[_Candidate], list[MeetingOutcome]]:
    """The scored candidates of the meeting times ``times_s`` [s] (start delays, in order) and what each gave."""
    x_prev = ctx.x_home
    candidates: list[_Candidate] = []
    outcomes: list[MeetingOutcome] = []
    for tau in times_s:
        outcome, configs = _poses_at(ctx, tau, x_prev)
        outcomes.append(outcome)
        if configs:
            x_prev = configs[0]  # the next time's pre-grasp starts here, even if this time's tracking failed
        if outcome is MeetingOutcome.REACHED:
            candidates.append(_scored(ctx, tau, configs))
    return candidates, outcomes


def _poses_at(ctx: _Scan, tau: float, x_prev: Array) -> tuple[MeetingOutcome, list[Array]]:
    """The pre-grasp and tracking-node configurations ``[q, b_x, b_z]`` for meeting at ``tau`` + t_f¹, as far
    as they were solved (all of them when the outcome is :attr:`MeetingOutcome.REACHED`). Should the starts near the
    guess not lead to the tracking poses, the pre-grasp is solved again from each other point of the base-offset box
    (``ctx.base_starts``), the base pulled toward that point, and kept only if its tracking poses are solved."""
    sc, ik = ctx.sc, ctx.ik
    R_g, p_g = (a[0] for a in ctx.motion.grasp_pose(tau + sc.phases.approach_s))
    p_pre = pregrasp_position(sc, R_g, p_g)
    if ik.out_of_reach(p_pre, None, (np.zeros(3), np.eye(3))):
        return MeetingOutcome.BEYOND_REACH, []
    x_pre = ik.solve(p_pre, R_g, ctx.S_pre, [x_prev, ctx.x_home, *ctx.extra_starts])
    first = (MeetingOutcome.IK_UNSOLVED, []) if x_pre is None else _tracking_from(ctx, tau, R_g, p_g, x_pre)
    if first[0] is MeetingOutcome.REACHED:
        return first
    for starts in ctx.base_starts:
        x_pre = ik.solve(p_pre, R_g, ctx.S_pre, starts, own_base=True)
        if x_pre is None:
            continue
        elsewhere = _tracking_from(ctx, tau, R_g, p_g, x_pre)
        if elsewhere[0] is MeetingOutcome.REACHED:
            return elsewhere
    return first


def _tracking_from(ctx: _Scan, tau: float, R_g: Array, p_g: Array, x_pre: Array) -> tuple[MeetingOutcome,
                                                                                         list[Array]]:
    """The tracking poses from the pre-grasp ``x_pre``, turned first to the angle the IK chose about a free grasp
    axis (:func:`_tracking_poses_from`)."""
    firsts = [x_pre]
    if ctx.held_rad is None:  # the IK chose the angle about a free axis: back off along the frame at that angle
        turned = at_own_angle(ctx.sc, ctx.ik, R_g, p_g, x_pre, np.asarray(ctx.fk(x_pre[:7])[-2]))
        firsts = [turned, x_pre] if turned is not x_pre else firsts
    for x in firsts:  # should the tracking poses fail from the turned pre-grasp, the NLP still starts near the IK's
        outcome, configs = _tracking_poses_from(ctx, tau, R_g, x)
        if outcome is MeetingOutcome.REACHED:
            break
    return outcome, configs


def _tracking_poses_from(ctx: _Scan, tau: float, R_g: Array, x_pre: Array) -> tuple[MeetingOutcome, list[Array]]:
    """``x_pre`` and the tracking-node configurations from it (base pinned at its offset), as far as solved."""
    sc, ik = ctx.sc, ctx.ik
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    b = x_pre[7:]
    R_free = free_axis_turn(sc, R_g, np.asarray(ctx.fk(x_pre[:7])[-2])) if ctx.held_rad is None else np.eye(3)
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


def _angle_about_free_axis(ctx: _Scan, R_world_grasp: Array, x: Array) -> float:
    """The angle about the free grasp axis at which configuration ``x`` holds the grasp frame ``R_world_grasp``
    [rad]: ``ctx``'s held angle plus the IK's own turn."""
    R_ee = np.asarray(ctx.fk(x[:7])[-2])
    return (ctx.held_rad or 0.0) + free_axis_angle(R_world_grasp, R_ee, ctx.sc.target.grasp.free_axis)


def _scored(ctx: _Scan, tau: float, configs: list[Array]) -> _Candidate:
    """One reached meeting time as a scored NLP start."""
    sc, robot = ctx.sc, ctx.sc.robot
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    x_pre = configs[0]
    node_times = [0.0, *(f * t2 for f in TRACKING_NODES)]
    speeds = [np.abs(configs[j + 1][:7] - configs[j][:7]).max() / (node_times[j + 1] - node_times[j])
              / robot.qd_max.max() for j in range(len(TRACKING_NODES))]
    manip = min(manipulability(np.asarray(ik_jacobian(sc, x[:7]))) for x in configs)
    clearance = float(_distances(ctx, configs, [tau + tf + t for t in node_times]).min())
    # the quintic approach path peaks at 15/8 of its mean rate: travel / t_f¹ · 15/8 ≤ the limit
    travel = float((np.abs(x_pre[:7] - sc.q_initial) / robot.qd_max).max()) * 15 / 8 / tf
    speed_excess = sum(max(s / m - 1.0, 0.0) for s, m in zip(speeds, TRACKING_SPEED_MARGIN, strict=True))
    # clearance first (capped: beyond 0.3 m it buys nothing), conditioning, then the rate limits
    score = min(clearance, 0.3) + 2.0 * min(manip, 0.1) - speed_excess - max(travel - 0.9, 0.0)
    psi = None
    if sc.target.grasp.free_axis is not None:
        psi = _angle_about_free_axis(ctx, ctx.motion.grasp_pose(tau + tf)[0][0], x_pre)
    return _Candidate(score, clearance, [c.copy() for c in configs], tau, psi, ctx,
                      ctx.start.is_clear(x_pre[7:], tau))


def _distances(ctx: _Scan, configs: list[Array], times_s: list[float]) -> Array:
    """Every pair's signed distance (n, pairs) [m] of the chaser in each configuration ``[q, b_x, b_z]`` against the
    target at the matching time [s] (the base frozen, as in the scan's IK)."""
    frames: dict[str, list[Array]] = {}
    for x, t in zip(configs, times_s, strict=True):
        poses = world_poses(ctx.sc.robot, ctx.fk(x[:7]), np.eye(3), np.array([x[7], 0.0, x[8]]),
                            ctx.motion.T_world_body(t))
        for name, T in poses.items():
            frames.setdefault(name, []).append(T)
    # every configuration's pairs in one sweep: the engine's cost is per call
    return ctx.scene.sweep({name: np.array(Ts) for name, Ts in frames.items()}).distance_m


def _diverse(candidates: list[_Candidate], held: list[list[_Candidate]], count: int) -> list[_Candidate]:
    """Up to ``count`` of the scan's own candidates, best first and pairwise distinct (:func:`_distinct`), then the
    best distinct candidate of each held angle (the angle with the best candidate first): a grasp held at another
    angle about a free axis is braked differently, and is tried once the scan's own grasps are."""
    chosen: list[_Candidate] = []
    _take(sorted(candidates, key=lambda c: c.rank), chosen, count)
    for pool in sorted((sorted(h, key=lambda c: c.rank) for h in held if h), key=lambda pool: pool[0].rank):
        _take(pool, chosen, len(chosen) + 1)
    return chosen


def _take(pool: list[_Candidate], chosen: list[_Candidate], up_to: int) -> None:
    """Append to ``chosen`` the candidates of ``pool`` distinct from it, in order, until it holds ``up_to``."""
    for candidate in pool:
        if len(chosen) >= up_to:
            return
        if _distinct(candidate, chosen):
            chosen.append(candidate)


def _distinct(candidate: _Candidate, chosen: list[_Candidate]) -> bool:
    """True when ``candidate`` meets at least :data:`MIN_SEPARATION_S` from each of ``chosen``, or holds the handle at
    least :data:`ANGLE_SEPARATION_RAD` about the free axis from it."""
    return all(abs(candidate.start_delay_s - c.start_delay_s) >= MIN_SEPARATION_S
               or angles_apart(candidate.free_axis_angle_rad, c.free_axis_angle_rad) for c in chosen)


def angles_apart(a_rad: float | None, b_rad: float | None) -> bool:
    """True when two grasps hold the handle at least :data:`ANGLE_SEPARATION_RAD` apart about the free axis (never
    when either angle is unknown, None)."""
    if a_rad is None or b_rad is None:
        return False
    return abs((a_rad - b_rad + np.pi) % (2 * np.pi) - np.pi) >= ANGLE_SEPARATION_RAD


def _best_guesses(spline: UniformCubicBSpline, chosen: list[_Candidate]) -> list[ApproachGuess]:
    """The ``chosen`` candidates as NLP starts, in order: the base's drift corrected, Eq. 23's parameters fitted."""
    guesses = []
    for cand in chosen:
        sc, configs, tau, clearance = cand.ctx.sc, cand.configs, cand.start_delay_s, cand.clearance_m
        tf, psi = sc.phases.approach_s, cand.free_axis_angle_rad
        if np.isfinite(clearance):
            configs = _drift_corrected(cand)
            if psi is not None:  # the correction's IK may turn a free grasp about its axis
                psi = _angle_about_free_axis(cand.ctx, cand.ctx.motion.grasp_pose(tau + tf)[0][0], configs[0])
        x = configs[0]
        times = np.linspace(0.0, tf, 4 * spline.n_vertices)
        q_path = sc.q_initial + np.outer(smoothstep5(times / tf), x[:7] - sc.q_initial)
        params = fit_approach_params(spline, sc.q_initial, times, q_path)
        q_tracking = np.array([c[:7] for c in configs[1:]])
        guesses.append(ApproachGuess(params, x[7:].copy(), tau, x[:7].copy(), q_tracking, clearance, psi))
    return guesses


def _drift_corrected(cand: _Candidate) -> list[Array]:
    """``cand``'s configurations corrected for the base's drift (:func:`correct_for_base_drift`), or its own where the
    correction would put a clear start inside the target: the NLP corrects a drift, but rarely converges from there."""
    ctx = cand.ctx
    corrected = correct_for_base_drift(ctx.sc, ctx.ik, ctx.motion, cand.configs, cand.start_delay_s, ctx.S_pre)
    if cand.start_clear and not ctx.start.is_clear(corrected[0][7:], cand.start_delay_s):
        return cand.configs
    return corrected
