"""A plan's wall-clock deadline: the instant its time budget ends, read by every stage that can stop early.

An operator has 100 s from observing the target to moving the arm, so a plan is bounded as a whole: the
grasp search starts no new grasp, and every NLP's iteration callback ends its solve, once the deadline has
passed; what was found by then is verified and reported. A live plan's deadline also knows when its observation
was made: an approach solved then may not start before the answer can come (:meth:`Deadline.earliest_start_s`).
Instants are ``time.monotonic()`` seconds.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class Deadline:
    """The instant ``at_s`` [s, ``time.monotonic()``] a time budget ends; ``inf`` never does. ``what`` names the
    budget in the notes of a plan it cut short. ``observed_at_s`` [s, ``time.monotonic()``]: when the plan's
    observation was made, for a live plan (None: a table point or an offline plan, whose times are hypothetical)."""

    at_s: float = math.inf
    what: str = "the plan's time budget"
    observed_at_s: float | None = None

    @classmethod
    def after(cls, budget_s: float | None, since_s: float | None = None) -> Deadline:
        """The deadline ``budget_s`` [s] after ``since_s`` (default: now); ``None`` is no deadline."""
        if budget_s is None:
            return cls()
        return cls((time.monotonic() if since_s is None else since_s) + budget_s)

    @property
    def bounded(self) -> bool:
        """True when there is a deadline at all."""
        return math.isfinite(self.at_s)

    def remaining_s(self) -> float:
        """Seconds left until the deadline (negative once passed, ``inf`` without one)."""
        return self.at_s - time.monotonic()

    @property
    def passed(self) -> bool:
        """True once the deadline is behind us."""
        return self.bounded and time.monotonic() >= self.at_s

    def earlier(self, seconds: float, what: str | None = None) -> Deadline:
        """The deadline ``seconds`` [s] sooner: room kept back for what must follow (verification, export), or a
        share of the budget named ``what`` (default: this one's name)."""
        return Deadline(self.at_s - seconds, self.what if what is None else what, self.observed_at_s)

    def observed(self, observed_at_s: float) -> Deadline:
        """This deadline, of a live plan whose observation was made at ``observed_at_s`` [s, ``time.monotonic()``]."""
        return Deadline(self.at_s, self.what, observed_at_s)

    def in_time_for(self, start_delay_s: float, lead_s: float | None = None) -> Deadline:
        """This deadline, or for a live plan the instant ``lead_s`` [s] (default :data:`ANSWER_LEAD_S`) before an
        approach starting at ``start_delay_s`` [s after the observation] if that comes first: solving on past it, the
        plan would answer after its own start (a table point's or an offline plan's deadline is unchanged)."""
        if self.observed_at_s is None:
            return self
        start_by_s = self.observed_at_s + start_delay_s - (ANSWER_LEAD_S if lead_s is None else lead_s)
        return self if start_by_s >= self.at_s else Deadline(start_by_s, self.what, self.observed_at_s)

    def earliest_start_s(self, lead_s: float | None = None) -> float:
        """The earliest start delay [s after the observation] an approach solved now may take: the time since the
        observation and ``lead_s`` [s] for the rest of the plan (default :data:`START_LEAD_S`), rounded up to a whole
        :data:`FLOOR_STEP_S` (``-inf`` without an observation)."""
        if self.observed_at_s is None:
            return -math.inf
        floor_s = time.monotonic() - self.observed_at_s + (START_LEAD_S if lead_s is None else lead_s)
        return math.ceil(floor_s / FLOOR_STEP_S) * FLOOR_STEP_S

    def start_bound_s(self, guess_s: float) -> float:
        """The lower bound [s after the observation] of the start delay of an approach NLP solved now from a start at
        ``guess_s`` [s]: ``guess_s`` less :data:`STEADY_REACH_S` where that is no earlier than :meth:`earliest_start_s`,
        else the earliest start itself (``-inf`` without an observation). A bound that never binds still steers IPOPT's
        barrier, so a floor read off the clock made the same state's solves differ with the time its earlier stages
        took; taken from the guess, it is the same however long they took."""
        earliest_s = self.earliest_start_s()
        if not math.isfinite(earliest_s):
            return earliest_s
        return max(guess_s - STEADY_REACH_S, earliest_s)


NO_DEADLINE = Deadline()
# kept back from a budget to verify the plan found and write it out [s]
VERIFY_RESERVE_S = 5.0
# a live plan's approach solved now starts at least this long after: the solve itself, the tracking, the braking,
# verify and the export (README, the planner's constants)
START_LEAD_S = 5.0
# a live plan's earliest start is rounded up to a multiple of this [s]: the same state planned again a fraction of a
# second sooner or later then meets the same bounds, and gets the same plan to the bit (not the next second's)
FLOOR_STEP_S = 1.0
# a live approach NLP may move its start this far [s] before its guess where the guess is that far after the earliest
# start (Deadline.start_bound_s): the 58 solves of 15 coverage states traced ended from 4.1 s later to 11.7 s earlier
STEADY_REACH_S = 20.0
# a live plan's last solve (a braking, a costed descent's step) ends at least this long before the approach's start it
# plans: the plan's assembly and verify come after it (verify took 0.2 s at either default state, machine loaded)
ANSWER_LEAD_S = 2.0
# the soonest a live answer may start a plan that is already made (a table's, as carried to the state) [s after the
# observation]: its time to answer (> 0) and ANSWER_LEAD_S, rounded up to a whole FLOOR_STEP_S
QUERY_EARLIEST_START_S = ANSWER_LEAD_S + FLOOR_STEP_S
