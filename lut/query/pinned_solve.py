"""The re-plan's solver, run in a child process by :func:`lut.solve.point_process.run_point`: the warm start's base
offset pinned (the chaser already waits there), everything else free.

Same signature as :func:`lut.solve.point_worker.solve_point` (``SOLVER`` = ``lut.query.pinned_solve:solve_pinned``),
deadline included: the approach NLP's θ_b(0) bounds and guess are set to the warm start's base offset, so IPOPT keeps
it fixed; the plan is verified into the point's result by the point worker's own :func:`verified_plan`.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from lut.solve.point_worker import plan_deadline, verified_plan
from lut.table.records import Record, failed_result, to_record, with_notes
from planner.plan_parameters import PlanParameters

PINNED_SOLVER = "lut.query.pinned_solve:solve_pinned"


def solve_pinned(scenario_path: str, point: int, attitude_wxyz: NDArray[np.float64],
                 omega_body_rad_s: NDArray[np.float64], warm: PlanParameters | None, warm_shift_s: float,
                 max_wall_s: float | None = None, deadline_at_s: float | None = None,
                 observed_at_s: float | None = None) -> Record:
    """Plan the state (attitude ``(4,)`` w, x, y, z; body rates ``(3,)`` [rad/s]) from ``warm`` shifted in time by
    ``warm_shift_s`` [s], with θ_b(0) pinned at ``warm``'s base offset, and verify it; ``max_wall_s`` [s] caps each
    NLP, ``deadline_at_s`` (a ``time.monotonic()`` instant) ends the plan and ``observed_at_s`` (the new estimate's
    instant) dates it as in :func:`lut.solve.point_worker.solve_point`."""
    from planner.config.scenario import load_scenario
    from planner.model.target import TargetState
    from planner.plan import Planner

    t0 = time.perf_counter()
    if warm is None:
        return to_record(failed_result(point, "a re-plan needs the previous plan's parameters", 0.0))
    x, z = (float(v) for v in warm.approach.base_offset_m)
    sc = load_scenario(scenario_path)
    solver = sc.solver if max_wall_s is None else replace(sc.solver, max_wall_s=min(sc.solver.max_wall_s, max_wall_s))
    pinned = replace(sc, base_offset_bounds_m=((x, x), (z, z)), base_offset_guess_m=np.array([x, z]), solver=solver)
    state = TargetState(np.asarray(attitude_wxyz, dtype=float), np.asarray(omega_body_rad_s, dtype=float))
    warm_start = warm.with_start_delay(warm.approach.start_delay_s + warm_shift_s)
    result = verified_plan(Planner(pinned), point, state, warm_start, plan_deadline(deadline_at_s, observed_at_s))
    result = replace(result, solve_time_s=time.perf_counter() - t0)
    return with_notes(to_record(result), result)
