"""A process's pace: wall time over CPU time since a start, the factor by which a loaded machine stretches a live
plan's leads; 1 idle, capped, and not read from another process."""

from __future__ import annotations

import os
import time

import pytest

import planner.pace as pace_module
from planner.pace import IDLE_SLOWDOWN, MAX_SLOWDOWN, MIN_WALL_S, Pace, cpu_time_s


@pytest.mark.parametrize(("wall_s", "cpu_s", "slowdown"), [
    (MIN_WALL_S / 2, 0.0, 1.0),  # too soon to tell: the idle core's leads
    (MIN_WALL_S, 0.0, MAX_SLOWDOWN),  # measured from MIN_WALL_S on
    (10.0, 10.0, 1.0),  # computing all the time: idle
    (10.0, 10.0 / 1.2, 1.0),  # within the idle band
    (10.0, 10.0 / IDLE_SLOWDOWN, IDLE_SLOWDOWN),  # at its edge
    (10.0, 20.0 / 3.0, 1.5),  # one of three busy processes on two cores
    (10.0, 20.0, 1.0),  # two threads busy: never faster than idle
    (10.0, 10.0 / MAX_SLOWDOWN, MAX_SLOWDOWN),  # exactly at the cap
    (10.0, 0.0, MAX_SLOWDOWN),  # no CPU at all: capped, not infinite
])
def test_the_slowdown_is_wall_time_over_cpu_time_within_its_bounds(monkeypatch, wall_s, cpu_s, slowdown):
    pace = Pace(since_wall_s=100.0, since_cpu_s=3.0)
    monkeypatch.setattr(pace_module.time, "monotonic", lambda: 100.0 + wall_s)
    monkeypatch.setattr(pace_module, "cpu_time_s", lambda: 3.0 + cpu_s)
    assert pace.slowdown() == pytest.approx(slowdown, rel=1e-12)


def test_a_process_that_waited_reads_slow_on_the_real_clocks():
    """Sleeping spends wall time and no CPU time, whatever the machine's load: the cap."""
    pace = Pace.from_now()
    time.sleep(MIN_WALL_S + 0.1)
    assert pace.slowdown() == MAX_SLOWDOWN


def test_a_childs_cpu_time_counts_as_the_processs_own_once_it_ended():
    """A plan waiting for its C compiler is not waiting for a core: the child's CPU time is the parent's work."""
    import subprocess
    import sys

    before = cpu_time_s()
    busy = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.5: pass"
    subprocess.run([sys.executable, "-c", busy], check=True)
    assert cpu_time_s() - before >= 0.5


def test_a_pace_read_in_another_process_is_the_idle_one(monkeypatch):
    """A pace made in one process and read in another (pickled into a worker) knows nothing of that one's CPU."""
    other = Pace(since_wall_s=time.monotonic() - 10.0, since_cpu_s=cpu_time_s(), pid=os.getpid() + 1)
    assert other.slowdown() == 1.0
