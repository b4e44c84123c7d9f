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

from planner.collision.contact_rule import TRACKING, closed_backoff_m, required_clearance_m
from planner.collision.layout import SceneLayout
from planner.verify.distance import shape_distance

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PairSweep:
    """Signed distances of every layout pair at n samples: ``distance_m`` (n, m), witness points on A and on
    B ``p_world_a``, ``p_world_b`` (n, m, 3), and the shapes realising each minimum ``shape_pair`` (n, m)."""

    distance_m: Array
    p_world_a: Array
    p_world_b: Array
    shape_pair: list[list[tuple[str, str]]]


def sweep_pairs(layout: SceneLayout, T_world_frame: dict[str, Array]) -> PairSweep:
    """Distances of every pair of ``layout`` with the frames posed by (n, 4, 4) stacks (world, m)."""
    bodies = {b.name: b for b in layout.bodies}
    n = len(next(iter(T_world_frame.values())))
    m = len(layout.pairs)
    d = np.full((n, m), np.inf)
    pa, pb = np.zeros((n, m, 3)), np.zeros((n, m, 3))
    combo = np.zeros((n, m), dtype=int)
    names: list[list[tuple[str, str]]] = []
    for k, (a, b) in enumerate(layout.pairs):
        names.append([])
        for sa in bodies[a].shapes:
            Ta = T_world_frame[bodies[a].frame_name] @ sa.T_body_shape
            for sb in bodies[b].shapes:
                r = shape_distance(sa.shape, Ta, sb.shape, T_world_frame[bodies[b].frame_name] @ sb.T_body_shape)
                better = r.distance_m < d[:, k]
                d[better, k] = r.distance_m[better]
                pa[better, k], pb[better, k] = r.p_world_a[better], r.p_world_b[better]
                combo[better, k] = len(names[k])
                names[k].append((sa.name, sb.name))
    labels = [[names[k][c] for k, c in enumerate(row)] for row in combo]
    return PairSweep(d, pa, pb, labels)


def required_clearances(layout: SceneLayout, margin_m: float, t_s: Array, phase_index: Array,
                        phases: dict[str, tuple[float, float]], backoff0_m: float) -> Array:
    """(n, m) smallest signed distance each pair may have at each sample (``-inf``: exempt), by the contact rule."""
    t_start, t_end = (float(v) for v in phases["tracking"])
    out = np.empty((len(t_s), len(layout.pairs)))
    for i, (t, p) in enumerate(zip(t_s, phase_index, strict=True)):
        closed = closed_backoff_m(backoff0_m, float(t) - t_start, t_end - t_start) if p == TRACKING else 0.0
        out[i] = required_clearance_m(layout.pairs, layout.gripper_handle, margin_m, int(p), closed)
    return out
