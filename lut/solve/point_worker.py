"""Solve one grid point in its own process: ``python -m lut.build.point_worker SOLVER IN.npz OUT.npz [PARENT_PID]``.

A build runs every point in a child process so that a point that exceeds its time limit can be
killed, and a point that crashes (segfault, out of memory) takes down only itself: both are recorded
as failed with the reason and the build goes on. Inputs and outputs are ``.npz`` files read with
``allow_pickle=False``; the output is written atomically (temp + rename).

``SOLVER`` is ``module:function`` with the signature of :func:`solve_point` (tests substitute a fast
stand-in; the product always uses this module's own). ``PARENT_PID``, the process that started this
one, makes it end when that process dies (:mod:`lut.build.parent_watch`).
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from lut.build.parent_watch import exit_with_parent
from lut.table.records import Record, failed_record, out_of_reach_record, parameters_from_record, record_from_plan

_PLANNERS: dict[str, Any] = {}


def solve_point(scenario_path: str, point: int, attitude_wxyz: np.ndarray, omega_body_rad_s: np.ndarray,
                warm: Record | None, warm_shift_s: float, max_wall_s: float | None = None) -> Record:
    """Plan and verify one target state; warm-started from a neighbour's record when given.

    ``max_wall_s`` (s) lowers the scenario's per-NLP wall-time limit (a query's refine inside its budget).
    """
    from dataclasses import replace

    from planner.config.scenario import load_scenario
    from planner.model.target import TargetState
    from planner.plan import OutOfReach, Planner
    from planner.verify.verifier import verify

    key = f"{scenario_path}|{max_wall_s}"
    if key not in _PLANNERS:
        sc = load_scenario(scenario_path)
        if max_wall_s is not None:
            sc = replace(sc, solver=replace(sc.solver, max_wall_s=min(sc.solver.max_wall_s, max_wall_s)))
        _PLANNERS[key] = Planner(sc)
    planner = _PLANNERS[key]
    state = TargetState(np.asarray(attitude_wxyz, dtype=float), np.asarray(omega_body_rad_s, dtype=float))
    warm_start = None
    if warm is not None:
        rate = float(np.linalg.norm(omega_body_rad_s))
        period = 2 * np.pi / rate if rate > 0 else None
        max_delay_s = planner.scenario.phases.max_start_delay_s
        warm_start = parameters_from_record(warm).shifted_in_time(warm_shift_s, period, max_delay_s)
    t0 = time.perf_counter()
    try:
        plan = planner.plan(state, warm_start)
    except OutOfReach as exc:
        return out_of_reach_record(point, str(exc), time.perf_counter() - t0)
    report = verify(plan)
    rec = record_from_plan(point, plan, report)
    rec["solve_time_s"] = time.perf_counter() - t0
    return rec


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
    solver_spec, in_path, out_path, *parent = argv
    # a killed build (or query) must not leave this solve running to its time limit
    exit_with_parent(int(parent[0]) if parent else None)
    module, _, name = solver_spec.partition(":")
    solver = getattr(importlib.import_module(module), name)
    args = load_npz(Path(in_path))
    warm = {k[5:]: v for k, v in args.items() if k.startswith("warm/")} or None
    point = int(args["point"])
    extra = {"max_wall_s": float(args["max_wall_s"])} if "max_wall_s" in args else {}
    try:
        rec = solver(str(args["scenario_path"]), point, args["attitude_wxyz"], args["omega_body_rad_s"], warm,
                     float(args["warm_shift_s"]), **extra)
    except Exception as exc:  # noqa: BLE001 - a failure of this point only: recorded, the build goes on
        rec = failed_record(point, f"{type(exc).__name__}: {exc}".splitlines()[0])
    save_npz(Path(out_path), rec)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
