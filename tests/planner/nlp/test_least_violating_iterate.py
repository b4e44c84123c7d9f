"""An unsuccessful solve answers with its least violating iterate, not wherever it stopped.

The measure (:meth:`FeasibilityStop.violation`) on hand-made rows at their degenerate cases (on the bound, inside,
a zero bound, an infinite one, NaN) and the choice over a sequence of iterates fed to the callback. The
stabilization solve's answer is tested in tests/planner/phases/test_stabilization.py.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from planner.nlp.feasibility_stop import FeasibilityStop, row_limits

INF = np.inf


def _stop(lbg, ubg) -> FeasibilityStop:
    stop = FeasibilityStop("least_violating_test", 2, len(lbg), 0, slice(0, 0), 0.0, 0.0)
    stop.arm(np.asarray(lbg, float), np.asarray(ubg, float), stop_when_feasible=False)
    return stop


def _feed(stop: FeasibilityStop, x, g, f=0.0) -> None:
    """One IPOPT iteration as the callback sees it."""
    values = {"x": x, "f": [f], "g": g, "lam_x": np.zeros(2), "lam_g": np.zeros(len(g)), "lam_p": np.zeros(0)}
    stop.eval([ca.DM(np.asarray(values[name], float)) for name in ca.nlpsol_out()])


def test_each_row_counts_in_units_of_its_own_bound():
    # a torque box ±10 N·m, a clearance ≥ 0.02 m, an end rate = 0 rad/s, a free row
    lbg, ubg = [-10.0, 0.02, 0.0, -INF], [10.0, INF, 0.0, INF]
    np.testing.assert_array_equal(row_limits(np.array(lbg), np.array(ubg)), [10.0, 0.02, 0.0, 0.0])
    stop = _stop(lbg, ubg)
    assert stop.violation(np.array([10.0, 0.02, 0.0, 1e9])) == 0.0  # on every bound: nothing over
    assert stop.violation(np.array([-3.0, 5.0, 0.0, -1e9])) == 0.0  # inside
    # 2 N·m over a 10 N·m limit, 1 cm short of a 2 cm clearance, 0.1 rad/s off a zero bound
    assert stop.violation(np.array([12.0, 0.01, -0.1, 0.0])) == pytest.approx(0.2 + 0.5 + 0.1)
    assert stop.violation(np.array([np.nan, 0.02, 0.0, 0.0])) == INF  # NaN is never the least violating


def test_the_least_violating_of_the_iterates_is_kept_and_the_final_one_wins_ties():
    stop = _stop([-10.0], [10.0])
    for x, g in (([0.0, 0.0], [30.0]), ([1.0, 1.0], [11.0]), ([2.0, 2.0], [-90.0])):
        _feed(stop, x, g, f=float(x[0]))
    x, f = stop.least_violating(np.array([3.0, 3.0]), 3.0, np.array([400.0]))  # the final iterate diverged
    np.testing.assert_array_equal(x, [1.0, 1.0])
    assert f == 1.0
    x, _ = stop.least_violating(np.array([4.0, 4.0]), 4.0, np.array([11.0]))  # as good as the best: the final one
    np.testing.assert_array_equal(x, [4.0, 4.0])
    stop.arm(np.array([-10.0]), np.array([10.0]))  # a new solve forgets the last one's iterates
    x, _ = stop.least_violating(np.array([5.0, 5.0]), 5.0, np.array([400.0]))
    np.testing.assert_array_equal(x, [5.0, 5.0])
