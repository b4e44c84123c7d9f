"""Plan export: the ``lutgen.plan/1`` JSON object and its flat CSV twin (docs/table.md, Plan file).

All quantities in the orbital frame O and SI units; samples at the verification step, one row per time.
"""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from lut.output.plan_replay import replay_block
from lut.table.records import plan_costs
from planner.box_edge import box_edge_note
from planner.errors import LutgenError
from planner.model.rotation import matrix_to_quat
from planner.model.shapes import Box
from planner.plan import GraspPlan
from planner.verify.verifier import VerifyReport

SCHEMA = "lutgen.plan/1"


def _finite(x: float) -> float | None:
    """JSON has no inf/NaN: unconstrained limits are written as null."""
    return float(x) if math.isfinite(x) else None


def verdict_notes(plan: GraspPlan, report: VerifyReport) -> list[str]:
    """What the verdict adds to a plan's notes: for a refused plan, θ_b(0) on its base-offset box's edge."""
    edge = None if report.feasible else box_edge_note(plan.scenario.base_offset_bounds_m, plan.approach.base_offset_m)
    return [] if edge is None else [edge]


def plan_metrics(plan: GraspPlan, report: VerifyReport) -> dict[str, Any]:
    """Costs, margins, solver statistics and grasp errors of a verified plan."""
    sc = plan.scenario
    checks = {name: {"value": _finite(c.value), "limit": _finite(c.limit), "margin": _finite(c.margin),
                     "passed": bool(c.passed), "where": c.where} for name, c in report.checks.items()}
    return {
        "feasible": bool(report.feasible),
        "violations": list(report.violations),
        "start_delay_s": plan.approach.start_delay_s,
        "base_offset_m": {"x": float(plan.approach.base_offset_m[0]), "z": float(plan.approach.base_offset_m[1])},
        "free_axis_angle_deg": math.degrees(plan.tracking.free_axis_angle_rad),
        "costs": {**plan_costs(plan, report),
                  "peak_grasp_force_n": float(np.abs(report.grasp_wrench[:, :3]).max())},
        "collision_pairs": int(report.pair_count),
        "collision_rule": report.collision_rule,
        "checks": checks,
        "solver": {
            "approach": {"status": plan.approach.status, "iterations": plan.approach.iterations,
                         "time_s": plan.approach.solve_time_s},
            "stabilization": {"status": plan.stabilization.status, "iterations": plan.stabilization.iterations,
                              "time_s": plan.stabilization.solve_time_s,
                              "build_time_s": plan.stabilization.build_time_s},
            "timings_s": dict(plan.timings_s),
        },
        "notes": [*plan.notes, *verdict_notes(plan, report)],
        "limits": {"grasp_torque_max_nm": _finite(sc.limits.grasp_torque_max_nm),
                   "grasp_force_max_n": _finite(sc.limits.grasp_force_max_n),
                   "collision_margin_m": sc.limits.collision_margin_m},
    }


def plan_samples(plan: GraspPlan, report: VerifyReport) -> dict[str, np.ndarray]:
    """The sampled trajectory at the report's fixed step (the plan's own samples at those times)."""
    t = np.asarray(report.t)
    q = plan.q[report.sample_index]
    qd = plan.qd[report.sample_index]
    return {
        "t": t, "q": q, "qd": qd,
        "base_position": report.base_pose[0], "base_wxyz": report.base_pose[1],
        "ee_position": report.ee_pose[0], "ee_wxyz": report.ee_pose[1],
        "grasp_position": report.grasp_pose[0], "grasp_wxyz": report.grasp_pose[1],
        "target_position": report.target_pose[0], "target_wxyz": report.target_pose[1],
        "grasp_wrench": report.grasp_wrench,
        "min_distance_m": report.min_distance_m,
        "closest_points_m": report.closest_points_m,
    }


def target_shapes(plan: GraspPlan) -> list[dict[str, Any]]:
    """The target's collision shapes in its body frame (for the preview): boxes ``size_m`` [3] (full edge
    lengths), capsules ``radius_m``/``length_m`` (segment along the shape's z), ``handle`` marks the grasped
    part."""
    target = plan.scenario.target
    out: list[dict[str, Any]] = []
    for placed in target.shapes:
        T = placed.T_body_shape
        entry: dict[str, Any] = {"name": placed.name}
        if isinstance(placed.shape, Box):
            entry.update(kind="box", size_m=[float(v) for v in placed.shape.size_m])
        else:
            entry.update(kind="capsule", radius_m=float(placed.shape.radius_m), length_m=float(placed.shape.length_m))
        entry.update(position_m=T[:3, 3].tolist(), wxyz=matrix_to_quat(T[:3, :3]).tolist(),
                     handle=placed.name in target.handle_shapes)
        out.append(entry)
    return out


def portable_path(path: str | Path) -> str:
    """``path`` relative to the current directory, normalised (``a/../b`` → ``b``): a plan names its robot
    the way the command was given it, never by this machine's absolute path
    (:func:`lut.output.plan_file.resolve_robot_urdf` reads it against the current directory, then the
    repository root)."""
    return Path(os.path.normpath(os.path.relpath(Path(path).absolute()))).as_posix()


def plan_document(plan: GraspPlan, report: VerifyReport) -> dict[str, Any]:
    """The ``lutgen.plan/1`` JSON object."""
    sc = plan.scenario
    T = plan.T_body_grasp_used
    samples = plan_samples(plan, report)
    return {
        "schema": SCHEMA,
        "status": "feasible" if report.feasible else "infeasible",
        "scenario": sc.name,
        "robot_urdf": portable_path(sc.robot.urdf_path),
        "ee_frame": sc.robot.ee_frame,
        "target": {
            "inertia_kg_m2": np.asarray(sc.target.inertia_body_kg_m2, dtype=float).tolist(),  # 3×3, body frame
            "mass_kg": sc.target.mass_kg,
            "com_position_m": sc.target.p_world_com.tolist(),
            "attitude_wxyz": np.asarray(plan.target_state.attitude_wxyz).tolist(),
            "omega_body_rad_s": np.asarray(plan.target_state.omega_body_rad_s).tolist(),
            "grasp_in_body": {"position": T[:3, 3].tolist(), "wxyz": matrix_to_quat(T[:3, :3]).tolist()},
            "shapes": target_shapes(plan),
        },
        "phases": {name: [float(a), float(b)] for name, (a, b) in plan.phases.items()},
        "metrics": plan_metrics(plan, report),
        "samples": {**{key: np.asarray(v).tolist() for key, v in samples.items()},
                    "closest_pair": list(report.closest_pair)},
        **replay_block(plan, portable_path(sc.source)),
    }


def _write_atomically(path: str | Path, write: Callable[[Path], None]) -> None:
    """``write`` a temp file beside ``path``, then rename it over ``path``: a reader never sees half a file.
    An OS error (folder gone, disk full) is a one-line :class:`LutgenError` and leaves no temp file."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        write(tmp)
        tmp.replace(path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise LutgenError(f"{path}: cannot write ({exc.strerror or exc})") from None


def write_json(path: str | Path, document: dict[str, Any]) -> None:
    """Write the plan JSON atomically, compact (an indented dump takes the slow pure-Python encoder)."""
    _write_atomically(path, lambda tmp: tmp.write_text(json.dumps(document), encoding="utf-8"))


CSV_COLUMNS = (("t", 1), ("q", 7), ("qd", 7), ("base_position", 3), ("base_wxyz", 4), ("ee_position", 3),
               ("ee_wxyz", 4), ("grasp_position", 3), ("grasp_wxyz", 4), ("target_position", 3),
               ("target_wxyz", 4), ("grasp_wrench", 6), ("min_distance_m", 1))
# unit of each column group (the grasp wrench: forces in N, moments in N·m)
CSV_UNITS = {"t": "s", "q": "rad", "qd": "rad/s", "base_position": "m", "base_wxyz": "1", "ee_position": "m",
             "ee_wxyz": "1", "grasp_position": "m", "grasp_wxyz": "1", "target_position": "m", "target_wxyz": "1",
             "min_distance_m": "m"}


def csv_header() -> list[str]:
    """Column names with their unit in brackets, e.g. ``t [s]``, ``q_1 [rad]``, ``grasp_wrench_mx [N·m]``."""
    header = []
    for key, width in CSV_COLUMNS:
        if width == 1:
            header.append(f"{key} [{CSV_UNITS[key]}]")
            continue
        if key == "grasp_wrench":
            header += [f"{key}_{s} [{'N' if s[0] == 'f' else 'N·m'}]" for s in ("fx", "fy", "fz", "mx", "my", "mz")]
            continue
        suffixes = ["w", "x", "y", "z"] if key.endswith("wxyz") else \
            ["x", "y", "z"] if key.endswith("position") else [str(j + 1) for j in range(width)]
        header += [f"{key}_{s} [{CSV_UNITS[key]}]" for s in suffixes]
    return header


def write_csv(path: str | Path, plan: GraspPlan, report: VerifyReport) -> None:
    """The samples flat: one row per time step, a header naming each column with its unit."""
    samples = plan_samples(plan, report)
    n = len(samples["t"])
    rows = np.hstack([np.asarray(samples[key]).reshape(n, -1) for key, _ in CSV_COLUMNS])

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="", encoding="utf-8") as fh:
            writer = csv.writer(fh)
            writer.writerow(csv_header())
            for row in rows:
                writer.writerow([f"{v:.10g}" for v in row])

    _write_atomically(path, write)
