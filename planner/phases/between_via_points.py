"""What a solved stabilization does between its via points, and the tighter via-point bounds that hold it there.

The stabilization NLP bounds the grasp torque and the clearance at its via points only. Between two of them the
braking can peak above the torque limit, or swing the grasped target into the chaser: a scenario II query's repaired
braking kept 4.4 cm between the chaser base and the target at every via point and 0.9 cm between two (verify: 0.65 cm
against the 2 cm margin). Both are read on the NLP's own model and collision engine at
:data:`~planner.phases.stabilization.DENSE_FACTOR` times as many instants; a shortfall tightens the via-point bounds
for a warm re-solve: the torque rows scaled down by the overshoot, the clearance rows of each pair that came too close
raised by how much it did (:func:`tightened`). Whether the plan holds is still judged by ``verify`` alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.nlp.outcome import SolveOutcome
from planner.phases.sampled_peak import peak_magnitude
from planner.phases.stabilization import GraspState, StabilizationProblem

Array = NDArray[np.float64]

# a torque bound is scaled by limit / peak times this (the 5 % back-off held on five grasps; a scenario II flat spin
# peaked 0.51 N·m above its via points, 10.013 N·m against the 10 N·m limit)
TORQUE_MARGIN = 0.98
# a pair holds between via points when its dense clearance exceeds the margin by this [m]: the dense instants are
# 0.19 s apart (scenario II), and a pair swinging past at 0.1 m/s dips up to 5 mm lower between two of them; a pair
# short of it has its via-point bound raised by the shortfall (a re-solve; refused only below the margin itself)
CLEARANCE_PAD_M = 0.005


@dataclass(frozen=True)
class ViaPointBounds:
    """How much tighter than the NLP's own the via-point bounds of a re-solve are."""

    torque_scale: float = 1.0  # the grasp-torque rows' bounds times this
    clearance_raise_m: tuple[float, ...] = ()  # per collision pair, added to its rows' lower bound [m] (): none

    def applied(self, problem: StabilizationProblem) -> tuple[Array, Array]:
        """``(lbg, ubg)`` of ``problem`` with these tightenings (copies)."""
        lbg, ubg = problem.lbg.copy(), problem.ubg.copy()
        rows = problem.constraints.slice("grasp_torque")
        lbg[rows] *= self.torque_scale
        ubg[rows] *= self.torque_scale
        if self.clearance_raise_m:
            lbg[problem.constraints.slice("collision")] += np.tile(self.clearance_raise_m, problem.k)
        return lbg, ubg


@dataclass(frozen=True)
class BetweenViaPoints:
    """A solved braking sampled densely on the NLP's own model: its grasp torque peak and each pair's clearance."""

    peak_torque_nm: float  # the largest |component| of the grasp moment [N·m]
    min_distance_m: Array  # (n_pairs,) each collision pair's smallest signed distance [m]


AS_SOLVED = ViaPointBounds()  # the NLP's own bounds


def between_via_points(problem: StabilizationProblem, grasp: GraspState, params: Array) -> BetweenViaPoints:
    """The braking of ``params`` from ``grasp`` at :attr:`~StabilizationProblem.dense_times_s`: its torque peak (a
    local cubic between samples, :func:`~planner.phases.sampled_peak.peak_magnitude`), each pair's least clearance."""
    torques, distances = (np.asarray(a) for a in problem.dense_samples()(params, problem.parameters(grasp)))
    return BetweenViaPoints(peak_magnitude(problem.dense_times_s, torques.reshape(-1, 3)),
                            distances.reshape(len(problem.dense_times_s), -1).min(axis=0))


def tightened(problem: StabilizationProblem, bounds: ViaPointBounds,
              seen: BetweenViaPoints) -> ViaPointBounds | None:
    """``bounds`` tightened where ``seen`` peaks above the torque limit or comes closer than the collision margin plus
    :data:`CLEARANCE_PAD_M` between the via points, else None: it holds."""
    over_torque = _over_torque(problem, seen)
    short_m = _clearance_short_m(problem, seen)
    if not over_torque and not short_m.any():
        return None
    scale = bounds.torque_scale * (TORQUE_MARGIN * problem.torque_limit / seen.peak_torque_nm if over_torque else 1.0)
    raised = np.asarray(bounds.clearance_raise_m or np.zeros(len(short_m)), dtype=float) + short_m
    return ViaPointBounds(float(scale), tuple(float(r) for r in raised))


def _over_torque(problem: StabilizationProblem, seen: BetweenViaPoints) -> bool:
    """Whether ``seen``'s torque peaks above a (finite) torque limit."""
    return bool(np.isfinite(problem.torque_limit) and seen.peak_torque_nm > problem.torque_limit)


def _clearance_short_m(problem: StabilizationProblem, seen: BetweenViaPoints, pad_m: float = CLEARANCE_PAD_M) -> Array:
    """(n_pairs,) how far each pair's dense clearance falls below the margin plus ``pad_m`` [m] (0: it holds)."""
    return np.maximum(problem.scenario.limits.collision_margin_m + pad_m - seen.min_distance_m, 0.0)


def within_limits(problem: StabilizationProblem, seen: BetweenViaPoints) -> bool:
    """Whether ``seen`` keeps the torque limit and the collision margin themselves (the pad aside)."""
    return not _over_torque(problem, seen) and not _clearance_short_m(problem, seen, 0.0).any()


def failed_between(problem: StabilizationProblem, seen: BetweenViaPoints) -> SolveOutcome:
    """The outcome of a braking still beyond a limit between its via points after every re-solve."""
    if _over_torque(problem, seen):
        return SolveOutcome.TORQUE_BETWEEN_VIA_POINTS
    return SolveOutcome.CLEARANCE_BETWEEN_VIA_POINTS
