"""How much slower than an idle core this process computes: its wall time over its CPU time since a start.

A live plan's leads (:data:`planner.deadline.START_LEAD_S`, :data:`planner.deadline.ANSWER_LEAD_S`) are the time the
rest of a plan takes on an idle core. On a loaded machine the same work takes longer in wall time, by the factor this
process has been waiting for a core; measured on the plan's own process, it scales the leads (README, "On time").
Only a process that computes throughout is measured so: one waiting on another's work would read as slow (the CPU time
of its children, such as the C compiler of :mod:`planner.nlp.compiled`, counts as its own once they end).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

# below this much wall time since the start the share is not measured yet (the slowdown is 1) [s]
MIN_WALL_S = 1.0
# the slowdown is capped here: a lead of 4× START_LEAD_S is 20 s of a 100 s budget
MAX_SLOWDOWN = 4.0
# below this the slowdown reads 1: the leads were measured with each plan on a core of its own, and such a plan (1.002
# measured) keeps the bounds, and so the plans, it had before paces were measured
IDLE_SLOWDOWN = 1.25


@dataclass(frozen=True)
class Pace:
    """This process's pace since ``since_wall_s`` [s, ``time.monotonic()``], when its CPU time was ``since_cpu_s``
    [s, :func:`cpu_time_s`]; measured in process ``pid`` only (another process reads a slowdown of 1)."""

    since_wall_s: float
    since_cpu_s: float
    pid: int = field(default_factory=os.getpid)

    @classmethod
    def from_now(cls) -> Pace:
        """A pace measured from now, in this process."""
        return cls(time.monotonic(), cpu_time_s())

    def slowdown(self) -> float:
        """Wall time over CPU time since the start, in [1, :data:`MAX_SLOWDOWN`]: 1 on an idle core (or with more
        than one thread busy, or below :data:`IDLE_SLOWDOWN`), 1.5 for one of three busy processes on two cores; 1
        before :data:`MIN_WALL_S`."""
        if os.getpid() != self.pid:
            return 1.0
        wall_s = time.monotonic() - self.since_wall_s
        if wall_s < MIN_WALL_S:
            return 1.0
        slowdown = min(MAX_SLOWDOWN, wall_s / max(cpu_time_s() - self.since_cpu_s, wall_s / MAX_SLOWDOWN))
        return slowdown if slowdown >= IDLE_SLOWDOWN else 1.0


def cpu_time_s() -> float:
    """The CPU time [s] this process and its ended children have spent, user and system."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system
