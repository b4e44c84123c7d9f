"""Which failed checks no braking can change (``planner.verify.before_grasp``): by name, or by where the worst value
lies against the grasp instant, at the instant's edges on purpose (exactly at it, within the join tolerance, just
before it). Real plans: tests/lut/query/test_stabilization_repair.py (a braking too harsh, joints overspeeding before
the grasp) and tests/planner/test_plan_retry.py (a rushed approach)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from planner.verify.before_grasp import BEFORE_THE_GRASP, failed_before_grasp, judged_before_grasp
from planner.verify.checks import CheckResult
from planner.verify.kinematics import TIME_TOL_S

T_GRASP = 50.0


def _check(name: str, t_s: float | None, passed: bool = False) -> CheckResult:
    return CheckResult(name, 2.0, 1.0, 1.0 if passed else -1.0, passed, "-", "", t_s)


@pytest.mark.parametrize("name", sorted(BEFORE_THE_GRASP))
def test_the_checks_of_the_approach_tracking_and_grasp_count_wherever_their_worst_value_lies(name):
    for t_s in (None, T_GRASP, T_GRASP + 10.0):
        assert judged_before_grasp(_check(name, t_s), T_GRASP)


@pytest.mark.parametrize(("t_s", "before"), [
    (T_GRASP - 1.0, True),
    (T_GRASP - 2 * TIME_TOL_S, True),   # just before the instant, beyond the join tolerance
    (T_GRASP - 0.5 * TIME_TOL_S, False),  # the grasp instant itself, within the tolerance
    (T_GRASP, False),
    (T_GRASP + 1.0, False),
    (None, False),  # no time: not known to lie before it
])
def test_any_other_check_counts_only_when_its_worst_value_lies_before_the_grasp(t_s, before):
    for name in ("collision", "joint_position", "joint_velocity", "grasp_torque"):
        assert judged_before_grasp(_check(name, t_s), T_GRASP) is before


def test_only_failed_checks_are_listed_in_report_order():
    checks = {"joint_velocity": _check("joint_velocity", 10.0),
              "collision": _check("collision", 10.0, passed=True),
              "grasp_torque": _check("grasp_torque", 60.0),
              "grasp_position": _check("grasp_position", T_GRASP)}
    report = SimpleNamespace(checks=checks, t_grasp_s=T_GRASP)
    assert [c.name for c in failed_before_grasp(report)] == ["joint_velocity", "grasp_position"]
