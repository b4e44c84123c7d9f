"""Verify's collision check: every pair at every verified sample, by verify's own distance engine.

The distances come from :mod:`planner.verify.distance` (closed form, vectorised over all samples at once),
verify's own engine, written apart from the NLPs' (:mod:`planner.collision.closed_form`) with other algorithms,
so one engine's error is caught by the other. Which bodies and pairs
exist is the scene's layout (:func:`planner.collision.layout.scene_layout`), and which clearance each pair must keep
when is the handle-contact rule (:mod:`planner.collision.contact_rule`): both are the specification being checked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.collision.contact_rule import (
    APPROACH,
    STABILIZATION,
    TRACKING,
    closed_backoff_m,
    required_clearance_m,
)
from planner.collision.layout import SceneLayout
from planner.model.shapes import PlacedShape
from planner.verify.distance import shape_distance

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PairSweep:
    """Signed distances of every layout pair at n samples: ``distance_m`` (n, m), witness points on A and on
    B ``p_world_a``, ``p_world_b`` (n, m, 3), and which shapes realise each minimum (:meth:`shape_pair`)."""

    distance_m: Array
    p_world_a: Array
    p_world_b: Array
    combo: NDArray[np.int_]  # (n, m) index into ``shape_names[pair]`` of the shapes realising the minimum
    shape_names: list[list[tuple[str, str]]]  # per pair, its (shape of A, shape of B) combinations

    def shape_pair(self, i: int, j: int) -> tuple[str, str]:
        """Names of the shape of A and of B realising pair ``j``'s distance at sample ``i``."""
        return self.shape_names[j][self.combo[i, j]]


def sweep_pairs(layout: SceneLayout, T_world_frame: dict[str, Array]) -> PairSweep:
    """Distances of every pair of ``layout`` with the frames posed by (n, 4, 4) stacks (world, m)."""
    bodies = {b.name: b for b in layout.bodies}
    n = len(next(iter(T_world_frame.values())))
    m = len(layout.pairs)
    d = np.full((n, m), np.inf)
    pa, pb = np.zeros((n, m, 3)), np.zeros((n, m, 3))
    combo = np.zeros((n, m), dtype=int)
    names: list[list[tuple[str, str]]] = []
    posed: dict[tuple[str, str], Array] = {}  # (body, shape) → its (n, 4, 4) world poses, once per sweep

    def world_pose(body: str, shape: PlacedShape) -> Array:
        key = (body, shape.name)
        if key not in posed:
            posed[key] = T_world_frame[bodies[body].frame_name] @ shape.T_body_shape
        return posed[key]

    for k, (a, b) in enumerate(layout.pairs):
        names.append([])
        for sa in bodies[a].shapes:
            for sb in bodies[b].shapes:
                r = shape_distance(sa.shape, world_pose(a, sa), sb.shape, world_pose(b, sb))
                better = r.distance_m < d[:, k]
                d[better, k] = r.distance_m[better]
                pa[better, k], pb[better, k] = r.p_world_a[better], r.p_world_b[better]
                combo[better, k] = len(names[k])
                names[k].append((sa.name, sb.name))
    return PairSweep(d, pa, pb, combo, names)


def required_clearances(layout: SceneLayout, margin_m: float, t_s: Array, phase_index: Array,
                        phases: dict[str, tuple[float, float]], backoff0_m: float) -> Array:
    """(n, m) smallest signed distance each pair may have at each sample (``-inf``: exempt), by the contact rule."""
    t_start, t_end = (float(v) for v in phases["tracking"])
    out = np.empty((len(t_s), len(layout.pairs)))
    out[:] = required_clearance_m(layout.pairs, layout.gripper_handle, margin_m, APPROACH)
    out[phase_index == STABILIZATION] = required_clearance_m(layout.pairs, layout.gripper_handle, margin_m,
                                                             STABILIZATION)  # no back-off closes outside tracking
    for i in np.flatnonzero(phase_index == TRACKING):
        closed = closed_backoff_m(backoff0_m, float(t_s[i]) - t_start, t_end - t_start)
        out[i] = required_clearance_m(layout.pairs, layout.gripper_handle, margin_m, TRACKING, closed)
    return out
