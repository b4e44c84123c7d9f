"""When an answer comes against when its plan starts: a plan whose approach starts before its answer is late.

A plan's times count from the observation, which lutgen takes to be the command's start (an observation made
earlier only makes the answer later still). The approach starts at its start delay with the chaser already at
θ_b(0) in θ_in; an answer given after that instant asks for a motion that should already have begun, so however
sound its physics, it cannot be flown as planned.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class AnswerTime:
    """``start_delay_s``: when the plan's approach starts, after the observation [s]; ``answered_s``: when the
    verdict on it was reached, after the observation (the command's start) [s]."""

    start_delay_s: float
    answered_s: float

    @property
    def late(self) -> bool:
        """True when the approach was to start before the answer came."""
        return self.start_delay_s < self.answered_s

    def line(self) -> str:
        """One line for the summary: both instants and how much time the answer leaves before the approach."""
        lead = self.start_delay_s - self.answered_s
        margin = f"{lead:.1f} s ahead" if lead >= 0 else f"{-lead:.1f} s late"
        return (f"answered {self.answered_s:.1f} s after the observation (the command's start); the approach starts "
                f"{self.start_delay_s:.2f} s after it: {margin}")

    def reason(self) -> str:
        """Why a late plan is refused, with what to do (one sentence)."""
        return (f"late: the approach was to start {self.start_delay_s:.2f} s after the observation and this answer "
                f"came {self.answered_s:.1f} s after it; plan again from a newer observation, or with a later start "
                f"(--earliest-start-s)")

    def as_dict(self) -> dict[str, Any]:
        """The plan file's ``answer`` object."""
        return {"answered_s": self.answered_s, "start_delay_s": self.start_delay_s, "late": self.late}
