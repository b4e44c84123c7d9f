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
from numpy.typing import ArrayLike, NDArray

from planner.collision.nlp_scene import build_scene, world_poses
from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel
from planner.model.robot import fk_function
from planner.model.rotation import axis_angle_to_matrix, quat_to_matrix
from planner.model.target import TargetBody, TargetMotion, TargetState
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.phase_spline import fit_approach_params
from planner.nlp.costs import manipulability
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
REACH_TOLERANCE = 1e-3  # pose residual (m, rad) below which a pose counts as reachable
REGULARISATION = 0.02  # weight pulling the IK toward θ_in and the base-offset guess (1/rad, 1/m)
# the polish keeps a little of it: with none, the redundant arm and the base drift to their bounds
POLISH_REGULARISATION = 2e-3
# a start whose regularised solve leaves a larger pose residual (m, rad) is not polished: measured over the
# scans of 18 target states per scenario (3897 starts), every start the polish took below REACH_TOLERANCE
# had left at most 0.015 here, and skipping the hopeless polishes saves 16 % of the scan's evaluations
POLISH_WORTHWHILE_ERROR = 0.1


@dataclass(frozen=True)
class ApproachGuess:
    params: Array
    base_offset_m: Array
    start_delay_s: float
    q_pregrasp: Array
    q_tracking: Array  # (len(TRACKING_NODES), 7)
    clearance_m: float


def target_motion(scenario: Scenario, state: TargetState, t_end_s: float) -> TargetMotion:
    """Accurate torque-free motion of the scenario's target from the observed ``state``."""
    t = scenario.target
    return TargetMotion(TargetBody(t.mass_kg, t.inertia_body_kg_m2, t.p_world_com, t.grasp.T_body_grasp),
                        state, t_end_s)


def _ik_residual_function(scenario: Scenario) -> ca.Function:
    """``(x = [q, b_x, b_z], p_goal, R_goal, S) -> (residual, jacobian)`` of a pose IK with the base frozen.

    Orientation residual ``(R_ee − R_goal) S``: S = I matches the whole orientation, S = [a 0 0] only
    the free axis a. Smooth, and free of the spurious minima of sin-based errors at large angles.
    """
    sc = scenario
    x = ca.SX.sym("x", sc.robot.n_joints + 2)
    p_goal = ca.SX.sym("p_goal", 3)
    R_goal = ca.SX.sym("R_goal", 3, 3)
    S = ca.SX.sym("S", 3, 3)
    weight = ca.SX.sym("weight")
    dp = ca.SX.sym("drift_p", 3)  # base drift since t = 0 (free-floating), held fixed in the IK
    dR = ca.SX.sym("drift_R", 3, 3)
    base_given = ca.SX.sym("base_given", 2)  # used instead of x[-2:] when fix_base = 1
    fix_base = ca.SX.sym("fix_base")
    base = fix_base * base_given + (1 - fix_base) * x[-2:]
    out = fk_function(sc.robot)(x[:-2])
    p_ee = ca.vertcat(base[0], 0.0, base[1]) + dp + ca.mtimes(dR, out[-1])
    rot = ca.reshape(ca.mtimes(ca.mtimes(dR, out[-2]) - R_goal, S), 9, 1)
    reg = weight * ca.vertcat(x[:-2] - ca.DM(sc.q_initial), x[-2:] - ca.DM(sc.base_offset_guess_m))
    r = ca.vertcat(p_ee - p_goal, rot, reg)
    return ca.Function("pose_ik", [x, p_goal, R_goal, S, weight, dp, dR, base_given, fix_base],
                       [r, ca.jacobian(r, x)])


def _levenberg_marquardt_function(residual: ca.Function, lo: Array, hi: Array, iterations: int) -> ca.Function:
    """``(x0, p) -> (x, pose_error)``: ``iterations`` projected Levenberg-Marquardt steps on ``residual``
    (the :func:`_ik_residual_function` signature, its parameters packed into one vector ``p``, matrices
    column-major), compiled into one CasADi Function; ``pose_error`` is the norm of the pose rows at x.

    Each step solves ``(JᵀJ + λ D) δ = −Jᵀr`` with ``D = diag(JᵀJ)`` (Marquardt's scaling) over the
    variables not held by an active bound (projected Newton: a variable on a bound whose gradient points
    outward stays put), projects ``x + δ`` onto ``[lo, hi]`` and keeps it if the squared residual fell.
    λ follows Nielsen's rule (the ratio ρ of actual to predicted decrease: λ·max(1/3, 1 − (2ρ−1)³) on
    success; λ·ν, ν doubling, on failure). Why not ``scipy.optimize.least_squares``: a scan makes ~300 of
    these 9-unknown solves, and its Python-level iterations cost ~0.26 ms per residual evaluation (4.7 s
    per scan); compiled, a whole solve is one call (~1.5 ms).
    """
    nx = residual.size1_in(0)
    parts = [residual.sparsity_in(i) for i in range(1, residual.n_in())]
    p = ca.SX.sym("p", sum(sp.numel() for sp in parts))
    args, offset = [], 0
    for sp in parts:
        args.append(ca.reshape(p[offset: offset + sp.numel()], sp.size1(), sp.size2()))
        offset += sp.numel()
    x = ca.SX.sym("x", nx)
    lam, nu = ca.SX.sym("lambda"), ca.SX.sym("nu")
    r, J = residual(x, *args)
    H = ca.mtimes(J.T, J)
    grad = ca.mtimes(J.T, r)
    free = 1 - ca.logic_or(ca.logic_and(x <= ca.DM(lo), grad > 0), ca.logic_and(x >= ca.DM(hi), grad < 0))
    H_free = ca.mtimes(ca.mtimes(ca.diag(free), H), ca.diag(free)) + ca.diag(1 - free)
    delta = ca.solve(H_free + lam * (ca.diag(ca.diag(H_free)) + 1e-9 * ca.SX.eye(nx)), -free * grad)
    x_try = ca.fmin(ca.fmax(x + delta, ca.DM(lo)), ca.DM(hi))
    step = x_try - x
    r_try, _ = residual(x_try, *args)
    decrease = ca.sumsqr(r) - ca.sumsqr(r_try)
    predicted = -(2 * ca.dot(grad, step) + ca.sumsqr(ca.mtimes(J, step)))  # of the linearised residual
    rho = decrease / ca.fmax(predicted, 1e-300)
    better = decrease > 0
    lam_next = ca.if_else(better, lam * ca.fmax(1.0 / 3.0, 1 - (2 * rho - 1) ** 3), lam * nu)
    state = ca.vertcat(x, lam, nu)
    step_fn = ca.Function("lm_step", [state, p],
                          [ca.vertcat(ca.if_else(better, x_try, x), ca.fmin(ca.fmax(lam_next, 1e-12), 1e12),
                                      ca.if_else(better, 2.0, 2.0 * nu))])
    x0 = ca.SX.sym("x0", nx)
    start = ca.vertcat(ca.fmin(ca.fmax(x0, ca.DM(lo)), ca.DM(hi)), 1e-3, 2.0)
    x_end = step_fn.fold(iterations)(start, ca.repmat(p, 1, iterations))[:nx]
    r_end, _ = residual(x_end, *args)
    return ca.Function("pose_ik_lm", [x0, p], [x_end, ca.norm_2(r_end[:12])])


def pack_ik_parameters(*args: ArrayLike) -> Array:
    """The parameters of :func:`_ik_residual_function` (after x), in its order, as the one vector ``p`` of
    :func:`_levenberg_marquardt_function`: each flattened column-major, as CasADi stores a matrix."""
    return np.concatenate([np.asarray(a, dtype=float).ravel(order="F") for a in args])


# Levenberg-Marquardt steps per solve. Measured on the default states of scenarios I and II: with 100
# steps the scan reaches the same meeting times and tracking nodes as scipy's trf did (xtol 1e-10), its
# guesses within 3e-5 rad; without the projected-Newton masking, 100 steps lost three reachable meeting
# times of scenario I
LM_ITERATIONS = 100


class _PoseIK:
    """Bounded least-squares IK to one pose from a list of starts; None when unreachable."""

    def __init__(self, scenario: Scenario) -> None:
        self.fn = _ik_residual_function(scenario)
        rob = scenario.robot
        (bx, bz) = scenario.base_offset_bounds_m
        # a pinned base component (min = max in the config) is legal: the projection holds it there
        self.lo = np.concatenate([rob.q_min + 1e-3, [bx[0], bz[0]]])
        self.hi = np.concatenate([rob.q_max - 1e-3, [bx[1], bz[1]]])
        self.lm = _levenberg_marquardt_function(self.fn, self.lo, self.hi, LM_ITERATIONS)
        self.p_joint1 = rob.p_base_joint1_m
        self.reach_m = rob.reach_from_joint1_m

    def out_of_reach(self, p_goal: Array, base_fixed: Array | None, drift: tuple[Array, Array]) -> bool:
        """True when no configuration within the bounds puts the end-effector within REACH_TOLERANCE of
        ``p_goal`` (m): the goal is farther than the arm's reach from every admissible first-joint origin.

        Most unreachable meeting times of a scan fail this way; the least-squares solves would spend
        ~200 evaluations from each of several starts to find the same answer.
        """
        # p_ee = (b_x, 0, b_z) + dp + dR (p_joint1 + r(q)) with |r(q)| ≤ reach, so the position error is at
        # least dist((b_x, 0, b_z), rel) − reach, minimised over the admissible base offsets
        dp, dR = drift
        rel = p_goal - dp - dR @ self.p_joint1
        if base_fixed is None:
            lo = np.array([self.lo[-2], 0.0, self.lo[-1]])
            hi = np.array([self.hi[-2], 0.0, self.hi[-1]])
        else:
            lo = hi = np.array([base_fixed[0], 0.0, base_fixed[1]])
        gap = rel - np.clip(rel, lo, hi)
        return bool(np.linalg.norm(gap) > self.reach_m + REACH_TOLERANCE)

    def solve(self, p_goal: Array, R_goal: Array, S: Array, starts: list[Array],
              base_fixed: Array | None = None, drift: tuple[Array, Array] | None = None) -> Array | None:
        dp, dR = drift if drift is not None else (np.zeros(3), np.eye(3))
        fixed_base, fix = (np.zeros(2), 0.0) if base_fixed is None else (np.asarray(base_fixed, dtype=float), 1.0)
        if self.out_of_reach(p_goal, base_fixed, (dp, dR)):
            return None

        def solve_from(x0: Array, weight: float) -> tuple[Array, float]:
            x, error = self.lm(x0, pack_ik_parameters(p_goal, R_goal, S, weight, dp, dR, fixed_base, fix))
            return np.asarray(x).ravel(), float(error)

        for x0 in starts:
            # regularised solve (stays near θ_in), then a polish that removes most of the regularisation's bias
            x, error = solve_from(x0, REGULARISATION)
            if error > POLISH_WORTHWHILE_ERROR:
                continue
            x, error = solve_from(x, POLISH_REGULARISATION)
            if error < REACH_TOLERANCE:
                if base_fixed is not None:
                    x = np.concatenate([x[:-2], base_fixed])
                return x
        return None


class MeetingOutcome(Enum):
    """What the scan found at one candidate meeting time."""

    REACHED = "reached"  # pre-grasp and tracking poses solved: a candidate NLP start
    BEYOND_REACH = "beyond reach"  # the pre-grasp is farther than the arm reaches from every admissible base offset
    IK_UNSOLVED = "IK unsolved"  # within that bound, but the bounded IK found no pre-grasp or tracking pose


@dataclass(frozen=True)
class ReachScan:
    """The scan of meeting times over the start-delay window: its NLP starts and what it found at each time."""

    guesses: list[ApproachGuess]
    window_s: float  # the start-delay window [0, window_s] (s)
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
class _Scan:
    """What every meeting time of one scan shares."""

    sc: Scenario
    motion: TargetMotion
    fk: ca.Function
    scene: object
    ik: _PoseIK
    S_pre: Array
    x_home: Array
    extra_starts: list[Array]


# the last scans, so that the planner's reach check and the approach's starts share one scan (two: a cold
# plan with the approach-energy cost scans with the base pinned as well)
_KEPT_SCANS = 2
_kept_scans: list[tuple[Scenario, UniformCubicBSpline, tuple, ReachScan]] = []


def forget_last_scan() -> None:
    """Drop the kept scans, so the next :func:`reach_scan` of any state scans anew."""
    _kept_scans.clear()


def initial_guesses(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState,
                    count: int = 3) -> list[ApproachGuess]:
    """Scan meeting times, solve the pre-grasp and tracking-node IK at each; return the ``count`` best
    NLP starts (meeting times at least :data:`MIN_SEPARATION_S` apart), best first."""
    return reach_scan(scenario, spline, state, count).guesses


def reach_scan(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int = 3) -> ReachScan:
    """:func:`initial_guesses` with what the scan found at each meeting time; the last scan is kept (same
    scenario and spline objects, state and count: the same answer, deterministic)."""
    # kept with the objects themselves: an id alone could be reused by a later scenario
    key = (state.attitude_wxyz.tobytes(), state.omega_body_rad_s.tobytes(), count)
    for kept_scenario, kept_spline, kept_key, kept in _kept_scans:
        if kept_scenario is scenario and kept_spline is spline and kept_key == key:
            return kept
    result = _scan(scenario, spline, state, count)
    _kept_scans.append((scenario, spline, key, result))
    del _kept_scans[:-_KEPT_SCANS]
    return result


def _scan(scenario: Scenario, spline: UniformCubicBSpline, state: TargetState, count: int) -> ReachScan:
    sc = scenario
    robot = sc.robot
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    motion = target_motion(sc, state, sc.phases.max_start_delay_s + tf + t2 + 1.0)
    free = sc.target.grasp.free_axis
    # a few fixed, seeded extra starts: the IK has local minima (folded vs stretched arm)
    rng = np.random.default_rng(IK_SEED)
    extra_starts = [np.concatenate([rng.uniform(0.6 * robot.q_min, 0.6 * robot.q_max), sc.base_offset_guess_m])
                    for _ in range(IK_EXTRA_STARTS)]
    ctx = _Scan(sc, motion, fk_function(robot), build_scene(sc), _PoseIK(sc),
                np.eye(3) if free is None else np.column_stack([free, np.zeros(3), np.zeros(3)]),
                np.concatenate([sc.q_initial, sc.base_offset_guess_m]), extra_starts)
    x_prev = ctx.x_home
    candidates: list[tuple] = []
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
        candidates.append((-np.inf, -np.inf, [ctx.x_home] * (1 + len(TRACKING_NODES)), 0.0))
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


def _scored(ctx: _Scan, tau: float, configs: list[Array]) -> tuple:
    """``(score, clearance, configs, tau)`` of one reached meeting time (higher score: a better NLP start)."""
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
    return score, clearance, [c.copy() for c in configs], tau


def _best_guesses(ctx: _Scan, spline: UniformCubicBSpline, candidates: list[tuple],
                  count: int) -> list[ApproachGuess]:
    """The ``count`` best candidates at least :data:`MIN_SEPARATION_S` apart, as NLP starts, best first."""
    sc, ik, motion, S_pre = ctx.sc, ctx.ik, ctx.motion, ctx.S_pre
    tf = sc.phases.approach_s
    candidates.sort(key=lambda c: -c[0])
    chosen: list[tuple] = []
    for cand in candidates:
        if all(abs(cand[3] - c[3]) >= MIN_SEPARATION_S for c in chosen):
            chosen.append(cand)
        if len(chosen) == count:
            break
    guesses = []
    for _, clearance, configs, tau in chosen:
        if np.isfinite(clearance):
            configs = _correct_for_base_drift(sc, ik, motion, configs, tau, S_pre)
        x = configs[0]
        times = np.linspace(0.0, tf, 4 * spline.n_vertices)
        q_path = sc.q_initial + np.outer(smoothstep5(times / tf), x[:7] - sc.q_initial)
        params = fit_approach_params(spline, sc.q_initial, times, q_path)
        q_tracking = np.array([c[:7] for c in configs[1:]])
        guesses.append(ApproachGuess(params, x[7:].copy(), tau, x[:7].copy(), q_tracking, clearance))
    return guesses


DRIFT_ITERATIONS = 3


def _correct_for_base_drift(sc: Scenario, ik: _PoseIK, motion: TargetMotion, configs: list[Array], tau: float,
                            S_pre: Array) -> list[Array]:
    """Re-solve the IK with the base where the free-floating base actually drifts along the guessed path.

    The scan froze the base; moving ~70 kg of arm through large angles shifts and turns the 800 kg base
    by centimetres and degrees, which would leave the NLP far from its end constraint. The drift does
    not depend on the base offset (translation invariance), so a few fixed-point passes converge.
    """
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    free = sc.target.grasp.free_axis
    fk = fk_function(sc.robot)
    for _ in range(DRIFT_ITERATIONS):
        drifts = _base_drift(sc, configs)
        R_g, p_g = (a[0] for a in motion.grasp_pose(tau + tf))
        x_pre = ik.solve(p_g - sc.approach.pregrasp_backoff_m * R_g[:, 2], R_g, S_pre, [configs[0]],
                         drift=drifts[0])
        if x_pre is None:
            return configs
        new = [x_pre]
        R_free = np.eye(3)
        if free is not None:
            R_ee = drifts[0][1] @ np.asarray(fk(x_pre[:7])[-2])
            R_free = axis_angle_to_matrix(free, free_axis_angle(R_g, R_ee, free))
        for j, frac in enumerate(TRACKING_NODES):
            t_node = frac * t2
            R_n, p_n = (a[0] for a in motion.grasp_pose(tau + tf + t_node))
            R_G = R_n @ R_free
            x_node = ik.solve(p_n - backoff_m(sc.approach.pregrasp_backoff_m, t_node, t2) * R_G[:, 2], R_G,
                              np.eye(3), [configs[j + 1]], base_fixed=x_pre[7:], drift=drifts[j + 1])
            if x_node is None:
                return configs
            new.append(x_node)
        configs = new
    return configs


def _base_drift(sc: Scenario, configs: list[Array]) -> list[tuple[Array, Array]]:
    """Base displacement and rotation since t = 0 at t_f¹ and at each tracking node (zero momentum).

    Joint path: the quintic blend θ_in → pre-grasp over the approach, then straight lines between the
    tracking nodes — the same path the NLP's guess and its tracking-node integration use.
    """
    ff = _free_floating(sc)
    tf, t2 = sc.phases.approach_s, sc.phases.tracking_s
    q_pre = configs[0][:7]

    def approach_state(t: float) -> tuple[Array, Array]:
        s = t / tf
        ds = 30 * s**2 * (1 - s) ** 2 / tf
        return sc.q_initial + smoothstep5(s) * (q_pre - sc.q_initial), ds * (q_pre - sc.q_initial)

    x = ff.integrate_base(np.linspace(0.0, tf, 41), approach_state, np.array([0, 0, 0, 1.0, 0, 0, 0]))[-1]
    out = [(x[:3].copy(), quat_to_matrix(x[3:]))]
    t_prev, q_prev = 0.0, q_pre
    for frac, c in zip(TRACKING_NODES, configs[1:], strict=True):
        t_node = frac * t2
        qd = (c[:7] - q_prev) / (t_node - t_prev)

        def line(t: float, q0: Array = q_prev, qd: Array = qd) -> tuple[Array, Array]:
            return q0 + qd * t, qd

        x = ff.integrate_base(np.linspace(0.0, t_node - t_prev, 9), line, x)[-1]
        out.append((x[:3].copy(), quat_to_matrix(x[3:])))
        t_prev, q_prev = t_node, c[:7]
    return out


_MODELS: dict[int, FreeFloatingModel] = {}


def _free_floating(scenario: Scenario) -> FreeFloatingModel:
    key = id(scenario.robot)
    if key not in _MODELS:
        _MODELS[key] = FreeFloatingModel(scenario.robot)
    return _MODELS[key]


def ik_jacobian(scenario: Scenario, q: Array) -> Array:
    """Generalized Jacobian J* (base frame) of the scenario's robot at ``q``."""
    return np.asarray(_free_floating(scenario).gen_jacobian(q)[0])
