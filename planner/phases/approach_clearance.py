"""The approach's clearance between its via points, on the NLP's own distance engine (paper Eq. 19).

The approach NLP holds every pair's distance at its k via points only, 0.02 m above the clearance (the back-off
of :mod:`planner.nlp.constraint_backoff`). Where a link passes a corner or a thin shape fast, the distance dips
deeper than that between two via points, and verify (which samples every 0.02 s) refuses the plan. This check
samples the re-simulated approach as densely as verify does and, where a pair dips below its clearance, says how
much higher that pair's bound must be at the two via points around the dip: the depth of the dip below them, so
that the same dip from the raised bound ends at the back-off above the clearance.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.collision.callback import frame_poses
from planner.model.robot import fk_function
from planner.model.target import TargetMotion
from planner.nlp import constraint_backoff as backoff
from planner.phases.approach import ApproachProblem, ApproachSolution
from planner.phases.approach_constraints import ScenePoses
from planner.plan_samples import PhaseSamples

Array = NDArray[np.float64]

# a dip this close above the clearance counts as one: verify samples other instants than this check does
DIP_TRIGGER_M = 1e-3


@dataclass(frozen=True)
class ClearanceDip:
    """The deepest dip of one pair between two via points: where, how deep below the clearance [m]."""

    pair: str  # "A-B"
    t_s: float  # time of the dip [s since the approach's start]
    distance_m: float  # the pair's distance there [m]
    clearance_m: float  # what the contact rule asks of it [m]


class ApproachClearance:
    """Dense clearance of an approach against :class:`ApproachProblem`'s own scene, pairs and via points."""

    def __init__(self, problem: ApproachProblem) -> None:
        self.problem = problem
        sc = problem.scenario
        poses = ScenePoses(sc.robot, fk_function(sc.robot), ca.DM(sc.target.p_world_com))
        x, q, R = ca.SX.sym("x", 7), ca.SX.sym("q", sc.robot.n_joints), ca.SX.sym("R", 3, 3)
        self._poses = ca.Function("approach_body_poses", [x, q, R], [poses.function(x, q, R)[0]])
        self.n_pairs = len(problem.scene.pairs)
        rows = problem.constraints.slice("collision")
        self.n_points = (rows.stop - rows.start) // self.n_pairs
        via_bounds = problem.lbg[rows][: problem.k * self.n_pairs].reshape(problem.k, self.n_pairs)
        self.clearance_m = via_bounds[0] - backoff.COLLISION_M  # every via point asks the same of a pair
        self.via_times_s = sc.phases.approach_s * np.arange(1, problem.k + 1) / problem.k

    def distances(self, samples: PhaseSamples, start_delay_s: float, motion: TargetMotion) -> Array:
        """Every pair's distance [m] at every sample of the approach ``(n, pairs)``."""
        return self.distances_at(start_delay_s + samples.t, samples.q, samples.x_base, motion)

    def distances_at(self, t_s: Array, q: Array, x_base: Array, motion: TargetMotion) -> Array:
        """Every pair's distance [m] ``(n, pairs)`` with the chaser at joints ``q`` ``(n, 7)`` [rad] and base poses
        ``x_base`` ``(n, 7)`` and the target where ``motion`` has it at ``t_s`` ``(n,)`` [s since the observation]."""
        R_target, _ = motion.body_pose(t_s)
        n = len(t_s)
        stacked = self._poses.map(n)(x_base.T, q.T, np.hstack(R_target))
        blocks = np.asarray(stacked).T.reshape(n, -1, 12)
        return self.problem.scene.sweep(frame_poses(blocks, self.problem.body_order)).distance_m

    def raised_bounds(self, app: ApproachSolution, samples: PhaseSamples,
                      motion: TargetMotion) -> tuple[Array, list[ClearanceDip]]:
        """How much [m] to raise each collision row's lower bound (the NLP's row order; 0 where nothing dips) so
        that the dips of ``app``'s approach end above the clearance, and the dips found (deepest per pair first)."""
        d = self.distances(samples, app.start_delay_s, motion)
        k, m = self.problem.k, self.n_pairs
        segment = np.clip(np.ceil(samples.t / self.via_times_s[0] - 1e-9).astype(int) - 1, 0, k - 1)
        via_sample = np.searchsorted(samples.t, self.via_times_s - 1e-9)
        raised = np.zeros((self.n_points, m))  # the via points' rows, then the tracking nodes' (never raised)
        dips: list[ClearanceDip] = []
        for j in range(k):
            in_segment = segment == j
            if not in_segment.any():
                continue
            worst = np.where(in_segment[:, None], d, np.inf).argmin(axis=0)
            d_min = d[worst, np.arange(m)]
            for pair in np.flatnonzero(d_min < self.clearance_m + DIP_TRIGGER_M):
                around = [v for v in (j - 1, j) if v >= 0]
                dip = min(d[via_sample[v], pair] for v in around) - d_min[pair]
                raised[around, pair] = np.maximum(raised[around, pair], max(dip, DIP_TRIGGER_M))
                a, b = self.problem.scene.pairs[pair]
                dips.append(ClearanceDip(f"{a}-{b}", float(samples.t[worst[pair]]), float(d_min[pair]),
                                         float(self.clearance_m[pair])))
        return raised.ravel(), sorted(dips, key=lambda x: x.distance_m - x.clearance_m)
