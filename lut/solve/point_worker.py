"""Solve one target state in its own process: ``python -m lut.solve.point_worker SOLVER IN.npz OUT.npz [PARENT_PID]``,
or a build's points one after another in one process: ``python -m lut.solve.point_worker --serve SOLVER PARENT_PID``.

A build runs every point in a child process so that a point that exceeds its time limit can be
killed, and a point that crashes (segfault, out of memory) takes down only itself: both are recorded
as failed with the reason and the build goes on. Inputs and outputs are ``.npz`` files read with
``allow_pickle=False``; the output is written atomically (temp + rename).

``SOLVER`` is ``module:function`` with the signature of :func:`solve_point` (tests substitute a fast
stand-in; the product always uses this module's own): it gets the warm start typed and returns the
point's flat record (:mod:`lut.table.records`), which is what goes into OUT.npz. ``PARENT_PID``, the
process that started this one, makes it end when that process dies (:mod:`lut.solve.parent_watch`).
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from lut.solve.parent_watch import exit_with_parent
from lut.table.point_result import PointResult, PointStatus
from lut.table.records import (
    Record,
    failed_result,
    out_of_reach_result,
    parameters_from_fields,
    result_from_plan,
    to_record,
    with_notes,
)
from planner.deadline import NO_DEADLINE, VERIFY_RESERVE_S, Deadline
from planner.model.spin_period import repeat_period_s
from planner.plan_parameters import PlanParameters

if TYPE_CHECKING:
    from planner.model.target import TargetState
    from planner.plan import Planner

WARM_PREFIX = "warm/"  # the warm start's parameter fields in IN.npz
KWARG_PREFIX = "kw/"  # further keyword arguments of the solver (e.g. a build's --robust), by name
DONE_TOKEN = "lutgen-point-done"  # a served point's answer line (a solver's own prints on stdout are skipped)
_PLANNERS: dict[str, Planner] = {}
PLANNERS_KEPT = 2  # a planner holds its compiled problems (hundreds of MB): a kept process keeps few
# share of the time left within which a warm plan must find a braked grasp when a cold plan follows it: a neighbour's
# grasp that cannot be braked here held its stabilization to the point's timeout, and the cold plan that would have
# been feasible never ran (docs/measurements.md, "Optimal tables"); a costed plan's descent still goes on to the
# deadline
WARM_SHARE = 0.5


def solve_point(scenario_path: str, point: int, attitude_wxyz: NDArray[np.float64],
                omega_body_rad_s: NDArray[np.float64], warm: PlanParameters | None, warm_shift_s: float,
                max_wall_s: float | None = None, deadline_at_s: float | None = None, cold_fallback: bool = False,
                robust_attitude_sigma_deg: float | None = None, robust_rate_sigma_deg_s: float = 0.0,
                robust_samples: int = 0, observed_at_s: float | None = None,
                earliest_start_s: float | None = None) -> Record:
    """Plan and verify one target state (attitude ``(4,)`` w, x, y, z; body rates ``(3,)`` [rad/s]); warm-started
    from a neighbour's parameters, shifted in time by ``warm_shift_s`` [s], when given.

    ``max_wall_s`` [s] lowers the scenario's per-NLP wall-time limit (a query's refine inside its budget);
    ``deadline_at_s`` (a ``time.monotonic()`` instant) ends the plan there, less :data:`VERIFY_RESERVE_S` to verify
    it and write the record. With ``cold_fallback`` a warm-started plan that verify finds infeasible is planned
    again cold (with its retries over grasps, within the same deadline), and the cold plan is kept if it is
    feasible: a neighbour's solution can lead into a family that does not work here.
    With ``robust_attitude_sigma_deg`` [deg] (and the rate σ [deg/s]) a feasible point also gets its robustness
    figure over ``robust_samples`` drawn states (``lutgen build --robust``). ``observed_at_s``: the instant of a
    live observation (a query's refine): its approaches start no earlier than its answer can come
    (:meth:`planner.deadline.Deadline.earliest_start_s`). ``earliest_start_s`` [s after the observation]: the
    approach starts no earlier (the scenario's ``phases.min_start_delay_s`` raised: a query's ``--earliest-start-s``).
    """
    from planner.model.target import TargetState

    planner = _planner(scenario_path, max_wall_s, earliest_start_s)
    state = TargetState(np.asarray(attitude_wxyz, dtype=float), np.asarray(omega_body_rad_s, dtype=float))
    warm_start = None
    if warm is not None:  # moved by whole periods only where the motion repeats: not for a tumble
        period = repeat_period_s(state, planner.scenario.target.inertia_body_kg_m2)
        warm_start = warm.shifted_in_time(warm_shift_s, period, planner.scenario.phases.start_delay_window_s)
    t0 = time.perf_counter()
    deadline = plan_deadline(deadline_at_s, observed_at_s)
    grasp_by = warm_grasp_deadline(deadline) if cold_fallback and warm_start is not None else None
    result = verified_plan(planner, point, state, warm_start, deadline, grasp_by)
    if cold_fallback and warm_start is not None and result.status is not PointStatus.FEASIBLE and not deadline.passed:
        cold = verified_plan(planner, point, state, None, deadline)
        kept = cold if cold.status is PointStatus.FEASIBLE else result  # else the neighbour's family's verdict
        result = replace(kept, iterations=result.iterations + cold.iterations)
    result = replace(result, solve_time_s=time.perf_counter() - t0)
    if robust_attitude_sigma_deg is not None and robust_samples > 0 and result.status is PointStatus.FEASIBLE:
        from lut.robustness.point_figure import point_robustness

        result = replace(result, robustness=point_robustness(
            planner, scenario_path, state, result.parameters, robust_attitude_sigma_deg, robust_rate_sigma_deg_s,
            robust_samples, seed=max(point, 0)))
    return with_notes(to_record(result), result)


def plan_deadline(deadline_at_s: float | None, observed_at_s: float | None = None) -> Deadline:
    """A solver's plan deadline: ``deadline_at_s`` (a ``time.monotonic()`` instant; None: none) less
    :data:`VERIFY_RESERVE_S` to verify the plan and write the record before the process is killed; of a live plan
    observed at ``observed_at_s`` (a ``time.monotonic()`` instant, one clock for every process of the machine) when
    given (a query's or a re-plan's solve; None: a table point)."""
    deadline = NO_DEADLINE if deadline_at_s is None else Deadline(deadline_at_s).earlier(VERIFY_RESERVE_S)
    return deadline if observed_at_s is None else deadline.observed(observed_at_s)


def warm_grasp_deadline(deadline: Deadline) -> Deadline:
    """The instant by which a warm plan that a cold one follows must find a braked grasp: :data:`WARM_SHARE` of what
    is left of ``deadline`` (unbounded stays unbounded)."""
    if not deadline.bounded:
        return deadline
    return deadline.earlier((1.0 - WARM_SHARE) * max(deadline.remaining_s(), 0.0),
                            "the warm plan's share of the point's time (a cold plan follows)")


def verified_plan(planner: Planner, point: int, state: TargetState, warm_start: PlanParameters | None,
                  deadline: Deadline, grasp_by: Deadline | None = None) -> PointResult:
    """The plan of ``state`` (warm from ``warm_start``, cold without) verified, as the point's result; its braked
    grasp found by ``grasp_by`` (default ``deadline``); a cold plan proved out of reach is an infeasible result
    without parameters."""
    from planner.plan import OutOfReach
    from planner.verify.verifier import verify

    t0 = time.perf_counter()
    try:
        plan = planner.plan(state, warm_start, deadline, grasp_by)
    except OutOfReach as exc:
        return out_of_reach_result(point, str(exc), time.perf_counter() - t0)
    return result_from_plan(point, plan, verify(plan))


def _planner(scenario_path: str, max_wall_s: float | None, earliest_start_s: float | None = None) -> Planner:
    """The planner of ``scenario_path`` as its files are now (built once per process, model, wall-time limit [s] and
    earliest start [s]: a kept process serves later builds too, and an edited scenario, robot or target gets a new
    planner); the :data:`PLANNERS_KEPT` last used are kept."""
    from lut.table.model_identity import table_hash
    from planner.config.scenario import load_scenario
    from planner.plan import Planner

    sc = load_scenario(scenario_path)
    key = f"{table_hash(sc)}|{max_wall_s}|{earliest_start_s}"
    if key not in _PLANNERS:
        if max_wall_s is not None:
            sc = replace(sc, solver=replace(sc.solver, max_wall_s=min(sc.solver.max_wall_s, max_wall_s)))
        if earliest_start_s is not None:
            sc = sc.starting_from(earliest_start_s)
        _PLANNERS[key] = Planner(sc)
    _PLANNERS[key] = _PLANNERS.pop(key)  # the last used last
    while len(_PLANNERS) > PLANNERS_KEPT:
        del _PLANNERS[next(iter(_PLANNERS))]
    return _PLANNERS[key]


def save_npz(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` (numbers, arrays, strings) as .npz atomically."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, **{k: np.asarray(v) for k, v in data.items()})
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def load_npz(path: Path) -> dict[str, Any]:
    """Read an .npz written by :func:`save_npz` (0-d arrays become Python scalars/strings)."""
    with np.load(path, allow_pickle=False) as z:
        return {k: (z[k].item() if z[k].ndim == 0 else z[k]) for k in z.files}


def main(argv: list[str]) -> int:
    """``SOLVER IN.npz OUT.npz [PARENT_PID]``: one point; ``--serve SOLVER PARENT_PID``: :func:`serve`."""
    if argv and argv[0] == "--serve":
        return serve(argv[1], int(argv[2]))
    solver_spec, in_path, out_path, *parent = argv
    # a killed build (or query) must not leave this solve running to its time limit
    exit_with_parent(int(parent[0]) if parent else None)
    answer(resolve(solver_spec), Path(in_path), Path(out_path))
    return 0


def serve(solver_spec: str, parent_pid: int) -> int:
    """Solve the points asked on stdin, one line ``IN.npz OUT.npz`` each, in this one process, answering each with
    the line ``DONE_TOKEN OUT.npz`` on stdout once OUT.npz is written; ends when stdin closes or the parent dies.

    A build's points then share one planner per scenario (its problems built once, not once per point); a point
    that exceeds its time limit or crashes takes this process with it, and the next point starts a new one
    (:mod:`lut.solve.point_process`)."""
    exit_with_parent(parent_pid)
    solver = resolve(solver_spec)
    for line in sys.stdin:
        in_path, out_path = line.split()
        answer(solver, Path(in_path), Path(out_path))
        print(f"{DONE_TOKEN} {out_path}", flush=True)
    return 0


def resolve(solver_spec: str) -> Callable[..., Record]:
    """The solver ``module:function``."""
    module, _, name = solver_spec.partition(":")
    return getattr(importlib.import_module(module), name)


def answer(solver: Callable[..., Record], in_path: Path, out_path: Path) -> None:
    """Solve the point of ``in_path`` with ``solver`` and write its record to ``out_path``; an exception is this
    point's failure, recorded."""
    args = load_npz(in_path)
    warm = parameters_from_fields({k[len(WARM_PREFIX):]: v for k, v in args.items() if k.startswith(WARM_PREFIX)})
    point = int(args["point"])
    extra: dict[str, Any] = {key: float(args[key]) for key in ("max_wall_s", "deadline_at_s") if key in args}
    if args.get("cold_fallback"):
        extra["cold_fallback"] = True
    extra.update({k[len(KWARG_PREFIX):]: v for k, v in args.items() if k.startswith(KWARG_PREFIX)})
    try:
        rec = solver(str(args["scenario_path"]), point, args["attitude_wxyz"], args["omega_body_rad_s"], warm,
                     float(args["warm_shift_s"]), **extra)
    except Exception as exc:  # noqa: BLE001 - a failure of this point only: recorded, the build goes on
        rec = to_record(failed_result(point, f"{type(exc).__name__}: {exc}".splitlines()[0]))
    save_npz(out_path, rec)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
