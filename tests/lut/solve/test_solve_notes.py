"""A solve's notes (its grasps, re-solves, budget) reach the query that asked for it through the child process's
record, and the operator reads them; a journal or table record never holds them (its schema is unchanged)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from lut.query.result import QuerySource
from lut.query.table_query import TableQuery
from lut.solve.point_worker import load_npz, save_npz
from lut.table.point_result import PointResult, PointStatus
from lut.table.records import NOTES_KEY, from_record, to_record, with_notes
from planner.model.target import TargetState

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
NOTES = ("tracking joint rate 2.02× the limit: approach re-solved", "a note\nwith a line break")


def test_notes_cross_the_child_processs_record_and_no_journal_record_holds_them(tmp_path):
    result = PointResult(-1, PointStatus.INFEASIBLE, "grasp_torque", 12.5, 40, notes=NOTES)
    assert NOTES_KEY not in to_record(result)  # what a build journals and a table stores
    save_npz(tmp_path / "out.npz", with_notes(to_record(result), result))
    back = from_record(load_npz(tmp_path / "out.npz"))
    assert back.notes == (NOTES[0], "a note with a line break")  # one note a line
    assert replace(back, notes=()) == replace(result, notes=())
    assert from_record(to_record(result)).notes == ()  # a journal's record: none
    assert with_notes(to_record(replace(result, notes=())), replace(result, notes=())) == to_record(result)


def test_a_query_answered_by_its_cold_solve_carries_the_solves_notes():
    """The re-simulated plan of a solve has no notes of its own: the solve's reach the answer (printed as
    ``note: the solve: …``) and the plan file (the plan's notes)."""
    tq = TableQuery(GOLDEN)
    stored = tq.points[1].parameters
    solved = PointResult(-1, PointStatus.INFEASIBLE, "stand-in", 1.0, 1, parameters=stored, notes=NOTES[:1])
    failing = SimpleNamespace(feasible=False, checks={}, violations=["stand-in"], t_grasp_s=50.0)

    def simulate_and_verify(state, parameters, latency):
        return SimpleNamespace(notes=["simulated from given parameters"]), failing

    tq.interpolate = lambda state: None  # no table plan near: the cold solve answers
    tq.simulate_and_verify = simulate_and_verify
    tq.out_of_reach = lambda state, t_start: None
    tq.refine = lambda state, warm, budget_s: solved
    state = TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.radians([0.0, 0.0, 3.8]))
    res = tq.query(state, budget_s=100.0)
    assert res.source is QuerySource.SOLVED_COLD and res.solve_notes == NOTES[:1]
    assert res.plan.notes == ["simulated from given parameters", NOTES[0]]
