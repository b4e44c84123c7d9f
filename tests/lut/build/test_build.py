"""Build mechanics with a fast stand-in solver: parallel, fault isolation, kill -9 + resume, Dask."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from lut.build.existing_work import journal_path
from lut.build.options import BuildOptions
from lut.build.sweep import run_build
from lut.table.store import Table
from tests.support.fake_build import FAKE_SOLVER, assert_same, fake_solver_env, fresh_workers, snapshot

ROOT = Path(__file__).resolve().parents[3]

GRID = """
name = "test"
scenario = "{scenario}"
kind = "flat_spin"

[[axes]]
name = "spin_rate_deg_s"
min = 3.0
max = 4.0
count = 3

[[axes]]
name = "spin_phase_deg"
min = 0.0
max = 30.0
count = 3
"""


@pytest.fixture()
def grid_file(tmp_path: Path) -> Path:
    path = tmp_path / "grid.toml"
    path.write_text(GRID.format(scenario=(ROOT / "configs/scenarios/scenario_II.toml").as_posix()))
    return path


@pytest.fixture(autouse=True)
def _fake_solver(monkeypatch):
    fake_solver_env(monkeypatch)


def test_parallel_build_writes_every_point(grid_file, tmp_path):
    out = tmp_path / "t.h5"
    summary = run_build(grid_file, out, BuildOptions(jobs=2, solver=FAKE_SOLVER, progress=False))
    assert summary.counts["feasible"] == 9 and summary.counts["pending"] == 0
    t = Table.open(out)
    assert t.counts()["feasible"] == 9
    assert not journal_path(out).exists()  # a complete table makes the journal redundant: removed
    # same config ⇒ same table
    out2 = tmp_path / "t2.h5"
    run_build(grid_file, out2, BuildOptions(jobs=1, solver=FAKE_SOLVER, progress=False))
    assert_same(snapshot(out), snapshot(out2))


def test_raising_and_hanging_points_are_recorded_failed(grid_file, tmp_path, monkeypatch):
    monkeypatch.setenv("LUTGEN_FAKE_RAISE", "2")
    monkeypatch.setenv("LUTGEN_FAKE_HANG", "5")
    monkeypatch.setenv("LUTGEN_FAKE_CRASH", "7")
    fresh_workers()
    out = tmp_path / "t.h5"
    summary = run_build(grid_file, out, BuildOptions(jobs=2, solver=FAKE_SOLVER, point_timeout_s=8.0, progress=False))
    t = Table.open(out)
    reasons = {p: t.record(p)["failure_reason"] for p in range(t.n_points)}
    assert t.counts()["failed"] == 3 and t.counts()["feasible"] == 6, reasons
    assert "injected failure at point 2" in reasons[2]
    assert "timeout" in reasons[5]
    assert "crashed" in reasons[7]
    assert len(summary.failures) == 3


BUILD_SCRIPT = """
import sys
from lut.build.options import BuildOptions
from lut.build.sweep import run_build
run_build(sys.argv[1], sys.argv[2], BuildOptions(jobs=2, solver="{fake}", resume=True, progress=False))
"""


def _journaled_points(path: Path) -> int:
    """Intact point records in a journal (its first frame is the header)."""
    from lut.table.journal_format import MAGIC, read_frames

    if not path.exists():
        return 0
    data = path.read_bytes()
    if not data.startswith(MAGIC):
        return 0
    return max(0, len(read_frames(data, len(MAGIC))[0]) - 1)


def test_kill_9_at_random_moments_then_resume_equals_uninterrupted(grid_file, tmp_path):
    reference = tmp_path / "ref.h5"
    run_build(grid_file, reference, BuildOptions(jobs=2, solver=FAKE_SOLVER, progress=False))
    out = tmp_path / "killed.h5"
    # 1 s per point: 9 points on 2 processes take ≥ 5 s, so three kills land before the end
    # a SIGKILLed build cannot remove its points' scratch directories; keep them in this test's tmp_path
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    env = dict(os.environ, LUTGEN_FAKE_SLEEP_S="1.0", TMPDIR=str(scratch))
    rng = np.random.default_rng(7)
    script = BUILD_SCRIPT.format(fake=FAKE_SOLVER)
    kills = 0
    for _ in range(3):
        # Kill at a random moment after this run has journaled something new, so that every kill
        # interrupts real progress however slow the machine is (a wall-clock kill time is not).
        before = _journaled_points(journal_path(out))
        proc = subprocess.Popen([sys.executable, "-c", script, str(grid_file), str(out)], env=env,
                                start_new_session=True)
        deadline = time.monotonic() + 120.0
        while proc.poll() is None and _journaled_points(journal_path(out)) <= before \
                and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(float(rng.uniform(0.0, 0.6)))
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # the build and its point processes, no cleanup
            kills += 1
        proc.wait()
    assert kills == 3
    assert journal_path(out).exists()
    assert 3 <= _journaled_points(journal_path(out)) < 9
    run_build(grid_file, out, BuildOptions(jobs=2, solver=FAKE_SOLVER, resume=True, progress=False))
    assert_same(snapshot(reference), snapshot(out))


def test_an_existing_journal_needs_resume(grid_file, tmp_path):
    from planner.errors import LutgenError

    out = tmp_path / "t.h5"
    journal_path(out).write_bytes(b"")
    with pytest.raises(LutgenError, match="--resume"):
        run_build(grid_file, out, BuildOptions(jobs=1, solver=FAKE_SOLVER, progress=False))


def test_dask_local_cluster_gives_the_same_table_as_loky(grid_file, tmp_path):
    distributed = pytest.importorskip("distributed", reason="the 'dask' extra is not installed")
    loky = tmp_path / "loky.h5"
    run_build(grid_file, loky, BuildOptions(jobs=2, solver=FAKE_SOLVER, progress=False))
    import dask

    # the scheduler and workers keep their scratch space in this test's tmp_path, not the machine's /tmp
    with dask.config.set({"temporary-directory": str(tmp_path / "dask")}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                     dashboard_address=None) as cluster:
        dask_out = tmp_path / "dask.h5"
        run_build(grid_file, dask_out, BuildOptions(backend="dask", scheduler=cluster.scheduler_address,
                                                     solver=FAKE_SOLVER, progress=False))
    assert_same(snapshot(loky), snapshot(dask_out))
