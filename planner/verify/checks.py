"""The individual checks of :func:`planner.verify.verifier.verify`, their tolerances and :class:`CheckResult`.

Each function takes the plan's stored samples (``t`` s, ``q`` rad, ``qd`` rad/s, ``x`` base poses) plus
precomputed world poses (4×4 stacks over *all* stored samples, so FD stencils find their neighbours)
and returns named :class:`CheckResult` s. Why each tolerance is what it is: see :mod:`planner.verify.verifier`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from planner.collision.layout import TARGET_BODY, SceneLayout
from planner.config.scenario import Scenario
from planner.model.robot import RobotModel
from planner.model.target import TargetMotion
from planner.verify.collision import required_clearances, sweep_pairs
from planner.verify.kinematics import (
    PHASE_NAMES,
    TIME_TOL_S,
    PinKinematics,
    base_twist_world,
    derivatives,
    extrapolate,
    rotation_rates,
)

Array = NDArray[np.float64]
Segment = tuple[int, int]

FEASIBILITY_TOL = 1e-6  # slack (SI unit of the check) on physical limits: solver-tolerance activity
WRENCH_TOL_REL = 2e-4  # slack on the wrench limits, × the limit: FD error next to B-spline knots (≤ 1.2e-4)
GRASP_POSITION_TOL_M = 1e-3
GRASP_ORIENTATION_TOL_RAD = float(np.radians(0.1))
GRASP_VELOCITY_TOL_M_S = 1e-3
GRASP_ANGULAR_VELOCITY_TOL_RAD_S = float(np.radians(0.05))
JOIN_VELOCITY_JUMP_TOL_RAD_S = 1e-6
END_VELOCITY_TOL_RAD_S = 1e-6
RATE_CONSISTENCY_TOL_RAD_S = 1e-3
MOMENTUM_RELATIVE_TOL = 1e-3
MOMENTUM_FLOOR = 1e-3  # N·s and N·m·s: momentum scale of a plan whose arm does not move
JOIN_EXTRAPOLATION_POINTS = 5


@dataclass(frozen=True)
class CheckResult:
    """One verified constraint: worst ``value`` found, its ``limit``, ``margin`` (≥ 0 satisfied), SI ``unit``."""

    name: str
    value: float
    limit: float
    margin: float
    passed: bool
    unit: str
    where: str  # what and when, e.g. "joint4 upper bound at t = 12.340 s (approach)"
    t_s: float | None = None  # time of the worst value (s since the observation)


def make_check(name: str, value: float, limit: float, unit: str, where: str, t_s: float | None, *,
               lower: bool = False, tol: float = 0.0) -> CheckResult:
    """``value ≤ limit`` (``≥`` when ``lower``), passed when margin ≥ −tol; an infinite limit always passes."""
    margin = (value - limit) if lower else (limit - value)
    if not np.isfinite(limit):
        margin = np.inf
    return CheckResult(name, float(value), float(limit), float(margin), bool(margin >= -tol), unit, where,
                       None if t_s is None else float(t_s))


def when(t_s: float, phase: int) -> str:
    """``t = 12.345 s (tracking)``: where a check's worst value was found."""
    return f"t = {t_s:.3f} s ({PHASE_NAMES[phase]})"


def joint_checks(robot: RobotModel, t: Array, q: Array, qd: Array, phase_index: Array) -> dict[str, CheckResult]:
    """URDF position and velocity boxes at every stored sample."""
    lower, upper = q - robot.q_min, robot.q_max - q
    margins = np.minimum(lower, upper)
    k, j = np.unravel_index(int(np.argmin(margins)), margins.shape)
    side, bound = ("lower", robot.q_min[j]) if lower[k, j] <= upper[k, j] else ("upper", robot.q_max[j])
    pos = CheckResult("joint_position", float(q[k, j]), float(bound), float(margins[k, j]),
                      bool(margins[k, j] >= -FEASIBILITY_TOL), "rad",
                      f"{robot.joints[j].name} {side} bound at {when(t[k], phase_index[k])}", float(t[k]))
    vmargins = robot.qd_max - np.abs(qd)
    k, j = np.unravel_index(int(np.argmin(vmargins)), vmargins.shape)
    vel = make_check("joint_velocity", abs(qd[k, j]), robot.qd_max[j], "rad/s",
                     f"{robot.joints[j].name} at {when(t[k], phase_index[k])}", t[k], tol=FEASIBILITY_TOL)
    return {"joint_position": pos, "joint_velocity": vel}


def rate_consistency_check(robot: RobotModel, t: Array, q: Array, qd: Array, phase_index: Array,
                           segments: list[Segment], sel: Array) -> CheckResult:
    """Stored joint rates vs FD of the stored joint angles (the rates feed the velocity and momentum checks)."""
    err = np.zeros((len(sel), robot.n_joints))
    for p, seg in enumerate(segments):
        rows = np.flatnonzero(phase_index[sel] == p)
        err[rows] = np.abs(derivatives(t, q, sel[rows], seg, 1) - qd[sel[rows]])
    r, j = np.unravel_index(int(np.argmax(err)), err.shape)
    k = int(sel[r])
    return make_check("joint_rate_consistency", err[r, j], RATE_CONSISTENCY_TOL_RAD_S, "rad/s",
                      f"{robot.joints[j].name}: |q̇ − FD(q)| at {when(t[k], phase_index[k])}", t[k])


@dataclass(frozen=True)
class CollisionSamples:
    """Per verified sample: the smallest signed distance [m] over the pairs held to the full margin, the pair
    that has it and its witness points; per pair, its smallest distance while held to the full margin."""

    min_distance_m: Array  # [n]
    closest_pair: list[str]  # [n] "A-B (shapeA/shapeB)"
    closest_points_m: Array  # [n, 2, 3] witness points on A and on B, world frame
    pair_min_distance_m: dict[str, float]  # "A-B" -> min over the samples where it keeps the full margin


def collision_check(sc: Scenario, layout: SceneLayout, T_bodies: dict[str, Array], t: Array,
                    phase_index: Array, phases: dict[str, tuple[float, float]], sel: Array,
                    T_target: Array) -> tuple[CheckResult, CollisionSamples]:
    """Signed distance of every scene pair at the verified samples against the handle-contact rule
    (:mod:`planner.collision.contact_rule`), by verify's own engine (:mod:`planner.verify.collision`).
    ``T_bodies``: the chaser's body poses at the verified samples ``sel``."""
    poses = T_bodies | {TARGET_BODY: T_target[sel]}
    sweep = sweep_pairs(layout, poses)
    margin = sc.limits.collision_margin_m
    required = required_clearances(layout, margin, t[sel], phase_index[sel], phases, sc.approach.pregrasp_backoff_m)
    slack = sweep.distance_m - required
    i, j = np.unravel_index(int(np.argmin(slack)), slack.shape)
    names = layout.pair_names()
    label = _pair_label(names[j], sweep.shape_pair(i, j))
    k = int(sel[i])
    check = make_check("collision", sweep.distance_m[i, j], required[i, j], "m",
                       f"{label} at {when(t[k], phase_index[k])}", t[k], lower=True, tol=FEASIBILITY_TOL)
    held = np.where(required == margin, sweep.distance_m, np.inf)
    jmin = np.argmin(held, axis=1)
    rows = np.arange(len(sel))
    closest = [_pair_label(names[c], sweep.shape_pair(r, c)) for r, c in zip(rows, jmin, strict=True)]
    points = np.stack([sweep.p_world_a[rows, jmin], sweep.p_world_b[rows, jmin]], axis=1)
    pair_min = {name: float(v) for name, v in zip(names, held.min(axis=0), strict=True)}
    return check, CollisionSamples(held[rows, jmin], closest, points, pair_min)


def _pair_label(pair: str, shapes: tuple[str, str]) -> str:
    """``"A-B (shapeA/shapeB)"``: a pair and the shapes realising its distance."""
    return f"{pair} ({shapes[0]}/{shapes[1]})"


def _relative_deviation(dh: Array, h_arm: Array, h_ref: Array) -> tuple[Array, float, float]:
    """Per-sample max(‖ΔP‖/scale_P, ‖ΔL‖/scale_L) and the two scales (see :mod:`planner.verify.verifier`)."""
    scale_P = max(float(np.linalg.norm(h_ref[:3])), float(np.linalg.norm(h_arm[:, :3], axis=1).max()), MOMENTUM_FLOOR)
    scale_L = max(float(np.linalg.norm(h_ref[3:])), float(np.linalg.norm(h_arm[:, 3:], axis=1).max()), MOMENTUM_FLOOR)
    rel = np.maximum(np.linalg.norm(dh[:, :3], axis=1) / scale_P, np.linalg.norm(dh[:, 3:], axis=1) / scale_L)
    return rel, scale_P, scale_L


def momentum_checks(chaser: PinKinematics, compound: PinKinematics, motion: TargetMotion, t: Array, x: Array,
                    q: Array, qd: Array, phase_index: Array, segments: list[Segment], sel: Array, k_pre: int,
                    k_post: int) -> tuple[dict[str, CheckResult], Array]:
    """Chaser momentum (must be 0) up to the grasp, compound momentum (must keep its grasp value) from it on.

    Returns the checks and the momentum ``[P; L_G]`` (world) at the verified samples.
    """
    momentum = np.zeros((len(sel), 6))
    out = {}
    h_chaser_grasp = np.zeros(6)
    for name, model, rows in (("momentum_chaser", chaser, np.flatnonzero(sel <= k_pre)),
                              ("momentum_compound", compound, np.flatnonzero(sel >= k_post))):
        ks = sel[rows]
        v, w = np.empty((len(rows), 3)), np.empty((len(rows), 3))
        phases = np.full(len(rows), 2) if name == "momentum_compound" else np.minimum(phase_index[ks], 1)
        for p in np.unique(phases):
            part = phases == p
            v[part], w[part] = base_twist_world(t, x, ks[part], segments[p])
        h, h_arm = model.momenta(x[ks], q[ks], v, w, qd[ks])
        momentum[rows] = h
        h_ref = np.zeros(6) if name == "momentum_chaser" else h[0]  # rows[0] is the grasp instant
        rel, sP, sL = _relative_deviation(h - h_ref, h_arm, h_ref)
        r = int(np.argmax(rel))
        k = int(sel[rows[r]])
        where = (f"|ΔP| = {np.linalg.norm(h[r, :3] - h_ref[:3]):.3g} N·s (scale {sP:.3g}), |ΔL_G| = "
                 f"{np.linalg.norm(h[r, 3:] - h_ref[3:]):.3g} N·m·s (scale {sL:.3g}) at {when(t[k], phase_index[k])}")
        if name == "momentum_chaser":
            h_chaser_grasp = h[-1]
        else:  # information: what the chaser and the free target carried just before the grasp
            L_target = motion.angular_momentum_world(t[k_pre])[0]  # its COM is at rest: P_target = 0
            d = h_ref - h_chaser_grasp - np.concatenate([np.zeros(3), L_target])
            where += (f"; at the grasp vs chaser + free target: |ΔP| = {np.linalg.norm(d[:3]):.3g} N·s, "
                      f"|ΔL| = {np.linalg.norm(d[3:]):.3g} N·m·s")
        out[name] = make_check(name, rel[r], MOMENTUM_RELATIVE_TOL, "rel", where, t[k])
    return out, momentum


def grasp_checks(motion: TargetMotion, t: Array, T_ee: Array, T_free: Array, T_body_grasp: Array,
                 segment: Segment, k: int) -> dict[str, CheckResult]:
    """Relative pose and twist of the ee and the grasp frame at the grasp instant (sample k, end of ``segment``)."""
    T_grasp = T_free[k] @ T_body_grasp
    p_ee, R_ee = T_ee[k, :3, 3], T_ee[k, :3, :3]
    position_error = float(np.linalg.norm(p_ee - T_grasp[:3, 3]))
    orientation_error = float(np.linalg.norm(pin.log3(T_grasp[:3, :3].T @ R_ee)))
    v_ee = derivatives(t, T_ee[:, :3, 3], k, segment, 1)[0]
    w_ee = rotation_rates(t, T_ee[:, :3, :3], k, segment)[0][0]
    w_target = motion.grasp_twist(t[k])[1][0]
    v_target = np.cross(w_target, p_ee - T_free[k, :3, 3])  # target material point at the ee (COM at rest)
    dw = float(np.linalg.norm(w_ee - w_target))
    at = f"t_grasp = {t[k]:.3f} s"
    return {
        "grasp_position": make_check("grasp_position", position_error, GRASP_POSITION_TOL_M, "m", at, t[k]),
        "grasp_orientation": make_check("grasp_orientation", orientation_error, GRASP_ORIENTATION_TOL_RAD, "rad",
                                        f"{np.degrees(orientation_error):.3g}° at {at}", t[k]),
        "grasp_velocity": make_check("grasp_velocity", np.linalg.norm(v_ee - v_target), GRASP_VELOCITY_TOL_M_S,
                                     "m/s", f"ee vs target point at {at}", t[k]),
        "grasp_angular_velocity": make_check("grasp_angular_velocity", dw, GRASP_ANGULAR_VELOCITY_TOL_RAD_S,
                                             "rad/s", f"{np.degrees(dw):.3g}°/s at {at}", t[k]),
    }


def _rate_at_join(t: Array, qd: Array, idx: Array, t_join: float, after: bool) -> tuple[Array, Array]:
    """Joint rates of one phase (its samples ``idx``) at the join instant, and how finely they are known [rad/s]:
    a stored sample exactly (0); an extrapolation through the phase's :data:`JOIN_EXTRAPOLATION_POINTS` samples
    nearest the join to within its truncation error, estimated as its difference from the extrapolation through
    one point fewer (the farthest left out)."""
    at = idx[np.abs(t[idx] - t_join) <= TIME_TOL_S]
    if at.size:
        return qd[at[0]], np.zeros(qd.shape[1])
    near = idx[:JOIN_EXTRAPOLATION_POINTS] if after else idx[-JOIN_EXTRAPOLATION_POINTS:]
    fewer = near[:-1] if after else near[1:]
    rate = extrapolate(t, qd, near, t_join)
    return rate, np.abs(rate - extrapolate(t, qd, fewer, t_join))


def join_velocity_checks(robot: RobotModel, phases: dict[str, tuple[float, float]], t: Array, qd: Array,
                         phase_index: Array) -> dict[str, CheckResult]:
    """Joint-rate jump at the approach/tracking and tracking/stabilization joins, each side's rate stored or
    extrapolated to the join: a jump must stay within :data:`JOIN_VELOCITY_JUMP_TOL_RAD_S` plus what the
    extrapolations can resolve (a phase whose rates grow like t³ from the join, as the tracking's onset, is
    extrapolated from samples 0.01 s apart only to ~1e-4 rad/s)."""
    out = {}
    for p in (0, 1):
        a, b = PHASE_NAMES[p], PHASE_NAMES[p + 1]
        t_join = float(phases[a][1])
        after, res_after = _rate_at_join(t, qd, np.flatnonzero(phase_index == p + 1), t_join, after=True)
        before, res_before = _rate_at_join(t, qd, np.flatnonzero(phase_index == p), t_join, after=False)
        jump, limit = np.abs(after - before), JOIN_VELOCITY_JUMP_TOL_RAD_S + res_after + res_before
        j = int(np.argmin(limit - jump))
        name = f"join_velocity_{a}_{b}"
        out[name] = make_check(name, jump[j], limit[j], "rad/s",
                               f"{robot.joints[j].name} rate jump at the {a}/{b} join, t = {t_join:.3f} s "
                               f"(resolved to {limit[j] - JOIN_VELOCITY_JUMP_TOL_RAD_S:.2g} rad/s)", t_join)
    return out


def end_velocity_check(robot: RobotModel, t: Array, qd: Array) -> CheckResult:
    """The largest joint rate at the end of stabilization (the arm must be at rest)."""
    j = int(np.argmax(np.abs(qd[-1])))
    return make_check("end_velocity", abs(qd[-1, j]), END_VELOCITY_TOL_RAD_S, "rad/s",
                      f"{robot.joints[j].name} at the end of stabilization, t = {t[-1]:.3f} s", t[-1])


def wrench_checks(sc: Scenario, t: Array, T_ee: Array, T_attached: Array, segment: Segment, sel: Array,
                  k_post: int) -> tuple[dict[str, CheckResult], Array]:
    """Grasp wrench [F; M] on the attached target, ee frame, at the verified samples from the grasp on.

    ``F = m a_com``, ``M = I_w α + ω × I_w ω + (p_com − p_ee) × F`` with a_com, ω, α by FD of the
    attached target pose. Returns the force/torque checks (per component) and the n×6 wrench.
    """
    mass, I_body = sc.target.mass_kg, sc.target.inertia_body_kg_m2
    wrench = np.zeros((len(sel), 6))
    post = np.flatnonzero(sel >= k_post)
    ks = sel[post]
    a_com = derivatives(t, T_attached[:, :3, 3], ks, segment, 2)
    w, alpha = rotation_rates(t, T_attached[:, :3, :3], ks, segment)
    R_T = T_attached[ks, :3, :3]
    I_w = np.einsum("mij,jk,mlk->mil", R_T, I_body, R_T)
    F = mass * a_com
    M = (np.einsum("mij,mj->mi", I_w, alpha) + np.cross(w, np.einsum("mij,mj->mi", I_w, w))
         + np.cross(T_attached[ks, :3, 3] - T_ee[ks, :3, 3], F))
    R_ee = T_ee[ks, :3, :3]
    wrench[post] = np.concatenate([np.einsum("mji,mj->mi", R_ee, F), np.einsum("mji,mj->mi", R_ee, M)], axis=1)
    out = {}
    for name, cols, limit, unit in (("grasp_force", slice(0, 3), sc.limits.grasp_force_max_n, "N"),
                                    ("grasp_torque", slice(3, 6), sc.limits.grasp_torque_max_nm, "N·m")):
        block = np.abs(wrench[post, cols])
        r, axis = np.unravel_index(int(np.argmax(block)), block.shape)
        k = int(sel[post[r]])
        out[name] = make_check(name, block[r, axis], limit, unit, f"ee-frame {'xyz'[axis]} component at "
                               f"{when(t[k], 2)}", t[k], tol=max(FEASIBILITY_TOL, WRENCH_TOL_REL * limit))
    return out, wrench
