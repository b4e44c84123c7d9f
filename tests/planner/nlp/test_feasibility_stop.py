"""The feasibility stop ends an IPOPT solve at the first iterate inside every constraint, and only there.

Toy problem with a known feasible set: minimise a flat regulariser subject to a disc constraint
``x² + y² ≤ 1`` relaxed elastically by a slack ``s ≥ 0`` (``x² + y² − s ≤ 1``, cost ``100 s``), started
far outside the disc — the shape of the stabilization NLP's elastic mode in miniature.
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from planner.deadline import Deadline
from planner.nlp.feasibility_stop import FeasibilityStop, StallRule


def _solve(stop: FeasibilityStop | None, x0: list[float]):
    w = ca.MX.sym("w", 3)  # x, y, slack
    g = w[0] ** 2 + w[1] ** 2 - w[2]
    options = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-12,
               "ipopt.hessian_approximation": "limited-memory", "ipopt.max_iter": 500}
    if stop is not None:
        options["iteration_callback"] = stop
        stop.arm(np.array([-np.inf]), np.array([1.0]))
    solver = ca.nlpsol("toy", "ipopt", {"x": w, "f": 1e-6 * ((w[0] - 0.3) ** 2 + w[1] ** 2) + 100 * w[2], "g": g},
                       options)
    sol = solver(x0=x0, lbx=[-np.inf, -np.inf, 0.0], ubx=[np.inf] * 3, lbg=-np.inf, ubg=1.0)
    return np.asarray(sol["x"]).ravel(), solver.stats()


def _stopped_solver(name: str) -> tuple[FeasibilityStop, ca.Function]:
    """The toy problem's solver with a fresh callback as its iteration callback (to be armed by the test)."""
    stop = FeasibilityStop(name, 3, 1, 0, slice(2, 3), slack_tol=1e-6, constraint_tol=1e-9)
    w = ca.MX.sym("w", 3)
    solver = ca.nlpsol(name + "_solver", "ipopt",
                       {"x": w, "f": 1e-6 * ((w[0] - 0.3) ** 2 + w[1] ** 2) + 100 * w[2],
                        "g": w[0] ** 2 + w[1] ** 2 - w[2]},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-12,
                        "ipopt.hessian_approximation": "limited-memory", "iteration_callback": stop})
    return stop, solver


def test_stops_at_the_first_feasible_iterate_before_ipopt_would():
    x0 = [3.0, -2.0, 12.5]  # outside the disc, slack making it feasible for the relaxed problem
    w_full, stats_full = _solve(None, x0)
    stop = FeasibilityStop("toy_stop", 3, 1, 0, slice(2, 3), slack_tol=1e-6, constraint_tol=1e-9)
    w_stop, stats_stop = _solve(stop, x0)
    assert stats_stop["return_status"] == "User_Requested_Stop" and stop.stopped
    assert stats_stop["iter_count"] < stats_full["iter_count"]
    # the returned iterate is feasible for the ORIGINAL constraint: inside the disc, slack ~0
    assert w_stop[2] <= 1e-6
    assert w_stop[0] ** 2 + w_stop[1] ** 2 <= 1.0 + 1e-6 + 1e-9


def test_never_stops_while_a_slack_is_still_open():
    # the disc is unreachable when y is pinned at 2: the slack stays ≥ 3, so the solve must run to IPOPT's end
    w = ca.MX.sym("w", 3)
    stop = FeasibilityStop("toy_open", 3, 1, 0, slice(2, 3), slack_tol=1e-6, constraint_tol=1e-9)
    stop.arm(np.array([-np.inf]), np.array([1.0]))
    solver = ca.nlpsol("toy2", "ipopt", {"x": w, "f": 100 * w[2], "g": w[0] ** 2 + w[1] ** 2 - w[2]},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "iteration_callback": stop})
    sol = solver(x0=[1.0, 2.0, 5.0], lbx=[-np.inf, 2.0, 0.0], ubx=[np.inf, 2.0, np.inf], lbg=-np.inf, ubg=1.0)
    assert not stop.stopped and solver.stats()["success"]
    assert float(sol["x"][2]) > 3.0 - 1e-6  # x² + 4 − s ≤ 1 needs s ≥ 3


def test_an_iteration_budget_ends_the_solve_after_that_many_iterations():
    x0 = [3.0, -2.0, 12.5]
    _, stats_full = _solve(None, x0)
    assert stats_full["iter_count"] > 5  # the budget below must cut the solve short
    stop, solver = _stopped_solver("toy_budget")
    kwargs = {"x0": x0, "lbx": [-np.inf, -np.inf, 0.0], "ubx": [np.inf] * 3, "lbg": -np.inf, "ubg": 1.0}
    # the budget alone (no feasibility test): exactly 3 iterations
    stop.arm(np.array([-np.inf]), np.array([1.0]), stop_when_feasible=False, max_iterations=3)
    solver(**kwargs)
    assert stop.budget_exhausted and not stop.stopped
    assert solver.stats()["iter_count"] == 3 and solver.stats()["return_status"] == "User_Requested_Stop"
    # re-armed without a budget and without the feasibility test, the same solver runs to IPOPT's own end
    stop.arm(np.array([-np.inf]), np.array([1.0]), stop_when_feasible=False)
    solver(**kwargs)
    assert not stop.budget_exhausted and not stop.stopped
    assert solver.stats()["success"] and solver.stats()["iter_count"] == stats_full["iter_count"]


def test_a_passed_deadline_ends_the_solve_at_its_first_callback():
    stop, solver = _stopped_solver("toy_deadline")
    kwargs = {"x0": [3.0, -2.0, 12.5], "lbx": [-np.inf, -np.inf, 0.0], "ubx": [np.inf] * 3, "lbg": -np.inf,
              "ubg": 1.0}
    stop.arm(np.array([-np.inf]), np.array([1.0]), stop_when_feasible=False, deadline=Deadline(time.monotonic() - 1))
    sol = solver(**kwargs)
    assert stop.out_of_time and not stop.budget_exhausted and not stop.stopped
    assert solver.stats()["iter_count"] == 0 and solver.stats()["return_status"] == "User_Requested_Stop"
    np.testing.assert_array_equal(np.asarray(sol["x"]).ravel(), kwargs["x0"])  # the start, untouched
    # a deadline far ahead never fires: the same solver runs to IPOPT's own end
    stop.arm(np.array([-np.inf]), np.array([1.0]), stop_when_feasible=False, deadline=Deadline.after(3600.0))
    solver(**kwargs)
    assert not stop.out_of_time and solver.stats()["success"]


def test_a_stall_rule_holds_only_once_the_violation_stops_falling_by_its_ratio():
    rule = StallRule(after=5, over=5, ratio=0.7)
    falling = [10.0 * 0.9**i for i in range(12)]  # 41 % less over any 5 iterations: never stalled
    assert not any(rule.holds(falling[: i + 1]) for i in range(len(falling)))
    flat = [10.0] * 12
    assert [rule.holds(flat[: i + 1]) for i in range(7)] == [False] * 5 + [True, True]  # from iteration 5 on
    exactly = [10.0, 9.0, 8.0, 7.5, 7.2, 7.0]  # 7.0 is exactly 0.7 × 10: not above it, not stalled
    assert not rule.holds(exactly) and rule.holds([*exactly[:-1], 7.0 + 1e-12])
    assert not rule.holds([5.0, 1.0, 1.0, 1.0, 1.0, 0.0])  # feasible: nothing to fall from


def test_a_least_so_far_stall_rule_forgives_a_climb_and_a_solve_that_came_near_feasible():
    rule = StallRule(after=5, over=5, ratio=0.5, least_so_far=True, floor=1e-3)
    # IPOPT's filter lets the violation climb back up for a while: the least so far halved, so no stall, where the
    # iterate-by-iterate rule of the same ratio calls it one
    climb = [8.0, 4.0, 2.0, 1.0, 0.5, 0.2, 3.0, 3.0, 3.0, 3.0, 3.0]
    assert not rule.holds(climb[:7]) and StallRule(after=5, over=5, ratio=0.5).holds(climb[:7])
    # ... but 5 iterations after its least (0.2 at iteration 5), the least so far has not halved over 5: stalled
    assert [rule.holds(climb[: i + 1]) for i in range(5, 11)] == [False] * 5 + [True]
    # a solve whose least violation reached the floor never stalls, however long it then wanders
    near = [5.0, 1.0, 1e-3, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0]
    assert not any(rule.holds(near[: i + 1]) for i in range(len(near)))
    just_above = [5.0, 1.0, 1e-3 + 1e-12, *([2.0] * 9)]
    assert rule.holds(just_above[:8]) and not rule.holds(just_above[:7])  # 5 iterations after its least
    # exactly halved over the window is progress (not above ratio × before), a hair less is a stall
    halved = [4.0, 4.0, 4.0, 4.0, 4.0, 2.0]
    assert not rule.holds(halved) and rule.holds([*halved[:-1], 2.0 + 1e-12])
    assert not rule.holds([4.0] * 5)  # before ``after``: never


def test_an_armed_stall_rule_ends_a_solve_whose_violation_stops_falling():
    # the unreachable disc of the test above (y pinned at 2), with a budget and no feasibility test: the violation
    # settles at s ≥ 3 while IPOPT goes on; a stall rule ends it, and re-armed without one the solve runs on
    w = ca.MX.sym("w", 3)
    stop = FeasibilityStop("toy_stall", 3, 1, 0, slice(2, 3), slack_tol=1e-6, constraint_tol=1e-9)
    solver = ca.nlpsol("toy_stall_solver", "ipopt", {"x": w, "f": 1e-3 * w[0] ** 2, "g": w[0] ** 2 + w[1] ** 2},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "iteration_callback": stop})
    kwargs = {"x0": [2.0, 2.0, 0.0], "lbx": [-np.inf, 2.0, 0.0], "ubx": [np.inf, 2.0, 0.0], "lbg": -np.inf,
              "ubg": 1.0}
    stop.arm(np.array([-np.inf]), np.array([1.0]), max_iterations=50, stall=StallRule(after=5, over=5, ratio=0.7))
    solver(**kwargs)
    assert stop.stalled and not stop.budget_exhausted and not stop.stopped
    stalled_at = solver.stats()["iter_count"]
    assert stalled_at >= 5 and solver.stats()["return_status"] == "User_Requested_Stop"
    stop.arm(np.array([-np.inf]), np.array([1.0]), max_iterations=50)
    solver(**kwargs)
    assert not stop.stalled and solver.stats()["iter_count"] > stalled_at
