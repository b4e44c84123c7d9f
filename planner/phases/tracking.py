"""Phase 2, tracking and grasping: generalized-Jacobian pseudo-inverse IK (paper Eq. 7-9).

``q̇ = J*⁺ (ẋ_des + K σ_K(t) e) + (I − J*⁺ J*) k_n σ_n(t) ∇w(q)``, with J* the generalized Jacobian of the
free-floating chaser (zero momentum), e the pose error, w the manipulability (Eq. 14) whose gradient
acts in the null space. The desired end-effector pose blends smoothly from the pre-grasp pose, where the
approach left the arm at rest, to the moving grasp frame while the back-off distance closes to zero:

    p_des = (1 − s) p₀ + s (p_G − d(t) z_G),   R_des = R₀ exp(s log(R₀ᵀ R_G)),   d(t) = d₀ (1 − s_d(t))

s, s_d, σ_K, σ_n are quintic smoothsteps (zero rate and acceleration at their ends), so the joint
velocity and acceleration start at the approach's zeros and the grasp happens with the gripper at rest
relative to the grasp frame (impact-free, paper §3). ẋ_des comes from central differences of the
desired pose (step 1e-5 s, error ~1e-10 m/s), the closed loop removes the rest. The joint and base
states are integrated by RK4 at the scenario's step. Where the law asks for about
:data:`RATE_CAP_FRACTION` of a joint's rate limit or more, the whole q̇ is scaled down smoothly (its
direction kept) and the pose feedback recovers the lag; :attr:`TrackingResult.peak_rate_demand` records
how far over it was.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.interpolate import CubicHermiteSpline

from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel
from planner.model.rotation import axis_angle_to_matrix
from planner.model.target import TargetMotion
from planner.phases.tracking_kinematics import TrackingKinematics
from planner.phases.tracking_law import WELL_CONDITIONED, TrackingLaw
from planner.phases.tracking_profile import TRACKING_NODES, backoff_m, blend, gain_ramp

Array = NDArray[np.float64]

FD_STEP_S = 1e-5  # central-difference step of the desired twist [s]
RATE_CAP_FRACTION = 0.97  # the IK never commands more than this fraction of a joint's rate limit
RATE_CAP_POWER = 32  # exponent of the smooth cap (even: the cap is a smooth function of q̇)


@dataclass(frozen=True)
class TrackingResult:
    """Dense tracking trajectory; times are absolute [s since the observation]."""

    t: Array  # (n,) [s]
    q: Array  # (n, 7) [rad]
    qd: Array  # (n, 7) [rad/s]
    qdd_end: Array  # (7,) [rad/s²], joint acceleration at the grasp instant
    x_base: Array  # (n, 7) [p_world_base [m], quat_world_base]
    free_axis_angle_rad: float
    position_error_m: float  # at the grasp instant
    orientation_error_rad: float
    relative_velocity_m_s: float
    relative_angular_velocity_rad_s: float
    peak_rate_demand: float = 0.0  # max over the phase of |q̇ asked by the law| / q̇_max, before the cap
    peak_demand_time_s: float = 0.0  # when that peak was asked [s since the start of tracking]


def free_axis_angle(R_world_grasp: Array, R_world_ee: Array, axis: Array | None) -> float:
    """Angle ψ [rad] about the grasp frame's free axis that best aligns the grasp frame with the ee."""
    if axis is None:
        return 0.0
    M = R_world_grasp.T @ R_world_ee
    e = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e = e - np.dot(e, axis) * axis
    e /= np.linalg.norm(e)
    Me = M @ e
    return float(np.arctan2(np.dot(axis, np.cross(e, Me)), np.dot(e, Me)))


class TrackingController:
    """The IK law of the module docstring for one scenario (its kinematics compiled once)."""

    def __init__(self, scenario: Scenario, ff: FreeFloatingModel) -> None:
        self.scenario = scenario
        self.ff = ff
        self.kinematics = TrackingKinematics.of(ff)
        self.law = TrackingLaw.of(ff)

    def simulate(self, motion: TargetMotion, t_start_s: float, q0: Array, x_base0: Array,
                 q_nodes: Array | None = None) -> TrackingResult:
        """Run the tracking phase from the approach end state (absolute start time ``t_start_s`` [s]).

        ``q0`` (7,) [rad] and ``x_base0`` (7,) ``[p_world_base, quat_world_base]`` are the approach's end.
        ``q_nodes`` (len(TRACKING_NODES), 7) [rad]: the approach NLP's configurations at the tracking nodes; the
        null-space motion is pulled toward a C¹ interpolation of them (a posture potential, Eq. 7), so
        the IK follows the path whose limits and clearances the NLP checked.
        """
        sc = self.scenario
        T = sc.phases.tracking_s
        steps = int(np.ceil(T / sc.tracking.step_s))
        dt = T / steps
        kinematics = self.kinematics.evaluator()  # this simulation's own buffers
        at0 = kinematics(q0, x_base0)
        desired = _DesiredPose(sc, motion, t_start_s, at0.R_world_ee, at0.p_world_ee_m, _stage_times(steps, dt))
        law = _RateLaw(sc, kinematics, self.law.evaluator(), desired, _posture_reference(q0, q_nodes, T))
        ts = t_start_s + dt * np.arange(steps + 1)
        qs, qds, xs, xd_end = _integrate(law, desired.stages, steps, dt, q0, x_base0)
        # joint acceleration at the grasp instant: derivative of q̇ along the closed-loop flow
        eps = 1e-4
        qd_back, _ = law.rates(T - eps, qs[-1] - eps * qds[-1], xs[-1] - eps * xd_end)
        qdd_end = (qds[-1] - qd_back) / eps
        return _result(law, motion, desired, ts, qs, qds, xs, qdd_end)


def _result(law: _RateLaw, motion: TargetMotion, desired: _DesiredPose, ts: Array, qs: Array, qds: Array, xs: Array,
            qdd_end: Array) -> TrackingResult:
    """The trajectory with the relative pose and twist of the ee and the grasp frame at the grasp instant, and the
    law's peak rate demand."""
    at = law.kinematics(qs[-1], xs[-1])
    R_ee, p_ee = at.R_world_ee, at.p_world_ee_m
    R_g, p_g = (a[0] for a in motion.grasp_pose(ts[-1]))
    v_g, w_g = (a[0] for a in motion.grasp_twist(ts[-1]))
    twist_ee = at.J_world @ qds[-1]
    # the grasp point's velocity at the ee origin (rigid target): v_g + ω × (p_ee − p_g)
    v_rel = twist_ee[:3] - (v_g + np.cross(w_g, p_ee - p_g))
    return TrackingResult(
        t=ts, q=qs, qd=qds, qdd_end=qdd_end, x_base=xs, free_axis_angle_rad=desired.psi,
        position_error_m=float(np.linalg.norm(p_ee - p_g)),
        orientation_error_rad=float(np.linalg.norm(pin.log3((R_g @ desired.R_free).T @ R_ee))),
        relative_velocity_m_s=float(np.linalg.norm(v_rel)),
        relative_angular_velocity_rad_s=float(np.linalg.norm(twist_ee[3:] - w_g)),
        peak_rate_demand=law.peak_demand,
        peak_demand_time_s=law.peak_time_s,
    )


class _DesiredPose:
    """The desired ee pose of the module docstring at phase time ``t`` [s], and its twist by central differences.

    The target's grasp frame at every time the integration asks for is computed up front in one vectorised
    call (it does not depend on the chaser); poses are cached by time.
    """

    def __init__(self, sc: Scenario, motion: TargetMotion, t_start_s: float, R_ee0: Array, p_ee0: Array,
                 stages: list[float]) -> None:
        self.motion = motion
        self.t_start_s = t_start_s
        self.R_ee0, self.p_ee0 = R_ee0, p_ee0
        self.stages = stages
        self.T = sc.phases.tracking_s
        self.d0 = sc.approach.pregrasp_backoff_m
        axis = sc.target.grasp.free_axis
        R_g0, _ = (a[0] for a in motion.grasp_pose(t_start_s))
        self.psi = free_axis_angle(R_g0, R_ee0, axis)
        self.R_free = np.eye(3) if axis is None else axis_angle_to_matrix(axis, self.psi)
        self.grasp_at = _grasp_poses_at(motion, t_start_s,
                                        [*stages, *(u for t in stages for u in _difference_times(t))])
        self.cache: dict[float, tuple[Array, Array]] = {}

    def pose(self, t: float) -> tuple[Array, Array]:
        """``R_des`` (3, 3) and ``p_des`` (3,) [m], world."""
        if t in self.cache:
            return self.cache[t]
        if t in self.grasp_at:
            R_g, p_g = self.grasp_at[t]
        else:
            R_g, p_g = (a[0] for a in self.motion.grasp_pose(self.t_start_s + t))
        R_G = R_g @ self.R_free
        d = backoff_m(self.d0, t, self.T)
        s = blend(t, self.T)
        p = (1 - s) * self.p_ee0 + s * (p_g - d * R_G[:, 2])
        R = self.R_ee0 @ pin.exp3(s * pin.log3(self.R_ee0.T @ R_G))
        self.cache[t] = R, p
        return R, p

    def twist(self, t: float) -> Array:
        """``[v; ω]`` (6,) [m/s, rad/s], world, by central differences of :meth:`pose` (one-sided at 0)."""
        t_plus, t_minus = _difference_times(t)
        R_p, p_p = self.pose(t_plus)
        R_m, p_m = self.pose(t_minus)
        h = FD_STEP_S + min(t, FD_STEP_S)
        return np.concatenate([(p_p - p_m) / h, pin.log3(R_p @ R_m.T) / h])


def _posture_reference(q0: Array, q_nodes: Array | None, T: float) -> CubicHermiteSpline | None:
    """C¹ interpolation [rad] of the approach's configurations at the tracking nodes, at rest at t = 0."""
    if q_nodes is None:
        return None
    node_t = np.array([0.0, *(f * T for f in TRACKING_NODES)])
    node_q = np.vstack([q0, q_nodes])
    slopes = np.gradient(node_q, node_t, axis=0)
    slopes[0] = 0.0  # the approach ends at rest
    return CubicHermiteSpline(node_t, node_q, slopes)


class _RateLaw:
    """The IK law: joint rates [rad/s] and base-pose rate at phase time t, with the smooth rate cap; one compiled call
    (:mod:`planner.phases.tracking_law`), numpy's SVD pseudo-inverse where the QR one is ill-conditioned."""

    def __init__(self, sc: Scenario, kinematics: TrackingKinematics, law: TrackingLaw, desired: _DesiredPose,
                 q_ref: CubicHermiteSpline | None) -> None:
        self.kinematics = kinematics
        self.law = law
        self.desired = desired
        self.q_ref = q_ref
        self.q_ref_d = None if q_ref is None else q_ref.derivative()
        self.K = sc.tracking.pose_gain_per_s
        self.kn = sc.tracking.nullspace_gain
        self.T = sc.phases.tracking_s
        self.qd_max = sc.robot.qd_max
        self.gains = np.concatenate([[self.K, self.kn, RATE_CAP_FRACTION, RATE_CAP_POWER], self.qd_max])
        self.identity = np.eye(len(self.qd_max))  # the null-space projector's I
        self.peak_demand = 0.0  # max over the calls of |q̇ asked by the law| / q̇_max, before the cap
        self.peak_time_s = 0.0  # the phase time of that call [s]
        # what depends on the time alone, at every RK4 stage in one batch (the integration asks for each twice)
        stages = list(dict.fromkeys(desired.stages))
        refs = [None] * len(stages) if q_ref is None else zip(q_ref(stages), self.q_ref_d(stages), strict=True)
        self.at_stage = {t: (gain_ramp(t, self.T), ref) for t, ref in zip(stages, refs, strict=True)}
        self.law_inputs: dict[float, tuple[Array, Array]] = {}  # phase time → the law's desired and posture inputs

    def _time_terms(self, t: float) -> tuple[float, tuple[Array, Array] | None]:
        """The gain ramp and the posture reference ``(q_ref, q̇_ref)`` [rad, rad/s] (None without one) at ``t``."""
        if t in self.at_stage:
            return self.at_stage[t]
        return gain_ramp(t, self.T), None if self.q_ref is None else (self.q_ref(t), self.q_ref_d(t))

    def _inputs(self, t: float) -> tuple[Array, Array]:
        """The compiled law's ``desired`` and ``posture`` inputs at ``t`` (:func:`tracking_law_function`)."""
        if t not in self.law_inputs:
            R_d, p_d = self.desired.pose(t)
            ramp, ref = self._time_terms(t)
            q_ref, qd_ref = (np.zeros(len(self.qd_max)),) * 2 if ref is None else ref
            self.law_inputs[t] = (np.concatenate([R_d.ravel(order="F"), p_d, self.desired.twist(t)]),
                                  np.concatenate([[ramp], q_ref, qd_ref, [0.0 if ref is None else 1.0]]))
        return self.law_inputs[t]

    def rates(self, t: float, q: Array, x: Array) -> tuple[Array, Array]:
        """``q̇`` (7,) [rad/s] and ``ẋ_base`` (7,) at phase time ``t`` [s], joints ``q``, base pose ``x``."""
        at = self.law(q, x, *self._inputs(t), self.gains)
        if at.conditioning < WELL_CONDITIONED:
            return self._rates_by_svd(t, q, x)
        if at.demand > self.peak_demand:
            self.peak_demand, self.peak_time_s = at.demand, t
        return at.qd, at.x_base_rate

    def _rates_by_svd(self, t: float, q: Array, x: Array) -> tuple[Array, Array]:
        """:meth:`rates` with numpy's SVD pseudo-inverse, which drops a direction a singular pose has lost."""
        at = self.kinematics(q, x)
        J = at.J_world
        R_d, p_d = self.desired.pose(t)
        e = np.concatenate([p_d - at.p_world_ee_m, pin.log3(R_d @ at.R_world_ee.T)])
        ramp, ref = self._time_terms(t)
        J_pinv = np.linalg.pinv(J)
        qd = J_pinv @ (self.desired.twist(t) + self.K * ramp * e)
        null = self.kn * at.grad_manipulability
        if ref is not None:
            null = null + ref[1] + self.K * (ref[0] - q)
        qd += (self.identity - J_pinv @ J) @ (ramp * null)
        peak_before = self.peak_demand
        qd = self._capped(qd)
        if self.peak_demand > peak_before:
            self.peak_time_s = t
        return qd, self.kinematics.base_pose_rate(q, qd, x)

    def _capped(self, qd: Array) -> Array:
        """``q̇`` scaled (direction kept) into the rate limits by the smooth cap ``q̇ / (1 + r^p)^(1/p)``.

        r is the p-norm of q̇ / (cap · q̇_max): |q̇ᵢ| < cap always and q̈ stays continuous (a hard min() kinks
        it, and the base pose's central differences then lose O(dt²)); below 0.85 of the cap it changes q̇ by
        < 1e-4 relative. The pose feedback recovers the short lag where a blend peaks above what the approach
        NLP modelled.
        """
        demand = np.abs(qd) / self.qd_max
        self.peak_demand = max(self.peak_demand, float(demand.max()))
        r = float(np.sum((demand / RATE_CAP_FRACTION) ** RATE_CAP_POWER) ** (1.0 / RATE_CAP_POWER))
        return qd / (1.0 + r**RATE_CAP_POWER) ** (1.0 / RATE_CAP_POWER)


def _integrate(law: _RateLaw, stages: list[float], steps: int, dt: float, q0: Array,
               x_base0: Array) -> tuple[Array, Array, Array, Array]:
    """RK4 of the law over the phase: ``q``, ``q̇`` (steps + 1, 7), base poses (steps + 1, 7) and ``ẋ_base`` at
    the end (quaternion renormalised after every step)."""
    qs = np.empty((steps + 1, len(q0)))
    qds = np.empty_like(qs)
    xs = np.empty((steps + 1, 7))
    qs[0], xs[0] = q0, x_base0
    k1q, k1x = law.rates(0.0, q0, x_base0)
    qds[0] = k1q
    for i in range(steps):
        t_mid, t_next = stages[2 * i + 1], stages[2 * i + 2]
        k2q, k2x = law.rates(t_mid, qs[i] + dt / 2 * k1q, xs[i] + dt / 2 * k1x)
        k3q, k3x = law.rates(t_mid, qs[i] + dt / 2 * k2q, xs[i] + dt / 2 * k2x)
        k4q, k4x = law.rates(t_next, qs[i] + dt * k3q, xs[i] + dt * k3x)
        qs[i + 1] = qs[i] + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        xn = xs[i] + dt / 6 * (k1x + 2 * k2x + 2 * k3x + k4x)
        xn[3:] /= np.linalg.norm(xn[3:])
        xs[i + 1] = xn
        k1q, k1x = law.rates(t_next, qs[i + 1], xs[i + 1])
        qds[i + 1] = k1q
    return qs, qds, xs, k1x


def _stage_times(steps: int, dt: float) -> list[float]:
    """Phase times [s] of the RK4 integration's stages: ``[0, dt/2, dt, dt + dt/2, 2 dt, …]``, each step's
    midpoint and end formed from ``i·dt`` (the integration and the batched target poses share this list)."""
    stages = [0.0]
    for i in range(steps):
        t = i * dt
        stages += [t + dt / 2, t + dt]
    return stages


def _difference_times(t: float) -> tuple[float, float]:
    """The two phase times [s] of the desired twist's central difference at ``t`` (one-sided at 0)."""
    return t + FD_STEP_S, max(t - FD_STEP_S, 0.0)


def _grasp_poses_at(motion: TargetMotion, t_start_s: float, times: list[float]) -> dict[float, tuple[Array, Array]]:
    """``R_world_grasp``, ``p_world_grasp`` at ``t_start_s + t`` for each phase time ``t``, keyed by ``t``."""
    keys = list(dict.fromkeys(times))
    R, p = motion.grasp_pose(t_start_s + np.asarray(keys))
    return {t: (R[i], p[i]) for i, t in enumerate(keys)}
