"""Stop IPOPT at the first iterate that satisfies every constraint of a pure feasibility problem.

When a phase has no cost to optimise (all its weights zero), any point inside the constraints is a
solution. IPOPT's own test also asks for a small dual infeasibility, which a limited-memory Hessian on
a few thousand collision and wrench constraints reaches slowly if at all: the iterates are feasible long
before, and then wander chasing only the 1e-6 regulariser. This callback ends the solve there instead
("User_Requested_Stop" in IPOPT's stats; the caller reports it as ``SolveOutcome.FEASIBLE_POINT_FOUND``).

Optional slack variables of an elastic (ℓ1-penalty) formulation are checked too: a relaxed constraint
is satisfied only once its slack is below ``slack_tol``.

The same callback can also end a solve after an iteration budget (``max_iterations`` in :meth:`arm`,
``budget_exhausted`` afterwards): the planner gives a stabilization from one grasp a budget when another
grasp is there to try (:mod:`planner.plan_grasps`). The budget works with or without the feasibility test.
And it ends a solve once the plan's deadline (:mod:`planner.deadline`) has passed (``out_of_time`` afterwards):
the iterate reached by then is the answer.

It also keeps the least violating iterate of the solve (:meth:`least_violating`): an unsuccessful solve's last
iterate can be anywhere, while the least violating one is what the solve came closest to, which a plan that fails
should show. Armed with a :class:`StallRule`, it ends a solve whose violation has stopped falling (``stalled``
afterwards): a query's repair that will not succeed within its budget gives up early.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from planner.deadline import NO_DEADLINE, Deadline
from planner.excess import relative_excess_sum

Array = NDArray[np.float64]


@dataclass(frozen=True)
class StallRule:
    """A solve has stalled at iteration ``i ≥ after`` when its relative violation (:meth:`FeasibilityStop.violation`)
    is still above ``ratio`` times what it was ``over`` iterations before. With ``least_so_far`` the violation compared
    is the least of the solve's iterations up to then, and a solve whose least violation is at most ``floor`` never
    stalls: a solve that does not stop at its first feasible iterate (an approach) may leave the feasible set for a
    while on its way to converge (IPOPT's filter accepts a rising violation), which is no stall."""

    after: int
    over: int
    ratio: float
    least_so_far: bool = False
    floor: float = 0.0

    def holds(self, violations: list[float]) -> bool:
        """True when the violations of iterations 0, 1, … (the last one the current iterate's) have stalled."""
        i = len(violations) - 1
        if i < max(self.after, self.over):
            return False
        if self.least_so_far:
            now, before = min(violations), min(violations[: i - self.over + 1])
        else:
            now, before = violations[i], violations[i - self.over]
        return now > self.floor and now > self.ratio * before


def row_limits(lbg: Array, ubg: Array) -> Array:
    """Per constraint row, the magnitude of its largest finite bound (0 where it has none): the limit its excess is
    counted against (:mod:`planner.excess`)."""
    bounds = np.where(np.isfinite(lbg), np.abs(lbg), 0.0), np.where(np.isfinite(ubg), np.abs(ubg), 0.0)
    return np.maximum(*bounds)


class FeasibilityStop(ca.Callback):
    """IPOPT iteration callback: returns 1 (stop) once ``lbg − tol ≤ g ≤ ubg + tol`` and slacks ≤ slack_tol,
    or once the armed iteration budget is spent, or once the armed deadline has passed."""

    def __init__(self, name: str, n_x: int, n_g: int, n_p: int, slack_index: slice, slack_tol: float | Array,
                 constraint_tol: float) -> None:
        ca.Callback.__init__(self)
        self.n_x, self.n_g, self.n_p = n_x, n_g, n_p
        self.slack_index = slack_index
        self.slack_tol = np.asarray(slack_tol, dtype=float)  # scalar or one per slack
        self.constraint_tol = constraint_tol
        self.lbg = np.full(n_g, -np.inf)
        self.ubg = np.full(n_g, np.inf)
        self.stopped = False
        self.stop_when_feasible = True
        self.max_iterations: int | None = None
        self.budget_exhausted = False
        self.deadline = NO_DEADLINE
        self.out_of_time = False
        self._calls = 0
        self._row_limit = np.zeros(n_g)
        self._least_violation = np.inf
        self._least_violating: tuple[Array, float] | None = None  # (x, f)
        self.stall: StallRule | None = None
        self.stalled = False
        self._violations: list[float] = []  # relative violation of each iteration of the current solve
        self.construct(name, {})

    def arm(self, lbg: Array, ubg: Array, stop_when_feasible: bool = True, max_iterations: int | None = None,
            deadline: Deadline = NO_DEADLINE, stall: StallRule | None = None) -> None:
        """Set the bounds of the coming solve and clear the stop flags.

        ``stop_when_feasible`` False keeps only the budget; ``max_iterations`` (None: none) stops the solve
        after that many IPOPT iterations; ``deadline`` stops it at the first iteration past that instant; ``stall``
        (None: none) stops it once its violation has stopped falling.
        """
        self.lbg, self.ubg = np.asarray(lbg, dtype=float), np.asarray(ubg, dtype=float)
        self.stop_when_feasible = stop_when_feasible
        self.max_iterations = max_iterations
        self.deadline = deadline
        self.stall = stall
        self.stopped = False
        self.budget_exhausted = False
        self.out_of_time = False
        self.stalled = False
        self._violations = []
        self._calls = 0
        self._row_limit = row_limits(self.lbg, self.ubg)
        self._least_violation, self._least_violating = np.inf, None

    def violation(self, g: Array) -> float:
        """Σ over the rows of ``g`` of its excess beyond the armed bounds, each relative to its bound
        (:func:`planner.excess.relative_excess_sum`; a NaN row makes it infinite)."""
        excess = np.where(np.isnan(g), np.inf, np.maximum(np.maximum(self.lbg - g, g - self.ubg), 0.0))
        return relative_excess_sum(excess, self._row_limit)

    def least_violating(self, x: Array, f: float, g: Array) -> tuple[Array, float]:
        """``(x, f)`` of the solve's least violating iterate, the given final iterate ``(x, f, g)`` included."""
        if self._least_violating is not None and self._least_violation < self.violation(g):
            return self._least_violating
        return x, f

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "stop"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        size = {"f": 1, "x": self.n_x, "lam_x": self.n_x, "g": self.n_g, "lam_g": self.n_g}.get(name, self.n_p)
        return ca.Sparsity.dense(size)

    def eval(self, arg: list) -> list:
        iteration = self._calls  # IPOPT calls back once per iteration, iteration 0 (the start) included
        self._calls += 1
        x = np.asarray(arg[ca.nlpsol_out().index("x")]).ravel()
        g = np.asarray(arg[ca.nlpsol_out().index("g")]).ravel()
        relative = self.violation(g)
        self._violations.append(relative)
        if relative < self._least_violation:
            self._least_violation = relative
            self._least_violating = x.copy(), float(arg[ca.nlpsol_out().index("f")])
        if self.stop_when_feasible:
            violation = float(np.max(np.maximum(self.lbg - g, g - self.ubg), initial=0.0))
            self.stopped = violation <= self.constraint_tol and bool(np.all(x[self.slack_index] <= self.slack_tol))
        self.budget_exhausted = not self.stopped and self.max_iterations is not None \
            and iteration >= self.max_iterations
        self.stalled = not (self.stopped or self.budget_exhausted) and self.stall is not None \
            and self.stall.holds(self._violations)
        self.out_of_time = not (self.stopped or self.budget_exhausted or self.stalled) and self.deadline.passed
        return [1.0 if self.stopped or self.budget_exhausted or self.stalled or self.out_of_time else 0.0]
