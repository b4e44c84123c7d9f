"""A plan's weighted approach cost terms (paper Eq. 14–16), from its parameters, so a query compares like with like.

The approach NLP minimises ``w_E ‖θ_b(0)‖² − w_M w(q(t_f¹)) − w_D d_min`` (planner.phases.approach). A query's
plan and each table corner are scored here by the same terms from their stored parameters: Eq. 16 from the base
offset, Eq. 14 from the joints at the end of the approach spline (they depend on the spline alone), and Eq. 15
from the densely verified smallest distance (the NLP's slack lower-bounds it at its via points; with an
``overscale`` ≠ 1 the NLP measures an enlarged robot, which a verified plan does not record).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lut.table.point_result import PointResult
from planner.config.scenario import Scenario
from planner.model.freefloating import FreeFloatingModel
from planner.nlp.bspline import UniformCubicBSpline
from planner.nlp.costs import approach_energy, manipulability
from planner.nlp.phase_spline import approach_vertices
from planner.plan_parameters import ApproachParameters

# (scenario weight name, unit, sign in the minimised sum): Eq. 14 and 15 are maximised
TERMS = (("approach_energy", "m²", 1.0), ("manipulability", "", -1.0), ("min_distance", "m", -1.0))
STABILIZATION_WEIGHTS = ("attitude_disturbance", "peak_wrench")  # weighted in the stabilization NLP, not scored here


@dataclass(frozen=True)
class CostTerm:
    """One weighted term: its raw value (in ``unit``), its weight, and its signed share of the minimised total."""

    name: str
    unit: str
    value: float
    weight: float
    sign: float  # +1 minimised, −1 maximised

    @property
    def weighted(self) -> float:
        """The term's share of the minimised total."""
        return self.sign * self.weight * self.value


@dataclass(frozen=True)
class CostBreakdown:
    """A plan's weighted approach cost terms; ``label`` says whose (``"plan"``, ``"corner 12"``)."""

    label: str
    terms: tuple[CostTerm, ...]

    @property
    def total(self) -> float:
        """The minimised weighted sum (the approach NLP's objective, Eq. 14–16)."""
        return float(sum(t.weighted for t in self.terms))

    def as_dict(self) -> dict[str, float | str]:
        """``{"label", <term>: value, "total"}`` (the query's machine-readable output)."""
        return {"label": self.label, **{t.name: t.value for t in self.terms}, "total": self.total}


class CostScorer:
    """Scores plan parameters by a scenario's weighted approach cost terms (built once per scenario)."""

    def __init__(self, scenario: Scenario, ff: FreeFloatingModel, spline: UniformCubicBSpline) -> None:
        self.scenario = scenario
        self.ff = ff
        self.spline = spline

    @property
    def weighted_terms(self) -> tuple[tuple[str, str, float, float], ...]:
        """``(name, unit, sign, weight)`` of every term the scenario weights (> 0)."""
        c = self.scenario.costs
        return tuple((name, unit, sign, getattr(c, name)) for name, unit, sign in TERMS if getattr(c, name) > 0)

    @property
    def feasibility_only(self) -> bool:
        """Whether every cost weight is zero (the table holds feasible plans, not optima)."""
        c = self.scenario.costs
        return not self.weighted_terms and not any(getattr(c, name) > 0 for name in STABILIZATION_WEIGHTS)

    @property
    def unscored_weights(self) -> tuple[str, ...]:
        """The stabilization terms the scenario weights, which this scorer does not compare."""
        return tuple(name for name in STABILIZATION_WEIGHTS if getattr(self.scenario.costs, name) > 0)

    def manipulability_end(self, approach: ApproachParameters) -> float:
        """Eq. 14 at the end of the approach, ``q(t_f¹)`` of the parameters' spline (dimensionless)."""
        vertices = approach_vertices(self.spline, np.asarray(self.scenario.q_initial, dtype=float),
                                     np.asarray(approach.params, dtype=float))
        q_end = np.asarray(self.spline.evaluate(vertices, [self.scenario.phases.approach_s]), dtype=float)[0]
        return manipulability(np.asarray(self.ff.gen_jacobian(q_end)[0], dtype=float))

    def score_stored(self, label: str, stored: PointResult) -> CostBreakdown:
        """The weighted terms of a feasible table point's plan, from its parameters and verified clearance (NaN
        without ``costs/min_distance_m``)."""
        assert stored.parameters is not None, "only a feasible point's plan has parameters to score"
        return self.score(label, stored.parameters.approach, stored.costs.get("min_distance_m", float("nan")))

    def score(self, label: str, approach: ApproachParameters, min_distance_m: float) -> CostBreakdown:
        """The weighted terms of ``approach`` whose verified smallest distance is ``min_distance_m`` [m]."""
        values = {"approach_energy": lambda: approach_energy(np.asarray(approach.base_offset_m, dtype=float)),
                  "manipulability": lambda: self.manipulability_end(approach),
                  "min_distance": lambda: float(min_distance_m)}
        return CostBreakdown(label, tuple(CostTerm(name, unit, values[name](), weight, sign)
                                          for name, unit, sign, weight in self.weighted_terms))


def cost_ratio(cost: ArrayLike, lowest: float, floor: float) -> NDArray[np.float64]:
    """1 + the excess of ``cost`` over ``lowest`` relative to the lowest's size, at least ``floor`` (costs near zero are
    alike): the ratio of the two costs for a positive lowest cost above the floor; for a negative one (Eq. 14-15 are
    maximised) the excess in units of its size."""
    return 1.0 + (np.asarray(cost, dtype=float) - lowest) / max(abs(lowest), floor)
