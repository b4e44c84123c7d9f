"""``lutgen plan --budget-s``: a plan whose budget runs out ends with the plan found by then, verified, exit 2."""

from __future__ import annotations

import json

from tests.support.cli import ROOT, lutgen

SCENARIO_I = ROOT / "configs" / "scenarios" / "scenario_I.toml"


def test_a_plan_out_of_time_is_verified_written_and_refused(tmp_path):
    out = tmp_path / "plan.json"
    # a budget far below the problems' build: the deadline has passed before the first NLP iteration
    proc = lutgen("plan", SCENARIO_I, "--budget-s", "0.01", "--out", out)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    assert "note: the plan's time budget ran out" in proc.stdout
    assert proc.stderr.strip().splitlines()[-1].startswith("INFEASIBLE: ")
    doc = json.loads(out.read_text())
    # the approach and the stabilization both say why they are unsolved; the dense trajectory is there to look at
    assert doc["status"] == "infeasible"
    assert "Out_Of_Time" in json.dumps(doc["metrics"])
    assert len(doc["samples"]["t"]) > 1000
