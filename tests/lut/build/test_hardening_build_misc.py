"""A killed build leaves no process and no scratch folder behind; a query's refine timeout names the option that set
it."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from tests.support.cli import ROOT

pytestmark = pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads the process tree from /proc")
GONE_WITHIN_S = 10.0


def _children() -> dict[int, list[int]]:
    """parent pid → child pids, of every live (not zombie) process."""
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        state, ppid = stat.rsplit(")", 1)[1].split()[:2]
        if state != "Z":
            tree.setdefault(int(ppid), []).append(int(entry))
    return tree


def _descendants(pid: int) -> set[int]:
    tree, out, todo = _children(), set(), [pid]
    while todo:
        for child in tree.get(todo.pop(), []):
            out.add(child)
            todo.append(child)
    return out


def _alive(pids: set[int]) -> set[int]:
    tree = _children()
    live = {p for children in tree.values() for p in children}
    return pids & live


def test_a_killed_build_leaves_no_worker_or_solver_running(tmp_path):
    scratch = tmp_path / "tmp"  # the build's temporary folder: its workers' point folders go there
    scratch.mkdir()
    script = textwrap.dedent(f"""
        from lut.build.options import BuildOptions
        from lut.build.sweep import run_build
        run_build({str(ROOT / "configs/grids/ci.toml")!r}, {str(tmp_path / "t.h5")!r},
                  BuildOptions(jobs=2, solver="tests.support.fake_solver:solve", progress=False))
    """)
    env = {**os.environ, "LUTGEN_FAKE_SLEEP_S": "120", "PYTHONPATH": str(ROOT), "TMPDIR": str(scratch)}
    build = subprocess.Popen([sys.executable, "-c", script], env=env, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 120
        helpers: set[int] = set()
        while time.monotonic() < deadline:  # the loky workers and, under them, the point processes
            helpers = _descendants(build.pid)
            if sum("lut.solve.point_worker" in Path(f"/proc/{p}/cmdline").read_text(errors="replace")
                   for p in helpers if Path(f"/proc/{p}").exists()) >= 1:
                break
            time.sleep(0.2)
        else:
            pytest.fail("no point process started")
        assert any(p.name.startswith("lutgen-point-") for p in scratch.iterdir())  # the check below can fail
        helpers = _descendants(build.pid)
        build.send_signal(signal.SIGKILL)
        build.wait()
        t0 = time.monotonic()
        while _alive(helpers) and time.monotonic() - t0 < GONE_WITHIN_S:
            time.sleep(0.2)
        assert not _alive(helpers), f"still running {time.monotonic() - t0:.0f} s after the kill: {_alive(helpers)}"
        left = [p.name for p in scratch.iterdir() if p.name.startswith("lutgen-point-")]
        assert not left, f"scratch folders left by the killed build's workers: {left}"
    finally:
        for pid in _alive(_descendants(build.pid)) if build.poll() is None else set():
            os.kill(pid, signal.SIGKILL)
        build.kill()


def test_a_refine_timeout_names_the_query_budget(tmp_path, monkeypatch):
    import lut.query.table_query
    from lut.query.table_query import TableQuery
    from tests.support.cli import write_fake_table

    table = tmp_path / "t.h5"
    write_fake_table(table)
    monkeypatch.setenv("PYTHONPATH", str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    monkeypatch.setenv("LUTGEN_FAKE_HANG", "-1")  # the refine solves "point" -1
    monkeypatch.setattr(lut.query.table_query, "DEFAULT_SOLVER", "tests.support.fake_solver:solve")
    tq = TableQuery(table)
    result = tq.refine(tq.grid.state(0), None, budget_s=1.0)
    assert result.status == "failed"
    assert "--budget-s" in result.failure_reason and "--point-timeout" not in result.failure_reason
