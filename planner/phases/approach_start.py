"""Where the chaser may wait: θ_in at a base offset clear of the target when the approach starts.

The approach starts at rest at the fixed configuration θ_in (Eq. 23) with the base at θ_b(0), and the NLP holds every
pair's clearance from its first via point on. A start inside the target is one the NLP can mend only by moving the
base, away from the pre-grasp the scan reached it for: at the scenario II states whose approach converged from no
start, every scanned guess began with the arm 0.1-0.9 m inside the target.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.collision.layout import TARGET_BODY
from planner.collision.nlp_scene import world_poses
from planner.collision.scene_distances import CollisionScene
from planner.config.scenario import Scenario
from planner.model.robot import fk_function
from planner.model.target import TargetMotion

Array = NDArray[np.float64]

# once its scanned meeting times are spent, a cold plan tries the chaser waiting elsewhere in its base-offset box:
# θ_b(0) held near each bound and the middle of each axis (a 3 × 3 grid), farthest from the first grasp's first (a
# nearby base repeats the geometry that failed), skipping those within BASE_OFFSET_GAP_M of a grasp tried: where the
# chaser waits decides where the braked target swings
BASE_OFFSETS_PER_AXIS = 3
BASE_OFFSET_GAP_M = 0.25


def base_offset_grid(scenario: Scenario, per_axis: int) -> list[Array]:
    """θ_b(0) [m] (x, z) at ``per_axis`` evenly spaced values of each axis of the scenario's base-offset box, bounds
    included, in grid order (x slowest)."""
    (x_lo, x_hi), (z_lo, z_hi) = scenario.base_offset_bounds_m
    return [np.array([x, z]) for x in np.unique(np.linspace(x_lo, x_hi, per_axis))
            for z in np.unique(np.linspace(z_lo, z_hi, per_axis))]


def other_base_offsets(scenario: Scenario, first_m: Array) -> list[Array]:
    """θ_b(0) [m] (x, z) of the grid over the scenario's base-offset box, farthest from ``first_m`` first (ties: in
    grid order), those within :data:`BASE_OFFSET_GAP_M` of it left out."""
    grid = base_offset_grid(scenario, BASE_OFFSETS_PER_AXIS)
    away = [b for b in grid if np.linalg.norm(b - first_m) >= BASE_OFFSET_GAP_M]
    return sorted(away, key=lambda b: -float(np.linalg.norm(b - first_m)))


def starts_elsewhere_in_box(scenario: Scenario, starts: list[Array], per_axis: int) -> list[list[Array]]:
    """For each point of :func:`base_offset_grid` but the scenario's base-offset guess, ``starts`` (``[q, b_x, b_z]``,
    the base at the guess) with the base moved to that point [m]."""
    return [[np.concatenate([x[:-2], b]) for x in starts] for b in base_offset_grid(scenario, per_axis)
            if not np.allclose(b, scenario.base_offset_guess_m)]


class StartClearance:
    """θ_in's clearance from the target at the approach's start, for one target motion, at any base offset."""

    def __init__(self, scenario: Scenario, scene: CollisionScene, motion: TargetMotion) -> None:
        self.scenario, self.scene, self.motion = scenario, scene, motion
        # θ_in's body poses with the base at the origin: a base offset only translates them
        self._at_origin = world_poses(scenario.robot, fk_function(scenario.robot)(scenario.q_initial), np.eye(3),
                                      np.zeros(3), np.eye(4))

    def distances(self, base_offsets_m: Array, t_s: float) -> Array:
        """Every pair's signed distance (n, pairs) [m] of θ_in with the base at each of ``base_offsets_m`` (n, 2)
        (x, z) against the target at ``t_s`` [s]."""
        n = len(base_offsets_m)
        shift = np.column_stack([base_offsets_m[:, 0], np.zeros(n), base_offsets_m[:, 1]])
        T_target = self.motion.T_world_body(t_s)
        frames = {}
        for name, T in self._at_origin.items():
            stack = np.repeat((T_target if name == TARGET_BODY else T)[None], n, axis=0)
            if name != TARGET_BODY:
                stack[:, :3, 3] += shift
            frames[name] = stack
        return self.scene.sweep(frames).distance_m

    def is_clear(self, base_offset_m: Array, t_s: float) -> bool:
        """True when θ_in at ``base_offset_m`` (x, z) [m] is clear of the target at ``t_s`` [s] by the collision
        margin."""
        closest = self.distances(np.asarray(base_offset_m, dtype=float)[None], t_s).min()
        return bool(closest >= self.scenario.limits.collision_margin_m)
