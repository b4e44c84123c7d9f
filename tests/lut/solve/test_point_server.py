"""A kept solver process answers a build's successive points exactly as a new process per point would; a point over
its limit, or crashing, fails alone and the next point gets a new process."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from lut.solve import point_server
from lut.solve.point_process import run_point
from planner.model.target_state import TargetState
from tests.support.cli import ROOT

FAKE = "tests.support.fake_solver:solve"
SCENARIO = str(ROOT / "configs" / "scenarios" / "scenario_II.toml")


def _state(i: int) -> TargetState:
    return TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.radians([0.0, 0.0, 1.0 + 0.5 * i]))


@pytest.fixture(autouse=True)
def _fresh(monkeypatch):
    # the kept processes read the fault-injection variables at their start: each test starts its own
    monkeypatch.setenv("PYTHONPATH", str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for var in ("LUTGEN_FAKE_RAISE", "LUTGEN_FAKE_HANG", "LUTGEN_FAKE_CRASH", "LUTGEN_FAKE_SLEEP_S"):
        monkeypatch.delenv(var, raising=False)
    point_server.stop_all()
    yield
    point_server.stop_all()


def _solve(point: int, keep: bool, timeout_s: float = 60.0):
    return run_point(FAKE, SCENARIO, point, _state(point), None, 0.0, timeout_s, keep_process=keep)


def _pid() -> int:
    return point_server._SERVERS[FAKE].process.pid


def test_successive_points_in_one_kept_process_give_the_one_shot_records():
    kept = [_solve(p, keep=True) for p in range(4)]
    assert len(point_server._SERVERS) == 1
    one_shot = [_solve(p, keep=False) for p in range(4)]
    for a, b in zip(kept, one_shot, strict=True):
        assert a.status == b.status and a.point == b.point
        np.testing.assert_array_equal(a.parameters.approach.params, b.parameters.approach.params)
        np.testing.assert_array_equal(a.parameters.stabilization_params, b.parameters.stabilization_params)


def test_a_raising_point_fails_alone_and_the_process_is_kept(monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_RAISE", "1")
    assert _solve(0, keep=True).status == "feasible"
    pid = _pid()
    failed = _solve(1, keep=True)
    assert failed.status == "failed" and "injected failure at point 1" in failed.failure_reason
    assert _solve(2, keep=True).status == "feasible" and _pid() == pid


def test_a_point_over_its_limit_is_killed_and_the_next_gets_a_new_process(monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_HANG", "1")
    assert _solve(0, keep=True).status == "feasible"
    pid = _pid()
    t0 = time.monotonic()
    failed = _solve(1, keep=True, timeout_s=3.0)
    assert failed.status == "failed" and failed.failure_reason == "timeout: exceeded --point-timeout 3 s"
    assert time.monotonic() - t0 < 10.0
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # killed and reaped
    assert _solve(2, keep=True).status == "feasible" and _pid() != pid


def test_a_crashing_point_fails_alone_and_the_next_gets_a_new_process(monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_CRASH", "1")
    assert _solve(0, keep=True).status == "feasible"
    pid = _pid()
    failed = _solve(1, keep=True)
    assert failed.status == "failed" and failed.failure_reason.startswith("worker crashed (signal 9)")
    assert _solve(2, keep=True).status == "feasible" and _pid() != pid


def test_stopping_ends_the_kept_process():
    _solve(0, keep=True)
    process = point_server._SERVERS[FAKE].process
    point_server.stop_all()
    assert process.poll() is not None and not point_server._SERVERS


def test_a_process_that_died_idle_is_replaced_without_failing_the_next_point():
    assert _solve(0, keep=True).status == "feasible"
    process = point_server._SERVERS[FAKE].process
    process.kill()  # e.g. the kernel's OOM killer, between two points
    process.wait()
    assert _solve(1, keep=True).status == "feasible" and _pid() != process.pid


def test_a_crash_reports_its_own_last_words_not_an_earlier_point_s(monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_CRASH", "1")
    assert _solve(0, keep=True).status == "feasible"
    point_server._SERVERS[FAKE].stderr.write(b"an earlier point's warning\n")  # as if point 0 had written it
    failed = _solve(1, keep=True)
    assert failed.failure_reason == "worker crashed (signal 9): no output"
