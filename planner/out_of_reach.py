"""A state no plan can meet: the grasp beyond the arm's reach at every meeting time of the window, or within it only
at start delays before a live plan's approach could start.

Either is the state's answer, not a failed solve: no trajectory was made, so there is nothing to verify or export.
"""

from __future__ import annotations

from planner.phases.reach_scan_result import ReachScan


class OutOfReach(Exception):
    """A cold plan found no meeting time in the start-delay window where the arm reaches the grasp: the state
    is infeasible, and there is no trajectory to verify. ``str()`` says why; ``scan`` is what the scan found at
    each meeting time, ``elapsed_s`` how long it took [s]."""

    def __init__(self, scan: ReachScan, elapsed_s: float, reason: str | None = None) -> None:
        self.scan = scan
        self.elapsed_s = elapsed_s
        super().__init__(scan.reason() if reason is None else reason)


REACHABLE_ONLY_TOO_EARLY = "reachable only too early"


class ReachableOnlyTooEarly(OutOfReach):
    """A live cold plan whose every reachable meeting time, from every base offset it tried, starts the approach
    before its answer can come: no approach was started, so no plan exists in time (the target must be observed
    again). ``scan`` is the scan of the whole window; ``earliest_start_s`` the earliest start still in time [s after
    the observation]."""

    def __init__(self, scan: ReachScan, earliest_start_s: float, base_offsets: int, elapsed_s: float) -> None:
        self.earliest_start_s = earliest_start_s
        reached = " and ".join(f"{a:g}–{b:g} s" if b > a else f"{a:g} s" for a, b in scan.reached_start_delays_s())
        super().__init__(scan, elapsed_s,
                         f"{REACHABLE_ONLY_TOO_EARLY}: the scan of the start-delay window [{scan.window_s[0]:g}, "
                         f"{scan.window_s[1]:g}] s reaches the grasp only at start delays {reached} after the "
                         f"observation, before this plan's approach could start ({earliest_start_s:g} s: the time to "
                         f"answer and the plan's lead), and from none of the {base_offsets} places the chaser may "
                         "wait that were tried does it come later; a table's plan that, carried to this state, "
                         "starts after the answer, or a newer observation, may meet it")
