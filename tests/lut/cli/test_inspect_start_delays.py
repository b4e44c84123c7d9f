"""``lutgen inspect`` reports when a table's plans start and, for a tumble table, how many start before any query could
answer: a tumble plan keeps its start, so one starting within QUERY_EARLIEST_START_S of the observation is never flown.
A flat-spin table's plan is carried to the state's phase (later for a state whose phase lags its point's): an early
start at its point is no defect there (seed 12's scenario I flat spin 6 was answered from corners starting at 0.01-1.76
s, carried to 3.98 s)."""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from lut.table.point_result import PointStatus
from planner.deadline import ANSWER_LEAD_S, FLOOR_STEP_S, QUERY_EARLIEST_START_S
from tests.support.cli import ROOT, lutgen_in_process

GOLDEN = ROOT / "tests" / "data" / "ci_golden.h5"


def _with_start_delays(tmp_path, delays_s, infeasible=(), kind="tumble"):
    """The golden table (4 feasible points) with these start delays, the points ``infeasible`` marked so, labelled a
    table of grid ``kind`` (inspect reads the label, not the axes)."""
    path = tmp_path / "t.h5"
    shutil.copy(GOLDEN, path)
    with h5py.File(path, "r+") as f:
        f.attrs["grid_kind"] = kind
        f["points/start_delay_s"][...] = np.asarray(delays_s, dtype=float)
        status = f["points/status"][...]
        for p in infeasible:
            status[p] = PointStatus.INFEASIBLE.code
        f["points/status"][...] = status
    return path


@pytest.mark.parametrize(("elapsed_s", "earliest_s"), [(1e-6, 3.0), (0.6, 3.0), (1.0, 3.0), (1.001, 4.0)])
def test_the_soonest_a_query_starts_a_table_plan_is_its_own_placement_rule(monkeypatch, elapsed_s, earliest_s):
    """The query places a table plan no sooner than ``earliest_start_s(ANSWER_LEAD_S)`` (``TableQuery.placed``): for any
    time to answer above 0 and up to one floor step that is QUERY_EARLIEST_START_S, and never less."""
    import planner.deadline as deadline

    monkeypatch.setattr(deadline, "time", SimpleNamespace(monotonic=lambda: 100.0 + elapsed_s))
    placed_from = deadline.Deadline(observed_at_s=100.0).earliest_start_s(ANSWER_LEAD_S)
    assert placed_from == earliest_s >= QUERY_EARLIEST_START_S
    assert (placed_from == QUERY_EARLIEST_START_S) == (elapsed_s <= FLOOR_STEP_S)  # the soonest, never sooner


@pytest.mark.parametrize(("delays_s", "infeasible", "too_soon"), [
    ([18.6, 27.5, 30.0, 37.3], (), 0),               # the golden table as built
    ([0.0, 2.999, 3.0, 40.0], (), 2),                # the edge: 3.0 s can be started, 2.999 s cannot
    ([0.0, 2.999, 3.0, 40.0], (0,), 1),              # an infeasible point's parameters are no plan
])
def test_inspect_counts_the_feasible_plans_starting_too_soon(tmp_path, delays_s, infeasible, too_soon):
    path = _with_start_delays(tmp_path, delays_s, infeasible)
    info = json.loads(lutgen_in_process("inspect", path, "--json").stdout)
    assert info["starting_too_soon"] == {"within_s": QUERY_EARLIEST_START_S, "plans": too_soon}
    feasible = [d for p, d in enumerate(delays_s) if p not in infeasible]
    assert info["start_delay_s"]["min"] == pytest.approx(min(feasible))
    assert info["start_delay_s"]["max"] == pytest.approx(max(feasible))
    text = lutgen_in_process("inspect", path).stdout
    assert "start delay [s]" in text
    lines = [line for line in text.splitlines() if line.startswith("too soon")]
    if too_soon:
        assert lines == [f"too soon   {too_soon} of {len(feasible)} feasible plans start within 3 s of the "
                         "observation: no query answers that soon, and a tumble table's plans keep "
                         "their start"]
    else:
        assert lines == []


def test_a_flat_spin_tables_early_plans_are_not_called_too_soon(tmp_path):
    path = _with_start_delays(tmp_path, [0.0, 2.999, 3.0, 40.0], kind="flat_spin")
    info = json.loads(lutgen_in_process("inspect", path, "--json").stdout)
    assert info["starting_too_soon"] is None and info["start_delay_s"]["min"] == 0.0
    assert "too soon" not in lutgen_in_process("inspect", path).stdout
