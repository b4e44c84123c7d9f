"""What ``plan``, ``query`` and ``replan`` print of a plan (``lut.cli.plan_output.plan_lines``): the plan's table, then
each note on its own line after its prefix (a query's and a re-plan's solve notes as ``note: the solve: …``, which
the coverage bench reads back), then verify's summary."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

import lut.cli.plan_output as plan_output
import lut.output.export as export
import planner.verify.verifier as verifier
from planner.box_edge import BOX_EDGE_NOTE


def test_notes_come_between_the_plan_table_and_the_summary_each_after_its_prefix(monkeypatch):
    monkeypatch.setattr(plan_output, "plan_table", lambda plan, report: ["table"])
    monkeypatch.setattr(verifier, "summary_lines", lambda report: ["summary"])
    monkeypatch.setattr(export, "verdict_notes", lambda plan, report: [])
    notes = ("the re-solve failed (Out_Of_Time)", "a grasp with the chaser waiting elsewhere")
    assert plan_output.plan_lines(None, None, notes, plan_output.SOLVE_NOTE_PREFIX) == [
        "table", "note: the solve: the re-solve failed (Out_Of_Time)",
        "note: the solve: a grasp with the chaser waiting elsewhere", "summary"]
    assert plan_output.plan_lines(None, None, ["made from another grasp"]) == [
        "table", "note: made from another grasp", "summary"]
    assert plan_output.plan_lines(None, None) == ["table", "summary"]  # no notes: no note line


def _plan_at(base_offset_m):
    """What the verdict's notes read of a plan: its scenario's box and its θ_b(0) [m]."""
    scenario = SimpleNamespace(base_offset_bounds_m=((-1.0, 1.0), (-1.0, 1.0)))
    return SimpleNamespace(scenario=scenario, approach=SimpleNamespace(base_offset_m=np.asarray(base_offset_m)))


def test_a_refused_plan_on_its_box_edge_says_so_after_the_solve_notes(monkeypatch):
    monkeypatch.setattr(plan_output, "plan_table", lambda plan, report: ["table"])
    monkeypatch.setattr(verifier, "summary_lines", lambda report: ["summary"])
    refused, feasible = SimpleNamespace(feasible=False), SimpleNamespace(feasible=True)
    lines = plan_output.plan_lines(_plan_at([0.2, 1.0]), refused, ["made from another grasp"],
                                   plan_output.SOLVE_NOTE_PREFIX)
    assert lines[:2] == ["table", "note: the solve: made from another grasp"]
    assert lines[2].startswith("note: " + BOX_EDGE_NOTE) and "z = +1.000 m" in lines[2]
    assert lines[3:] == ["summary"]
    # a feasible plan on the edge, and a refused one inside the box, add nothing
    assert plan_output.plan_lines(_plan_at([0.2, 1.0]), feasible) == ["table", "summary"]
    assert plan_output.plan_lines(_plan_at([0.2, 0.9]), refused) == ["table", "summary"]
