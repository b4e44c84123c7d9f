"""Run one point's solve in a child process with a hard time limit; a timeout or a crash becomes a failed result."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from lut.solve.parent_watch import scratch_dir
from lut.solve.point_server import ServedAnswer, crash_reason, solve_served
from lut.solve.point_worker import KWARG_PREFIX, WARM_PREFIX, load_npz, save_npz
from lut.table.point_result import PointResult
from lut.table.records import failed_result, from_record, parameter_fields
from planner.deadline import Deadline
from planner.plan_parameters import PlanParameters

if TYPE_CHECKING:
    from planner.model.target import TargetState

DEFAULT_SOLVER = "lut.solve.point_worker:solve_point"  # module:function the child runs


def run_point(solver: str, scenario_path: str, point: int, state: TargetState, warm: PlanParameters | None,
              warm_shift_s: float, timeout_s: float, max_wall_s: float | None = None,
              plan_budget_s: float | None = None, cold_fallback: bool = False,
              timeout_name: str = "--point-timeout", solver_kwargs: dict[str, float] | None = None,
              keep_process: bool = False) -> PointResult:
    """Solve one point in a child process; timeouts and crashes become failed results.

    ``warm``, shifted in time by ``warm_shift_s`` [s], is the solve's warm start. ``max_wall_s`` [s], when
    given, lowers the per-NLP wall-time limit of the solve (see :func:`lut.solve.point_worker.solve_point`);
    ``plan_budget_s``, when given, ends the child's plan that many seconds after its launch (its best plan
    is verified and returned before the kill); ``cold_fallback`` re-plans cold a warm-started point whose plan is
    infeasible (see :func:`lut.solve.point_worker.solve_point`);
    ``timeout_s`` [s] is the hard limit of the whole process, which a timeout's reason names as
    ``timeout_name`` (the option that set it). ``solver_kwargs``: further keyword arguments of the solver.
    ``keep_process``: solve in this process's kept solver process (:mod:`lut.solve.point_server`: a build's points
    share its planner) instead of a new one; the same limit, and a point over it or crashing ends that process.
    """
    with scratch_dir("lutgen-point-") as tmp:
        in_path, out_path = tmp / "in.npz", tmp / "out.npz"
        args = {"scenario_path": scenario_path, "point": point, "attitude_wxyz": state.attitude_wxyz,
                "omega_body_rad_s": state.omega_body_rad_s, "warm_shift_s": warm_shift_s}
        if max_wall_s is not None:
            args["max_wall_s"] = max_wall_s
        if cold_fallback:
            args["cold_fallback"] = 1
        if warm is not None:
            args.update({WARM_PREFIX + key: value for key, value in parameter_fields(warm).items()})
        args.update({KWARG_PREFIX + key: value for key, value in (solver_kwargs or {}).items()})
        t0 = time.perf_counter()
        if plan_budget_s is not None:  # time.monotonic() is one clock for every process of the machine
            args["deadline_at_s"] = Deadline.after(plan_budget_s).at_s
        save_npz(in_path, args)
        solve = solve_served if keep_process else _solve_in_new_process
        answer = solve(solver, in_path, out_path, timeout_s)
        elapsed = time.perf_counter() - t0
        if answer.timed_out:
            return failed_result(point, f"timeout: exceeded {timeout_name} {timeout_s:g} s", elapsed)
        if not answer.answered or not out_path.exists():
            return failed_result(point, answer.why or "worker gave no answer", elapsed)
        return from_record(load_npz(out_path))


def _solve_in_new_process(solver: str, in_path: Path, out_path: Path, timeout_s: float) -> ServedAnswer:
    """IN.npz solved into OUT.npz by a process of its own, killed after ``timeout_s`` [s]."""
    try:
        proc = subprocess.run([sys.executable, "-m", "lut.solve.point_worker", solver, str(in_path), str(out_path),
                               str(os.getpid())], capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return ServedAnswer(False, timed_out=True)
    if proc.returncode != 0 or not out_path.exists():
        return ServedAnswer(False, why=crash_reason(proc.returncode, proc.stderr))
    return ServedAnswer(True)
