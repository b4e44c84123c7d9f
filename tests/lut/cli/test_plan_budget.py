"""``lutgen plan --budget-s``: a budget that runs out before anything is solved ends at once with exit 2 and the
reason (a budget that runs out later gives the plan found by then, verified: ``tests/planner/test_plan_retry.py``)."""

from __future__ import annotations

from tests.support.cli import ROOT, lutgen

SCENARIO_I = ROOT / "configs" / "scenarios" / "scenario_I.toml"


def test_a_budget_spent_on_building_the_problems_is_refused_at_once(tmp_path):
    out = tmp_path / "plan.json"
    # a budget far below the problems' build: nothing is solved, nothing written, exit 2 with the reason
    proc = lutgen("plan", SCENARIO_I, "--budget-s", "0.01", "--out", out)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines[-2].startswith("INFEASIBLE (") and "time budget of 0.01 s ran out while the problems were built" \
        in lines[-2]
    assert lines[-1] == "no plan written: there is no trajectory to export"
    assert not out.exists()
