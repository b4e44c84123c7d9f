"""A live plan's leads are paced by the process that solves it: ``lutgen plan``'s own, a query's or a re-plan's solver
process (``plan_deadline``); an offline plan and a table point have no observation and no pace."""

from __future__ import annotations

import os
import time

from lut.solve.point_worker import plan_deadline
from planner.plan import NoPlan, Planner
from tests.support.cli import ROOT, lutgen_in_process

SCENARIO_I = ROOT / "configs" / "scenarios" / "scenario_I.toml"


def test_a_solver_process_paces_a_live_solve_from_its_start_and_not_a_table_point():
    now = time.monotonic()
    live = plan_deadline(now + 50.0, now - 3.0)
    assert live.pace is not None and live.pace.pid == os.getpid() and live.pace.since_wall_s >= now
    assert plan_deadline(now + 50.0).pace is None


def test_lutgen_plan_paces_a_live_plan_in_its_own_process_and_not_an_offline_one(monkeypatch):
    given = []

    def no_plan(self, state, warm_start=None, deadline=None, grasp_by=None):
        given.append(deadline)
        raise NoPlan("stand-in: nothing solved")

    monkeypatch.setattr(Planner, "plan", no_plan)
    for extra in ((), ("--offline",)):
        assert lutgen_in_process("plan", SCENARIO_I, *extra).returncode == 2
    live, offline = given
    assert live.observed_at_s is not None and live.pace is not None and live.pace.pid == os.getpid()
    assert offline.observed_at_s is None and offline.pace is None
