"""What a phase NLP's solve ended with: IPOPT's own return status, or one of the planner's.

A :class:`SolveOutcome` member equals its text (``StrEnum``), so plans, tables and notes keep IPOPT's words
(``Solve_Succeeded``, ``Maximum_Iterations_Exceeded``…) and the planner's (``Feasible_Point_Found`` when the
feasibility stop ended a pure feasibility solve, ``Iteration_Budget_Exhausted``, ``given``…).
"""

from __future__ import annotations

from enum import StrEnum


class SolveOutcome(StrEnum):
    """The end of one solve; the value is the text stored in plans and printed."""

    # IPOPT's return statuses (as CasADi reports them in ``stats()["return_status"]``)
    SOLVED = "Solve_Succeeded"
    SOLVED_TO_ACCEPTABLE_LEVEL = "Solved_To_Acceptable_Level"
    INFEASIBLE = "Infeasible_Problem_Detected"
    SEARCH_DIRECTION_TOO_SMALL = "Search_Direction_Becomes_Too_Small"
    DIVERGING_ITERATES = "Diverging_Iterates"
    USER_REQUESTED_STOP = "User_Requested_Stop"
    FEASIBLE_POINT_FOUND = "Feasible_Point_Found"  # also ours: the feasibility stop ended the solve there
    ITERATION_LIMIT = "Maximum_Iterations_Exceeded"
    RESTORATION_FAILED = "Restoration_Failed"
    ERROR_IN_STEP_COMPUTATION = "Error_In_Step_Computation"
    CPU_TIME_LIMIT = "Maximum_CpuTime_Exceeded"
    WALL_TIME_LIMIT = "Maximum_WallTime_Exceeded"
    NOT_ENOUGH_DEGREES_OF_FREEDOM = "Not_Enough_Degrees_Of_Freedom"
    INVALID_PROBLEM_DEFINITION = "Invalid_Problem_Definition"
    INVALID_OPTION = "Invalid_Option"
    INVALID_NUMBER = "Invalid_Number_Detected"
    UNRECOVERABLE_EXCEPTION = "Unrecoverable_Exception"
    NON_IPOPT_EXCEPTION = "NonIpopt_Exception_Thrown"
    INSUFFICIENT_MEMORY = "Insufficient_Memory"
    INTERNAL_ERROR = "Internal_Error"
    UNKNOWN = "Unknown"
    # the planner's own
    ITERATION_BUDGET_EXHAUSTED = "Iteration_Budget_Exhausted"  # the caller's budget over all starts was spent
    SCREENED_OUT = "Screened_Out"  # a grasp's coarse stabilization was not feasible within the screen's budget
    OUT_OF_TIME = "Out_Of_Time"  # the plan's time budget (its deadline) ran out during this solve
    GIVEN = "given"  # parameters used as given (a table query), no solve
    NO_GUESS_LEFT = "no scanned initial guess left to start from"
    NO_PINNED_START = "no reachable meeting time with the base pinned"
    # a live plan's scanned meeting times all come before its answer can (the time since the observation and the lead)
    NO_GUESS_IN_TIME = "no meeting time the scan reached comes after the answer can"
    TORQUE_BETWEEN_VIA_POINTS = "Torque_Over_Limit_Between_Via_Points"  # feasible at the via points only
    CLEARANCE_BETWEEN_VIA_POINTS = "Clearance_Under_Margin_Between_Via_Points"  # the same, for a collision pair
    REFUSED_BEFORE_GRASP = "Refused_Before_The_Grasp"  # not braked: verify refuses the plan before its grasp
    STALLED = "Stalled"  # its violation stopped falling (a stall rule armed: a repair or an approach start given up)

    @classmethod
    def from_ipopt(cls, return_status: str) -> SolveOutcome:
        """The member of IPOPT's ``return_status`` text (:attr:`UNKNOWN` for a text CasADi never gave)."""
        try:
            return cls(return_status)
        except ValueError:
            return cls.UNKNOWN
