"""Bounded pose IK of the approach's initial guess: a compiled, projected Levenberg-Marquardt least squares.

The arm's configuration ``q`` [rad] and the base offset ``(b_x, b_z)`` [m] in the orbital plane that put the
end-effector on a pose, with the base frozen (or displaced by a given free-floating drift), within the joint
limits and the base-offset bounds.
"""

from __future__ import annotations

import hashlib
from typing import ClassVar

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.config.scenario import Scenario
from planner.model.robot import fk_function
from planner.nlp.compiled import compiled

Array = NDArray[np.float64]

REACH_TOLERANCE = 1e-3  # pose residual [m, rad] below which a pose counts as reachable
REGULARISATION = 0.02  # weight pulling the IK toward θ_in and a base-offset anchor [1/rad, 1/m]
# the polish keeps a little of it: with none, the redundant arm and the base drift to their bounds
POLISH_REGULARISATION = 2e-3
# a start whose regularised solve leaves a larger pose residual [m, rad] is not polished: the polish does not
# bring such a start within REACH_TOLERANCE, and skipping it saves a sixth of a scan's evaluations
POLISH_WORTHWHILE_ERROR = 0.1


def _ik_residual_function(scenario: Scenario) -> ca.Function:
    """``(x = [q, b_x, b_z], p_goal, R_goal, S, …, base_anchor) -> (residual, jacobian)`` of a pose IK.

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
    base_anchor = ca.SX.sym("base_anchor", 2)  # where the regularisation pulls the base [m]
    base = fix_base * base_given + (1 - fix_base) * x[-2:]
    out = fk_function(sc.robot)(x[:-2])
    p_ee = ca.vertcat(base[0], 0.0, base[1]) + dp + ca.mtimes(dR, out[-1])
    rot = ca.reshape(ca.mtimes(ca.mtimes(dR, out[-2]) - R_goal, S), 9, 1)
    reg = weight * ca.vertcat(x[:-2] - ca.DM(sc.q_initial), x[-2:] - base_anchor)
    r = ca.vertcat(p_ee - p_goal, rot, reg)
    return ca.Function("pose_ik", [x, p_goal, R_goal, S, weight, dp, dR, base_given, fix_base, base_anchor],
                       [r, ca.jacobian(r, x)])


def _levenberg_marquardt_function(residual: ca.Function, lo: Array, hi: Array, iterations: int) -> ca.Function:
    """``(x0, p) -> (x, pose_error)``: ``iterations`` projected Levenberg-Marquardt steps on ``residual``
    (the :func:`_ik_residual_function` signature, its parameters packed into one vector ``p``, matrices
    column-major), compiled into one CasADi Function; ``pose_error`` is the norm of the pose rows at x.

    Each step (:func:`_lm_step_function`) is one SX Function; the steps are a loop over it (an MX fold),
    compiled to C (:mod:`planner.nlp.compiled`): a whole solve is one call, where
    ``scipy.optimize.least_squares`` would iterate in Python, and the loop keeps the C source small (an SX
    graph would hold every step unrolled). Without a compiler the loop is expanded into one SX Function.
    """
    step_fn, p = _lm_step_function(residual, lo, hi)
    nx = residual.size1_in(0)
    x_sym = ca.SX.sym("x", nx)
    error_fn = ca.Function("lm_pose_error", [x_sym, p], [ca.norm_2(residual(x_sym, *_unpacked(residual, p))[0][:12])])
    x0, P = ca.MX.sym("x0", nx), ca.MX.sym("p", p.numel())
    start = ca.vertcat(ca.fmin(ca.fmax(x0, ca.DM(lo)), ca.DM(hi)), 1e-3, 2.0)
    x_end = step_fn.fold(iterations)(start, ca.repmat(P, 1, iterations))[:nx]
    lm = ca.Function("pose_ik_lm", [x0, P], [x_end, error_fn(x_end, P)])
    fast = compiled(lm, with_jacobian=False)
    return fast if fast.is_a("External") else lm.expand()


def _unpacked(residual: ca.Function, p: ca.SX) -> list[ca.SX]:
    """``residual``'s parameters (its inputs after x) cut out of the one vector ``p``, matrices column-major."""
    args, offset = [], 0
    for sp in (residual.sparsity_in(i) for i in range(1, residual.n_in())):
        args.append(ca.reshape(p[offset: offset + sp.numel()], sp.size1(), sp.size2()))
        offset += sp.numel()
    return args


def _lm_step_function(residual: ca.Function, lo: Array, hi: Array) -> tuple[ca.Function, ca.SX]:
    """``(state = [x, λ, ν], p) -> state``: one projected Levenberg-Marquardt step, and the symbol ``p``.

    The step solves ``(JᵀJ + λ D) δ = −Jᵀr`` with ``D = diag(JᵀJ)`` (Marquardt's scaling) over the
    variables not held by an active bound (projected Newton: a variable on a bound whose gradient points
    outward stays put), projects ``x + δ`` onto ``[lo, hi]`` and keeps it if the squared residual fell.
    λ follows Nielsen's rule (the ratio ρ of actual to predicted decrease: λ·max(1/3, 1 − (2ρ−1)³) on
    success; λ·ν, ν doubling, on failure).
    """
    nx = residual.size1_in(0)
    p = ca.SX.sym("p", sum(residual.numel_in(i) for i in range(1, residual.n_in())))
    args = _unpacked(residual, p)
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
    return ca.Function("lm_step", [state, p],
                       [ca.vertcat(ca.if_else(better, x_try, x), ca.fmin(ca.fmax(lam_next, 1e-12), 1e12),
                                   ca.if_else(better, 2.0, 2.0 * nu))]), p


def _ik_bounds(scenario: Scenario) -> tuple[Array, Array]:
    """Lower and upper bounds of the IK's unknowns ``[q [rad], b_x, b_z [m]]``."""
    rob = scenario.robot
    (bx, bz) = scenario.base_offset_bounds_m
    # a pinned base component (min = max in the config) is legal: the projection holds it there
    return (np.concatenate([rob.q_min + 1e-3, [bx[0], bz[0]]]), np.concatenate([rob.q_max - 1e-3, [bx[1], bz[1]]]))


def _ik_key(scenario: Scenario) -> str:
    """A digest of everything a :class:`PoseIK` of ``scenario`` is made of: the residual's expression graph
    (robot, θ_in), the bounds, the reach test's data and the base-offset guess."""
    rob = scenario.robot
    parts = [_ik_residual_function(scenario).serialize().encode(),
             *(np.asarray(a, dtype=float).tobytes() for a in (*_ik_bounds(scenario), rob.p_base_joint1_m,
                                                               rob.reach_from_joint1_m, scenario.base_offset_guess_m))]
    return hashlib.sha256(b"\0".join(parts)).hexdigest()


def pack_ik_parameters(*args: ArrayLike) -> Array:
    """The parameters of :func:`_ik_residual_function` (after x), in its order, as the one vector ``p`` of
    :func:`_levenberg_marquardt_function`: each flattened column-major, as CasADi stores a matrix."""
    return np.concatenate([np.asarray(a, dtype=float).ravel(order="F") for a in args])


# Levenberg-Marquardt steps per solve: enough for the scan to find the meeting times and tracking nodes a
# converged least-squares solve finds (the projected-Newton masking is what makes so few enough)
LM_ITERATIONS = 100
# PoseIKs :meth:`PoseIK.shared` keeps per process (a planner uses one, two with the approach-energy cost's
# base-pinned scan); the oldest goes first
SHARED_IK_LIMIT = 8


class PoseIK:
    """Bounded least-squares IK to one pose from a list of starts; None when unreachable."""

    _shared: ClassVar[dict[str, PoseIK]] = {}

    def __init__(self, scenario: Scenario) -> None:
        self.fn = _ik_residual_function(scenario)
        self.lo, self.hi = _ik_bounds(scenario)
        self.lm = _levenberg_marquardt_function(self.fn, self.lo, self.hi, LM_ITERATIONS)
        self.p_joint1 = scenario.robot.p_base_joint1_m
        self.reach_m = scenario.robot.reach_from_joint1_m
        self.base_guess_m = np.asarray(scenario.base_offset_guess_m, dtype=float)

    @classmethod
    def shared(cls, scenario: Scenario) -> PoseIK:
        """The PoseIK of ``scenario``, built once per process for each robot, θ_in and bounds.

        Building the Levenberg-Marquardt Function costs a sizeable part of a scan; a PoseIK holds no
        state between solves, so every scan of the same problem can share one.
        """
        key = _ik_key(scenario)
        if key not in cls._shared:
            while len(cls._shared) >= SHARED_IK_LIMIT:
                del cls._shared[next(iter(cls._shared))]
            cls._shared[key] = cls(scenario)
        return cls._shared[key]

    def out_of_reach(self, p_goal: Array, base_fixed: Array | None, drift: tuple[Array, Array]) -> bool:
        """True when no configuration within the bounds puts the end-effector within REACH_TOLERANCE of
        ``p_goal`` [m]: the goal is farther than the arm's reach from every admissible first-joint origin.

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

    def solve(self, p_goal: Array, R_goal: Array, S: Array, starts: list[Array], base_fixed: Array | None = None,
              drift: tuple[Array, Array] | None = None, own_base: bool = False) -> Array | None:
        """``[q, b_x, b_z]`` reaching the pose from the first of ``starts`` that does, None when none does. The
        regularisation pulls the base toward the scenario's base-offset guess or, with ``own_base``, toward each
        start's own base (a start elsewhere in the box is not pulled back to the guess, which can leave a pose
        reachable only there just outside REACH_TOLERANCE)."""
        dp, dR = drift if drift is not None else (np.zeros(3), np.eye(3))
        fixed_base, fix = (np.zeros(2), 0.0) if base_fixed is None else (np.asarray(base_fixed, dtype=float), 1.0)
        if self.out_of_reach(p_goal, base_fixed, (dp, dR)):
            return None

        def solve_from(x0: Array, weight: float, anchor: Array) -> tuple[Array, float]:
            x, error = self.lm(x0, pack_ik_parameters(p_goal, R_goal, S, weight, dp, dR, fixed_base, fix, anchor))
            return np.asarray(x).ravel(), float(error)

        for x0 in starts:
            anchor = np.asarray(x0[-2:], dtype=float) if own_base else self.base_guess_m
            # regularised solve (stays near θ_in), then a polish that removes most of the regularisation's bias
            x, error = solve_from(x0, REGULARISATION, anchor)
            if error > POLISH_WORTHWHILE_ERROR:
                continue
            x, error = solve_from(x, POLISH_REGULARISATION, anchor)
            if error < REACH_TOLERANCE:
                if base_fixed is not None:
                    x = np.concatenate([x[:-2], base_fixed])
                return x
        return None
