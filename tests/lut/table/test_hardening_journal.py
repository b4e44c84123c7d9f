"""Journals: created atomically under their lock, never left behind by a refused build, and the message
says whether another build is running or an earlier one was interrupted."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import threading
from pathlib import Path
from typing import NoReturn

import pytest

from lut.build.existing_work import journal_path
from lut.build.options import BuildOptions
from lut.build.sweep import run_build
from lut.table.journal import Journal, JournalStatus, journal_status
from tests.support.cli import CI_GRID, ROOT, assert_one_line_error, lutgen_in_process, write_fake_table

HEADER = {"model_hash": "abc", "grid_text": "x"}
RACE_TRIALS = 25
pytestmark = pytest.mark.skipif(os.name != "posix", reason="flock and fork are POSIX")


def _racer(path: str, barrier: multiprocessing.synchronize.Barrier, results: multiprocessing.queues.Queue,
           name: str) -> None:
    barrier.wait()
    try:
        journal = Journal(Path(path), HEADER)
        journal.append({"point": 0, "status": "feasible", "who": name})
    except Exception as exc:  # noqa: BLE001 - every outcome is reported to the test
        results.put((name, "refused" if "in use" in str(exc) else f"{type(exc).__name__}: {exc}"))
        return
    results.put((name, "opened"))
    with contextlib.suppress(threading.BrokenBarrierError):
        barrier.wait()  # hold the lock until the other racer has tried
    journal.close()


def test_two_builds_starting_together_get_one_journal(tmp_path):
    ctx = multiprocessing.get_context("fork")
    for trial in range(RACE_TRIALS):
        path = tmp_path / f"race{trial}.journal"
        barrier, results = ctx.Barrier(2, timeout=30), ctx.Queue()
        procs = [ctx.Process(target=_racer, args=(str(path), barrier, results, name)) for name in "ab"]
        for p in procs:
            p.start()
        outcome = dict(results.get(timeout=30) for _ in procs)
        if "opened" not in outcome.values() or "refused" in outcome.values():
            barrier.abort()  # a racer that did not open the journal never reaches the second wait
        for p in procs:
            p.join(timeout=30)
        assert sorted(outcome.values()) == ["opened", "refused"], (trial, outcome)
        winner = next(name for name, what in outcome.items() if what == "opened")
        with Journal(path, HEADER) as j:  # the winner's record is in the file at the path
            assert j.records()[0]["who"] == winner, trial


def test_journal_torn_while_created_is_started_again(tmp_path):
    path = tmp_path / "j"
    with Journal(path, HEADER):
        pass
    full = path.read_bytes()
    path.write_bytes(full[: len(full) // 2])  # a crash in the middle of writing the header
    with Journal(path, HEADER) as j:
        assert j.started and j.records() == {}
    assert path.read_bytes() == full


@pytest.mark.parametrize("args, words", [
    (("--backend", "dask"), ("--scheduler",)),
    (("--point-timeout", "nan"), ("--point-timeout",)),
    (("--point-timeout", "-3"), ("--point-timeout",)),
    (("-j", "0"), ("--jobs",)),
])
def test_option_errors_leave_no_journal_behind(tmp_path, args, words):
    out = tmp_path / "t.h5"
    proc = lutgen_in_process("build", CI_GRID, "--out", out, "--no-progress", *args)
    assert_one_line_error(proc, *words)
    assert sorted(os.listdir(tmp_path)) == []


def test_a_build_that_fails_before_its_first_record_leaves_no_journal(tmp_path, monkeypatch):
    import lut.build.sweep

    def no_workers(*args: object, **kwargs: object) -> NoReturn:
        raise OSError("no workers today")

    monkeypatch.setattr(lut.build.sweep, "_solve_layers", no_workers)
    with pytest.raises(OSError):
        run_build(CI_GRID, tmp_path / "t.h5", BuildOptions(progress=False))
    assert sorted(os.listdir(tmp_path)) == []


def test_a_running_build_and_an_interrupted_one_are_told_apart(tmp_path):
    out = tmp_path / "t.h5"
    jpath = journal_path(out)
    with Journal(jpath, HEADER):  # a build holding its journal
        assert journal_status(jpath) is JournalStatus.IN_USE
        line = assert_one_line_error(lutgen_in_process("build", CI_GRID, "--out", out, "--no-progress"))
        assert "running" in line and "interrupted" not in line
        line = assert_one_line_error(lutgen_in_process("build", CI_GRID, "--out", out, "--force"))
        assert "running" in line  # --force never takes a running build's journal
    assert journal_status(jpath) is JournalStatus.INTERRUPTED
    line = assert_one_line_error(lutgen_in_process("build", CI_GRID, "--out", out, "--no-progress"))
    assert "interrupted" in line and "--resume" in line and "--force" in line


def test_force_rebuilds_an_existing_table(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = tmp_path / "t.h5"
    write_fake_table(out)
    jpath = journal_path(out)
    with Journal(jpath, HEADER):  # an interrupted build's journal (of something else) is dropped too
        pass
    before = out.read_bytes()
    summary = run_build(CI_GRID, out, BuildOptions(force=True, solver="tests.support.fake_solver:solve",
                                                   progress=False))
    assert summary.solved_now == summary.n_points == 4
    assert out.read_bytes() != before and not jpath.exists()
