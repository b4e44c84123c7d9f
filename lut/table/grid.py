"""The look-up table's grid over the target's observed state at t = 0: points ↔ states, cells, continuation.

The grid's axes are always *all* axes of its kind (:data:`lut.table.grid_config.AXIS_NAMES`, in that order;
the axes a config omits hold one value), points are numbered in C order (the last axis varies fastest).

Conventions. World = the orbital frame O (the orbital plane is x–z). ``R(v, a)`` is the right-handed
rotation by ``a`` about unit ``v``.

**flat_spin** — the target spins steadily about its *major* principal axis (largest moment of inertia):

* ``e`` — the major axis in the body frame, a unit eigenvector of the target's inertia, signed so that
  its largest-magnitude component is positive (scenario I: +y, scenario II: +z).
* ``spin_rate_deg_s`` — ``r = |ω| > 0``; ``ω_body = r e`` (the spin is along +e, never -e).
* ``spin_axis_angle_deg`` — ``α``: the world spin axis ``s = R e = (cos α, 0, sin α)`` lies in the
  orbital x–z plane, ``α`` measured from +x towards +z (α = 90°: s = +z).
* ``spin_phase_deg`` — ``φ``: ``R_world_body = R(s, φ) · R(y, -α) · R₀``, where the reference ``R₀`` is
  the minimal rotation taking ``e`` onto +x (so ``R(y, -α) R₀`` takes ``e`` onto ``s``). φ turns the body
  about ``s`` in the sense of the spin. Scenario II's default (identity, ω = 4 °/s about body z) is
  exactly ``(4, 90, 0)``. Scenario I's default spins about the orbit normal y, which is not in this
  family: a flat-spin grid over it must give all three axes.
* Symmetry: the state at phase φ is the state at φ₀ advanced by ``(φ - φ₀) / r``
  (:mod:`lut.table.symmetry`), so the phase axis is periodic (360° wraps) and may be coarse.

**tumble** — ``omega_x/y/z_deg_s`` are the body rates ``ω_body``; ``roll_deg``, ``pitch_deg``, ``yaw_deg``
the initial attitude, URDF convention ``R_world_body = Rz(yaw) Ry(pitch) Rx(roll)``; pitch must stay
inside (-90°, 90°), where the angles are unique.

An angle axis whose values go round the whole turn (α, roll, yaw) wraps at 360° like the phase
(:attr:`lut.table.grid_config.Axis.periodic`), without the phase's time symmetry.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lut.table.grid_config import ANGLE_AXES, AXIS_NAMES, PHASE_AXIS, Axis, GridConfig
from lut.table.symmetry import start_delay_shift_s
from planner.errors import ConfigError, TargetStateError
from planner.model.rotation import axis_angle_to_matrix, matrix_to_quat, quat_to_matrix, rpy_to_matrix
from planner.model.target import TargetState

Array = NDArray[np.float64]
RATE_AXIS = "spin_rate_deg_s"
# a state is a flat spin about the major axis when ω and s are this close (rad) to the family
FLAT_SPIN_TOL_RAD = 1e-6
# coordinates (deg or deg/s) this close to a grid bound or a fixed axis value count as on it
COORD_TOL = 1e-6


@dataclass
class Cell:
    """The grid cell enclosing some coordinates.

    ``corners``: flat indices of the 2^d corner points (d = axes with count > 1); ``weights``: their
    multilinear interpolation weights (≥ 0, sum 1); ``coords``: the coordinates located (the phase taken
    in ``[min, min + 360)``); ``corner_coords`` (2^d × n_axes): the corners' coordinates unwrapped across
    the phase wrap, so that ``weights @ corner_coords == coords`` on every axis with count > 1.
    """

    corners: list[int]
    weights: Array
    coords: Array
    corner_coords: Array


class Grid:
    """Grid points ↔ target states, cells, and the continuation order of a build.

    ``inertia_body_kg_m2`` is the target's inertia (body frame; it defines the flat spin's major axis);
    ``default_state`` is the scenario's default state (it fixes the axes the config omits and seeds the
    continuation).
    """

    def __init__(self, config: GridConfig, inertia_body_kg_m2: ArrayLike, default_state: TargetState) -> None:
        self.config = config
        self.kind = config.kind
        inertia = np.asarray(inertia_body_kg_m2, dtype=float)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
            raise ValueError(f"inertia_body_kg_m2 must be a finite 3×3 matrix, got shape {inertia.shape}")
        self.inertia_body_kg_m2 = 0.5 * (inertia + inertia.T)
        self.default_state = default_state
        self.major_axis_body: Array | None = None
        if self.kind == "flat_spin":
            self.major_axis_body = _major_axis(self.inertia_body_kg_m2, config.source)
            self._R_ref = _minimal_rotation(self.major_axis_body, np.array([1.0, 0.0, 0.0]))
        try:
            default_raw: Array | None = self._raw_coordinates(default_state)
            default_problem = ""
        except TargetStateError as exc:
            default_raw, default_problem = None, str(exc)
        self.axes: tuple[Axis, ...] = self._all_axes(default_raw, default_problem)
        self._values = [ax.values() for ax in self.axes]
        self._shape = tuple(ax.count for ax in self.axes)
        self._n_points = math.prod(self._shape)
        self.default_coordinates: Array | None = None
        if default_raw is not None:
            self.default_coordinates = self._canonical(default_raw)

    def _all_axes(self, default_raw: Array | None, default_problem: str) -> tuple[Axis, ...]:
        """Every axis of the kind, in canonical order: the config's, or fixed at the default state's coordinate."""
        given = {ax.name: ax for ax in self.config.axes}
        axes = []
        for i, name in enumerate(AXIS_NAMES[self.kind]):
            if name in given:
                axes.append(given[name])
                continue
            if default_raw is None:
                raise ConfigError(self.config.source, "axes", f"no {name} axis, and the scenario's default state "
                                  f"cannot fix it: {default_problem}; give every axis of the kind")
            value = float(default_raw[i])
            axes.append(Axis(name, value, value, 1))
        return tuple(axes)

    # ---- shape and indices ------------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, ...]:
        return self._shape

    @property
    def n_points(self) -> int:
        return self._n_points

    @property
    def axis_names(self) -> list[str]:
        return [ax.name for ax in self.axes]

    @property
    def axis_values(self) -> list[Array]:
        return [v.copy() for v in self._values]

    def index_of(self, flat: int) -> tuple[int, ...]:
        flat = int(flat)
        if not 0 <= flat < self._n_points:
            raise IndexError(f"grid point {flat} out of range [0, {self._n_points})")
        return tuple(int(i) for i in np.unravel_index(flat, self._shape))

    def flat_of(self, idx: ArrayLike) -> int:
        idx = tuple(int(i) for i in idx)
        if len(idx) != len(self._shape) or any(not 0 <= i < n for i, n in zip(idx, self._shape, strict=True)):
            raise IndexError(f"grid index {idx} out of range for shape {self._shape}")
        return int(np.ravel_multi_index(idx, self._shape))

    def coordinates(self, flat: int) -> Array:
        """Axis values of grid point ``flat`` (canonical axis order)."""
        return np.array([v[i] for v, i in zip(self._values, self.index_of(flat), strict=True)])

    # ---- states ------------------------------------------------------------------------------------

    def state(self, flat: int) -> TargetState:
        """The target state at t = 0 of grid point ``flat``."""
        return self.state_at(self.coordinates(flat))

    def state_at(self, coords: ArrayLike) -> TargetState:
        """The target state at any coordinates (on or off the grid; no range check)."""
        c = self._check_coords(coords)
        if self.kind == "flat_spin":
            rate, alpha, phi = np.radians(c)
            R = self._flat_spin_rotation(alpha, phi)
            return TargetState(matrix_to_quat(R), rate * self.major_axis_body)
        omega = np.radians(c[:3])
        return TargetState(matrix_to_quat(rpy_to_matrix(np.radians(c[3:]))), omega)

    def coordinates_of_state(self, state: TargetState) -> Array:
        """Grid coordinates of ``state`` (the inverse of :meth:`state_at`); angles are taken in each
        axis' window (phase in ``[min, min + 360)``, other angles nearest the axis' centre).

        Flat spin: ``TargetStateError`` saying why when the state is not a flat spin about the major axis
        (within 1e-6 rad) with its spin axis in the orbital x–z plane. NaN/inf: ``TargetStateError``.
        """
        return self._canonical(self._raw_coordinates(state))

    def family_coordinates(self, state: TargetState) -> Array:
        """Coordinates of the member of the grid's state family nearest ``state`` (a flat-spin grid: rate |ω|,
        the spin axis R·e projected on the orbital x–z plane), possibly outside the axes' bounds."""
        return self._canonical(self._raw_coordinates(state, strict=False))

    def _flat_spin_rotation(self, alpha_rad: float, phi_rad: float) -> Array:
        s = np.array([math.cos(alpha_rad), 0.0, math.sin(alpha_rad)])
        R_align = axis_angle_to_matrix([0.0, 1.0, 0.0], -alpha_rad) @ self._R_ref
        return axis_angle_to_matrix(s, phi_rad) @ R_align

    def _raw_coordinates(self, state: TargetState, strict: bool = True) -> Array:
        """Coordinates of ``state`` before windowing. ``strict=False``: a flat-spin grid takes the nearest
        member of its family (rate |ω|, spin axis R·e projected on the x–z plane) instead of refusing it;
        a tumble at pitch ±90° takes roll 0."""
        q, omega = _finite_state(state)
        R = quat_to_matrix(q)
        if self.kind == "tumble":
            pitch = math.asin(float(np.clip(-R[2, 0], -1.0, 1.0)))
            if math.cos(pitch) < 1e-9:
                if strict:
                    raise TargetStateError("target state: attitude at pitch ±90°, where roll and yaw are not defined")
                return np.degrees(np.concatenate([omega, [0.0, pitch, math.atan2(-R[0, 1], R[1, 1])]]))
            roll = math.atan2(R[2, 1], R[2, 2])
            yaw = math.atan2(R[1, 0], R[0, 0])
            return np.degrees(np.concatenate([omega, [roll, pitch, yaw]]))
        s = R @ self.major_axis_body
        if strict:
            _check_flat_spin(omega, self.major_axis_body, s)
        alpha = math.atan2(float(s[2]), float(s[0]))
        M = R @ self._flat_spin_rotation(alpha, 0.0).T  # = R(s, φ)
        u = np.array([0.0, 1.0, 0.0])  # ⊥ s
        Mu = M @ u
        phi = math.atan2(float(s @ np.cross(u, Mu)), float(u @ Mu))
        return np.array([math.degrees(float(np.linalg.norm(omega))), math.degrees(alpha), math.degrees(phi)])

    def _canonical(self, raw: Array) -> Array:
        """Angles moved by whole turns into each axis' window."""
        c = np.array(raw, dtype=float)
        for i, ax in enumerate(self.axes):
            if ax.periodic:
                c[i] = _phase_window(ax, c[i])
            elif ax.name in ANGLE_AXES:
                centre = 0.5 * (ax.min + ax.max)
                c[i] += 360.0 * round((centre - c[i]) / 360.0)
        return c

    def _check_coords(self, coords: ArrayLike) -> Array:
        c = np.array(coords, dtype=float).reshape(-1)
        if c.shape != (len(self.axes),):
            raise ValueError(f"expected {len(self.axes)} coordinates ({', '.join(self.axis_names)}), got {c.size}")
        for name, value in zip(self.axis_names, c, strict=True):
            if not math.isfinite(value):
                raise TargetStateError(f"grid coordinate {name} = {value} is not finite")
        return c

    # ---- cells ----------------------------------------------------------------------------------------

    def locate(self, coords: ArrayLike) -> Cell:
        """The cell enclosing ``coords`` with multilinear weights; periodic axes (the phase, an angle round the
        whole turn: :attr:`Axis.periodic`) wrap at 360°.

        Outside the grid on any other axis (beyond 1e-6 of a bound, or off a single-valued axis):
        ``TargetStateError`` naming the axis, e.g. ``spin_rate_deg_s = 5.2 not in [3, 4]``.
        """
        c = self._check_coords(coords)
        per_axis: list[list[tuple[int, float, float]]] = []  # (index, weight, unwrapped coordinate)
        for i, (ax, vals) in enumerate(zip(self.axes, self._values, strict=True)):
            x = c[i]
            if ax.periodic:
                x = _phase_window(ax, x)
                c[i] = x
            elif not (ax.min - COORD_TOL <= x <= ax.max + COORD_TOL):
                fixed = f" (the grid fixes this axis at {ax.min:.10g})" if ax.count == 1 else ""
                raise TargetStateError(f"target state is outside the grid: {ax.name} = {x:.10g} not in "
                                       f"[{ax.min:.10g}, {ax.max:.10g}]{fixed}")
            if ax.count == 1:
                per_axis.append([(0, 1.0, float(vals[0]))])
                continue
            if ax.periodic and x > ax.max + COORD_TOL:  # between the last value and the first one + 360
                t = (x - ax.max) / (ax.min + 360.0 - ax.max)
                per_axis.append([(ax.count - 1, 1.0 - t, ax.max), (0, t, ax.min + 360.0)])
                continue
            xc = min(max(x, ax.min), ax.max)
            j = int(np.clip(np.searchsorted(vals, xc, side="right") - 1, 0, ax.count - 2))
            t = float(np.clip((xc - vals[j]) / (vals[j + 1] - vals[j]), 0.0, 1.0))
            per_axis.append([(j, 1.0 - t, float(vals[j])), (j + 1, t, float(vals[j + 1]))])
        corners, weights, corner_coords = [], [], []
        for combo in itertools.product(*per_axis):
            corners.append(self.flat_of([k for k, _, _ in combo]))
            weights.append(math.prod(w for _, w, _ in combo))
            corner_coords.append([x for _, _, x in combo])
        return Cell(corners, np.array(weights), c, np.array(corner_coords))

    def start_delay_shift_s(self, from_coords: ArrayLike, to_coords: ArrayLike, *, forward_turn: bool = False,
                            meeting_s: float = 0.0) -> float:
        """Start-delay shift [s] from ``from_coords`` to ``to_coords`` keeping the spin angle at the plan's meeting,
        ``meeting_s`` [s] after the observation (:func:`lut.table.symmetry.start_delay_shift_s`; 0 without a phase)."""
        names = self.axis_names
        if PHASE_AXIS not in names:
            return 0.0
        i, rate = names.index(PHASE_AXIS), names.index(RATE_AXIS)
        return start_delay_shift_s(from_coords[i], to_coords[i], to_coords[rate], forward_turn=forward_turn,
                                   rate_from_deg_s=from_coords[rate], meeting_s=meeting_s)

    def normalised_distance(self, a: ArrayLike, b: ArrayLike) -> float:
        """Distance between coordinates in grid steps (axis by axis; phase circular; 1 unit on fixed axes)."""
        d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
        d = [((x + 180.0) % 360.0 - 180.0 if ax.periodic else x) / (ax.step if ax.count > 1 else 1.0)
             for ax, x in zip(self.axes, d, strict=True)]
        return float(np.linalg.norm(d))

    def neighbours(self, flat: int) -> list[int]:
        """Axis-adjacent grid points, ascending. Across the phase wrap only when the wrap gap is one step."""
        idx = self.index_of(flat)
        out: set[int] = set()
        for a, ax in enumerate(self.axes):
            if ax.count == 1:
                continue
            wraps = ax.periodic and (360.0 - (ax.max - ax.min)) <= ax.step * (1 + 1e-9)
            for d in (-1, 1):
                k = idx[a] + d
                if wraps:
                    k %= ax.count
                elif not 0 <= k < ax.count:
                    continue
                if k != idx[a]:
                    out.add(self.flat_of(idx[:a] + (k,) + idx[a + 1:]))
        return sorted(out)

    def seed_point(self) -> int:
        """The grid point nearest the scenario's default state (the grid centre if it has no coordinates)."""
        if self.default_coordinates is None:
            return self.flat_of([n // 2 for n in self._shape])
        # the distance is a sum over axes, so the nearest point is the nearest value on each axis
        return self.flat_of([int(np.argmin(d)) for d in self._axis_distances(self.default_coordinates)])

    def point_at(self, coords: ArrayLike) -> int | None:
        """The grid point at ``coords`` (each axis within :data:`COORD_TOL`, periodic axes modulo 360°), or ``None``."""
        hits = [np.flatnonzero(d <= COORD_TOL) for d in self._axis_distances(coords)]
        return self.flat_of([int(h[0]) for h in hits]) if all(h.size for h in hits) else None

    def _axis_distances(self, coords: ArrayLike) -> list[Array]:
        """Per axis, the distance of every grid value to the coordinate (periodic axes: the shorter way round)."""
        return [np.abs((v - x + 180.0) % 360.0 - 180.0 if ax.periodic else v - x)
                for ax, v, x in zip(self.axes, self._values, np.asarray(coords, dtype=float), strict=True)]

    def continuation_order(self) -> list[tuple[int, int | None]]:
        """Every point once as ``(point, warm-start parent)``: breadth-first from :meth:`seed_point`
        (parent ``None``) over :meth:`neighbours`, so each parent is an adjacent, earlier point."""
        seed = self.seed_point()
        order: list[tuple[int, int | None]] = [(seed, None)]
        seen = {seed}
        queue = deque([seed])
        while queue:
            p = queue.popleft()
            for nb in self.neighbours(p):
                if nb not in seen:
                    seen.add(nb)
                    order.append((nb, p))
                    queue.append(nb)
        return order


def _phase_window(ax: Axis, x: float) -> float:
    """``x`` [deg] moved by whole turns into the periodic axis' window ``[min, min + 360)`` (a value within
    :data:`COORD_TOL` below ``min`` stays there: on the grid's first value, not a turn later)."""
    return ax.min + ((x - ax.min + COORD_TOL) % 360.0) - COORD_TOL


def _finite_state(state: TargetState) -> tuple[Array, Array]:
    """The state's quaternion (4,) and body rates (3,) [rad/s]; ``TargetStateError`` when malformed."""
    q = np.asarray(state.attitude_wxyz, dtype=float)
    omega = np.asarray(state.omega_body_rad_s, dtype=float)
    if q.shape != (4,) or omega.shape != (3,):
        raise TargetStateError(f"target state: expected a quaternion (4) and body rates (3), got shapes "
                               f"{q.shape}, {omega.shape}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(omega))):
        raise TargetStateError(f"target state must be finite, got attitude_wxyz {q.tolist()}, "
                               f"omega_body_rad_s {omega.tolist()}")
    return q, omega


def _check_flat_spin(omega: Array, e: Array, s: Array) -> None:
    """``TargetStateError`` saying why, unless ω_body [rad/s] is along +e and the world spin axis ``s`` lies
    in the orbital x–z plane (each within :data:`FLAT_SPIN_TOL_RAD`)."""
    if float(np.linalg.norm(omega)) == 0.0:
        raise TargetStateError("not a flat spin: the target does not rotate (ω = 0); a flat-spin table "
                               "needs a spin rate > 0")
    off = math.atan2(float(np.linalg.norm(np.cross(omega, e))), float(omega @ e))
    if off > FLAT_SPIN_TOL_RAD:
        why = ("it spins about -e, against the grid's convention ω_body = +rate·e" if off > math.pi / 2
               else f"ω_body is {off:.3g} rad away from it")
        raise TargetStateError(f"not a flat spin about the major principal axis e = {np.round(e, 6).tolist()} "
                               f"(body frame): {why} (tolerance {FLAT_SPIN_TOL_RAD:g} rad)")
    tilt = math.asin(min(1.0, abs(float(s[1]))))
    if tilt > FLAT_SPIN_TOL_RAD:
        raise TargetStateError(f"flat spin with its spin axis {np.round(s, 6).tolist()} (world) {tilt:.3g} rad "
                               f"out of the orbital x–z plane (tolerance {FLAT_SPIN_TOL_RAD:g} rad); "
                               "a flat-spin grid holds spin axes in that plane only")


def _major_axis(inertia_body_kg_m2: Array, source: str) -> Array:
    """The unit major principal axis ``(3,)`` of a symmetric inertia [kg·m²], its largest component positive."""
    eig, vecs = np.linalg.eigh(inertia_body_kg_m2)
    if eig[2] - eig[1] <= 1e-9 * abs(eig[2]):
        raise ConfigError(source, "kind", "a flat-spin grid needs a unique major axis, but the "
                          f"target's two largest principal moments are equal ({eig[1]:g}, {eig[2]:g})")
    e = vecs[:, 2]
    e = e if e[int(np.argmax(np.abs(e)))] > 0 else -e
    return e / np.linalg.norm(e)


def _minimal_rotation(a: Array, b: Array) -> Array:
    """The smallest rotation taking unit ``a`` onto unit ``b`` (``a ≠ -b``)."""
    axis = np.cross(a, b)
    sin, cos = float(np.linalg.norm(axis)), float(a @ b)
    if sin < 1e-15:
        if cos > 0:
            return np.eye(3)
        raise ValueError("antiparallel vectors: the minimal rotation is not unique")
    return axis_angle_to_matrix(axis / sin, math.atan2(sin, cos))
