"""What ``plan``, ``query`` and ``replan`` print of a plan (``lut.cli.plan_output.plan_lines``): the plan's table, then
each note on its own line after its prefix (a query's and a re-plan's solve notes as ``note: the solve: …``, which
the coverage bench reads back), then verify's summary."""

from __future__ import annotations

import lut.cli.plan_output as plan_output
import planner.verify.verifier as verifier


def test_notes_come_between_the_plan_table_and_the_summary_each_after_its_prefix(monkeypatch):
    monkeypatch.setattr(plan_output, "plan_table", lambda plan, report: ["table"])
    monkeypatch.setattr(verifier, "summary_lines", lambda report: ["summary"])
    notes = ("the re-solve failed (Out_Of_Time)", "a grasp with the chaser waiting elsewhere")
    assert plan_output.plan_lines(None, None, notes, plan_output.SOLVE_NOTE_PREFIX) == [
        "table", "note: the solve: the re-solve failed (Out_Of_Time)",
        "note: the solve: a grasp with the chaser waiting elsewhere", "summary"]
    assert plan_output.plan_lines(None, None, ["made from another grasp"]) == [
        "table", "note: made from another grasp", "summary"]
    assert plan_output.plan_lines(None, None) == ["table", "summary"]  # no notes: no note line
