"""Dense, solver-independent verification of a plan (see docs/phases.md, Verification).

The NLPs enforce their constraints at k via points only. :func:`verify` re-checks a plan on its stored
samples at a step ≤ :data:`MAX_STEP_S` (phase starts and ends always included) with tools the NLPs do
not use: pinocchio for forward kinematics and centroidal momentum, the accurate torque-free target
propagation (:class:`planner.model.target.TargetMotion`), its own closed-form signed distances
(:mod:`planner.verify.distance`, not the NLPs' engine), and 5-point finite differences (FD) of the
stored poses for every rate (:mod:`planner.verify.kinematics`).
A plan is *feasible* only if every check passes. Checks (``margin`` ≥ 0 means satisfied, SI units),
in report order; the tolerances live in :mod:`planner.verify.checks`, each well above the FD error of the
quantity it checks and far below any real modelling error:

* ``joint_position``, ``joint_velocity``: URDF boxes, at every stored sample (cheap, so all of them).
* ``joint_rate_consistency``: stored q̇ vs FD of the stored q (< 1e-3 rad/s; the rates feed the velocity
  and momentum checks). Catches wrong or mis-scaled rates, not noise.
* ``collision``: every scene pair (37 by default: :mod:`planner.collision.layout`) against the clearance the
  handle-contact rule (:mod:`planner.collision.contact_rule`) asks of it at that instant:
  ``limits.collision_margin_m`` for all, but the gripper–handle pair in tracking (the margin less the closed
  back-off) and after the grasp (exempt). Up to the grasp the target moves torque-free; after it, it is rigidly
  attached: ``T_world_target = T_world_ee T_ee_target``.
* ``momentum_chaser`` (up to the grasp; must be 0) and ``momentum_compound`` (from the grasp on; must
  keep its value at the grasp): ``h = A_g(q) [ν_base; q̇]`` from pinocchio's centroidal map, the base
  twist ν_base by FD of the stored base pose. Value: relative deviation, max over samples of
  max(‖ΔP‖/s_P, ‖ΔL_G‖/s_L), where the scales s are the largest momentum the joint motion alone
  produces (``A_g[:, 6:] q̇``: what the base must cancel) or, for the compound, the momentum it
  carries, whichever is larger (floor 1e-3 N·s / N·m·s). A base not integrated with the arm (e.g. frozen)
  deviates by O(1); the limit is 1e-3. The compound check's text also compares the momentum at the grasp
  with what the chaser and the free target carried just before it (impact-free grasp: ~0).
* ``grasp_position``, ``grasp_orientation``, ``grasp_velocity``, ``grasp_angular_velocity`` at
  t_grasp = ``phases["tracking"][1]``: pinocchio ee pose vs the grasp frame (``T_body_grasp_used`` on
  the propagated target); the ee twist by one-sided (backward) FD of the ee pose, the target's from
  TargetMotion, at the target material point under the ee origin. Limits 1 mm, 0.1°, 1 mm/s, 0.05 °/s.
* ``join_velocity_approach_tracking``, ``join_velocity_tracking_stabilization``: joint-rate jump at the joins
  (< 1e-6 rad/s). When a phase has no sample at the join instant (the planner stores it once, as the
  earlier phase's last sample), its rate there is extrapolated by a quartic through its first 5
  samples (exact for the B-spline phases).
* ``end_velocity``: |q̇| at the end of stabilization < 1e-6 rad/s.
* ``grasp_force``, ``grasp_torque`` (from the grasp on): target COM acceleration and angular rates by
  FD of the attached target pose, ``F = m a``, ``M = I_w α + ω × I_w ω + (p_com − p_ee) × F``, in the
  ee (grasp) frame; every component within ``limits.grasp_force_max_n`` / ``grasp_torque_max_nm``
  (per component, as in the NLP; an infinite limit always passes, the peak is still reported). Next to a
  stabilization B-spline knot the target's jerk jumps and the second difference errs by O(h · jump); hence
  these two pass when ``margin ≥ −WRENCH_TOL_REL · limit`` (2e-4).

The other physical limits (joint boxes, collision) pass when ``margin ≥ -FEASIBILITY_TOL`` (1e-6): a
constraint the solver left active at its tolerance (IPOPT ``constr_viol_tol`` 1e-7) is not a violation.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from planner.collision.contact_rule import exemption_note
from planner.collision.layout import SceneLayout, scene_layout
from planner.model.compound import compound_robot
from planner.model.target import TargetMotion
from planner.verify.checks import (
    END_VELOCITY_TOL_RAD_S,
    FEASIBILITY_TOL,
    GRASP_ANGULAR_VELOCITY_TOL_RAD_S,
    GRASP_ORIENTATION_TOL_RAD,
    GRASP_POSITION_TOL_M,
    GRASP_VELOCITY_TOL_M_S,
    JOIN_VELOCITY_JUMP_TOL_RAD_S,
    MOMENTUM_RELATIVE_TOL,
    RATE_CONSISTENCY_TOL_RAD_S,
    WRENCH_TOL_REL,
    CheckResult,
    CollisionSamples,
    collision_check,
    end_velocity_check,
    grasp_checks,
    join_velocity_checks,
    joint_checks,
    momentum_checks,
    rate_consistency_check,
    wrench_checks,
)
from planner.verify.kinematics import (
    TIME_TOL_S,
    PinKinematics,
    PoseSamples,
    phase_segments,
    pose_samples,
    select_samples,
)
from planner.verify.verifiable import VerifiablePlan

__all__ = [
    "DEFAULT_STEP_S", "END_VELOCITY_TOL_RAD_S", "FEASIBILITY_TOL", "GRASP_ANGULAR_VELOCITY_TOL_RAD_S",
    "GRASP_ORIENTATION_TOL_RAD", "GRASP_POSITION_TOL_M", "GRASP_VELOCITY_TOL_M_S", "JOIN_VELOCITY_JUMP_TOL_RAD_S",
    "MAX_STEP_S", "MOMENTUM_RELATIVE_TOL", "RATE_CONSISTENCY_TOL_RAD_S", "WRENCH_TOL_REL", "CheckResult", "PoseSamples",
    "VerifiablePlan", "VerifyReport", "summary_lines", "verify",
]

Array = NDArray[np.float64]

DEFAULT_STEP_S = 0.02
MAX_STEP_S = 0.02


@dataclass
class VerifyReport:
    """Result of :func:`verify`. Per-sample arrays share the verified times ``t`` (s since the observation)."""

    feasible: bool  # every check passed
    checks: dict[str, CheckResult]  # in a fixed order, see the module docstring
    violations: list[str]  # one human-readable line per failed check
    t: Array  # (n,) [s]
    sample_index: Array  # (n,) index of each verified sample in the plan's arrays (plan.q[sample_index], …)
    phase_index: Array  # (n,) 0 approach, 1 tracking, 2 stabilization
    min_distance_m: Array  # (n,) smallest signed distance over all pairs [m]
    closest_pair: list[str]  # per sample: "A-B (shapeA/shapeB)", the pair with min_distance_m
    closest_points_m: Array  # (n, 2, 3) witness points of closest_pair (on A, on B), world frame [m]
    grasp_wrench: Array  # (n, 6) [F [N]; M [N·m]] on the target at the grasp point, ee frame; 0 before grasp
    ee_pose: PoseSamples  # scenario.robot.ee_frame, pinocchio FK
    grasp_pose: PoseSamples  # grasp frame on the target (free-axis angle applied)
    target_pose: PoseSamples  # target body frame (at its COM)
    base_pose: PoseSamples
    momentum_world: Array  # (n, 6) [P [N·s]; L_G [N·m·s]]: the chaser's before the grasp, the compound's from it on
    pair_min_distance_m: dict[str, float] = field(default_factory=dict)  # "A-B" -> min over the samples
    pair_count: int = 0
    step_s: float = 0.0  # largest gap between verified samples
    t_grasp_s: float = 0.0
    collision_rule: str = ""  # which pair was exempt or relaxed, when (planner.collision.contact_rule.exemption_note)


def verify(plan: VerifiablePlan, step_s: float = DEFAULT_STEP_S) -> VerifyReport:
    """Check every constraint of ``plan`` densely (module docstring); violations are reported, not raised.

    ``step_s`` (0 < step_s ≤ 0.02 s) is the largest gap between verified samples: the plan's stored
    samples are subsampled (a step finer than the stored one verifies every stored sample); phase
    starts and ends are always verified. Uses only the fields of :class:`VerifiablePlan`.
    Raises ValueError on a malformed plan (shapes, a phase without samples, no sample at t_grasp).
    """
    if not 0.0 < step_s <= MAX_STEP_S + 1e-12:
        raise ValueError(f"step_s must be in (0, {MAX_STEP_S}] s, got {step_s!r}")
    s = _samples(plan)
    sel = select_samples(s.t, sorted({float(b) for span in plan.phases.values() for b in span}), step_s)
    w = _world(plan, s, sel)
    checks, contact, momentum, wrench = _run_checks(plan, s, w, sel)
    violations = [f"{c.name}: {c.value:.6g} {c.unit} vs limit {c.limit:.6g} {c.unit} (margin {c.margin:.3g}), "
                  f"{c.where}" for c in checks.values() if not c.passed]
    return VerifyReport(
        feasible=not violations, checks=checks, violations=violations, t=s.t[sel], sample_index=sel,
        phase_index=s.phase_index[sel], min_distance_m=contact.min_distance_m, closest_pair=contact.closest_pair,
        closest_points_m=contact.closest_points_m, grasp_wrench=wrench,
        ee_pose=pose_samples(w.T_ee[sel]), grasp_pose=pose_samples(w.T_target[sel] @ w.T_body_grasp),
        target_pose=pose_samples(w.T_target[sel]), base_pose=PoseSamples(s.x[sel, :3].copy(), s.x[sel, 3:].copy()),
        momentum_world=momentum, pair_min_distance_m=contact.pair_min_distance_m,
        pair_count=len(contact.pair_min_distance_m),
        step_s=float(np.diff(s.t[sel]).max()) if len(sel) > 1 else 0.0, t_grasp_s=s.t_grasp,
        collision_rule=exemption_note(w.layout.gripper_handle))


@dataclass(frozen=True)
class _Samples:
    """A plan's stored samples, checked for shape, and where the grasp instant falls among them."""

    t: Array  # (n,) [s]
    q: Array  # (n, 7) [rad]
    qd: Array  # (n, 7) [rad/s]
    x: Array  # (n, 7) base poses
    phase_index: Array  # (n,)
    segments: list[tuple[int, int]]  # first and last sample index of each phase
    t_grasp: float  # [s]
    k_pre: int  # the grasp instant, as the tracking's last sample
    k_post: int  # the grasp instant, as the stabilization's first sample


def _samples(plan: VerifiablePlan) -> _Samples:
    """The plan's arrays as floats, with their phases; ValueError when they do not fit together."""
    robot = plan.scenario.robot
    t, q, qd, x = (np.asarray(a, dtype=float) for a in (plan.t, plan.q, plan.qd, plan.x_base))
    phase_index = np.asarray(plan.phase_index, dtype=int)
    n = len(t)
    if q.shape != (n, robot.n_joints) or qd.shape != q.shape or x.shape != (n, 7) or phase_index.shape != (n,):
        raise ValueError(f"inconsistent plan arrays: t {t.shape}, q {q.shape}, qd {qd.shape}, x_base {x.shape}, "
                         f"phase_index {phase_index.shape}")
    if np.any(np.diff(t) < 0):
        raise ValueError("plan.t must be non-decreasing")
    segments = phase_segments(t, phase_index, plan.phases)
    t_grasp = float(plan.phases["tracking"][1])
    k_pre, k_post = segments[1][1], segments[2][0]  # the grasp instant, seen from each side
    for k in (k_pre, k_post):
        if abs(t[k] - t_grasp) > TIME_TOL_S:
            raise ValueError(f"no sample at t_grasp = {t_grasp:.6f} s (nearest {t[k]:.6f} s)")
    return _Samples(t, q, qd, x, phase_index, segments, t_grasp, k_pre, k_post)


@dataclass(frozen=True)
class _World:
    """What verify computes itself: the target's motion, pinocchio models, and (n, 4, 4) world poses at every
    stored sample (FD stencils need the neighbours of the verified samples)."""

    motion: TargetMotion
    chaser: PinKinematics
    compound: PinKinematics
    T_body_grasp: Array  # (4, 4)
    T_ee: Array  # the gripper, by pinocchio FK
    T_free: Array  # the target moving torque-free
    T_attached: Array  # the target held by the gripper
    T_target: Array  # free up to the grasp, attached after it
    T_bodies: dict[str, Array]  # the chaser's bodies at the verified samples only, (len(sel), 4, 4) each
    layout: SceneLayout  # the scene's collision bodies and pairs


def _world(plan: VerifiablePlan, s: _Samples, sel: Array) -> _World:
    """Poses of the gripper and the target at every stored sample, by verify's own models."""
    sc = plan.scenario
    motion = sc.target.motion(plan.target_state, float(s.t[-1]) + 1.0)
    T_ee_target = np.asarray(plan.grasp.T_ee_target, dtype=float)
    T_body_grasp = np.asarray(plan.T_body_grasp_used, dtype=float)
    chaser = PinKinematics(sc.robot)
    compound = PinKinematics(compound_robot(sc, T_ee_target))
    n = len(s.t)
    T_ee, T_bodies = chaser.sampled_poses(s.x, s.q, sel)
    T_free = np.tile(np.eye(4), (n, 1, 1))
    T_free[:, :3, :3], T_free[:, :3, 3] = motion.body_pose(s.t)
    T_attached = T_ee @ T_ee_target
    T_target = np.where((s.t > s.t_grasp + TIME_TOL_S)[:, None, None], T_attached, T_free)
    return _World(motion, chaser, compound, T_body_grasp, T_ee, T_free, T_attached, T_target,
                  T_bodies, scene_layout(sc.robot, sc.target))


def _run_checks(plan: VerifiablePlan, s: _Samples, w: _World,
                sel: Array) -> tuple[dict[str, CheckResult], CollisionSamples, Array, Array]:
    """Every check in report order, with the per-sample collision, momentum (n, 6) and wrench (n, 6) values."""
    sc = plan.scenario
    robot = sc.robot
    t, q, qd, x, phase_index, segments = s.t, s.q, s.qd, s.x, s.phase_index, s.segments
    checks: dict[str, CheckResult] = {}
    checks.update(joint_checks(robot, t, q, qd, phase_index))
    checks["joint_rate_consistency"] = rate_consistency_check(robot, t, q, qd, phase_index, segments, sel)
    checks["collision"], contact = collision_check(sc, w.layout, w.T_bodies, t, phase_index, plan.phases, sel,
                                                   w.T_target)
    mom, momentum = momentum_checks(w.chaser, w.compound, w.motion, t, x, q, qd, phase_index, segments, sel,
                                    s.k_pre, s.k_post)
    checks.update(mom)
    checks.update(grasp_checks(w.motion, t, w.T_ee, w.T_free, w.T_body_grasp, segments[1], s.k_pre))
    checks.update(join_velocity_checks(robot, plan.phases, t, qd, phase_index))
    checks["end_velocity"] = end_velocity_check(robot, t, qd)
    wrench_results, wrench = wrench_checks(sc, t, w.T_ee, w.T_attached, segments[2], sel, s.k_post)
    checks.update(wrench_results)
    return checks, contact, momentum, wrench


def summary_lines(report: VerifyReport) -> list[str]:
    """A fixed-width table of the checks (one line each) and a verdict line, for the CLI."""
    header = f"{'check':<34} {'value':>11} {'limit':>11} {'margin':>11} {'unit':<6} {'ok':<3} where"
    lines = [header, "-" * len(header)]
    for c in report.checks.values():
        lines.append(f"{c.name:<34} {c.value:>11.4g} {c.limit:>11.4g} {c.margin:>11.3g} {c.unit:<6} "
                     f"{'yes' if c.passed else 'NO':<3} {c.where}")
    verdict = "FEASIBLE" if report.feasible else f"INFEASIBLE ({len(report.violations)} violated)"
    lines.append(f"verdict: {verdict}; {len(report.t)} samples, step <= {report.step_s:.3f} s, "
                 f"t_grasp = {report.t_grasp_s:.3f} s, {report.pair_count} collision pairs")
    return lines
