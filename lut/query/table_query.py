"""``lutgen query``: observed target state → table lookup → interpolation → verify → refine (DESIGN §6).

1. The state is mapped to grid coordinates (flat spin: rate, spin-axis angle, phase) and its cell.
2. The feasible corners of the cell are interpolated — only mutually consistent ones: their meeting
   times, carried to the query's phase by the flat-spin symmetry, agree within
   :data:`CONSISTENT_DELAY_S` (corners in different local minima are not averaged). Without a feasible
   corner the nearest feasible point of the table is used.
3. The interpolated parameters are re-simulated at the true state (tracking IK, stabilization from the
   actual grasp state) and verified densely.
4. If that is not feasible, or refinement was asked for, a warm-started solve runs in a child process
   within what is left of the time budget (killed at it); a feasible refined plan replaces the
   interpolated one.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lut.build.sweep import DEFAULT_SOLVER, run_point, table_hash
from lut.table.grid import Grid, load_grid_text
from lut.table.records import PARAMETER_KEYS, Record, has_parameters, parameters_from_record
from lut.table.store import STATUS_CODES, Table, TableError
from planner.config.scenario import Scenario, load_scenario
from planner.errors import LutgenError
from planner.model.target import TargetState
from planner.nlp.bspline import UniformCubicBSpline
from planner.phases.stabilization import stabilization_spline
from planner.phases.tracking_profile import TRACKING_NODES
from planner.plan import GraspPlan, Planner
from planner.verify.verifier import VerifyReport, verify

CONSISTENT_DELAY_S = 3.0
PERIOD_FREE = float("inf")
FINISH_RESERVE_S = 3.0  # kept back from the budget to re-simulate, verify and export a refined plan (s)
PHASE_SNAP_DEG = 1e-9  # spin phases this close to a corner's are that corner's phase
MIN_REFINE_S = 5.0  # a refine with less time than this cannot finish a solve: not started (s)


@dataclass
class QueryResult:
    plan: GraspPlan
    report: VerifyReport
    source: str  # "interpolated", "nearest", "refined"
    corners_used: list[int]
    latency_s: dict[str, float] = field(default_factory=dict)


class TableQuery:
    """A table opened for queries: its grid, records and the planner of its scenario (built once)."""

    def __init__(self, table_path: str | Path, scenario_path: str | Path | None = None) -> None:
        t0 = time.perf_counter()
        self.table = Table.open(table_path)
        attrs = self.table.attrs
        path = scenario_path
        if path is None:
            stored = attrs.get("scenario_path")
            if not stored:
                raise TableError(f"{table_path}: the table does not name its scenario; pass --scenario")
            path = Path(table_path).absolute().parent / stored  # stored relative to the table's folder
            if not path.is_file():
                raise TableError(f"{table_path}: its scenario {stored} (relative to the table) is not there; "
                                 "pass --scenario")
        self.scenario: Scenario = load_scenario(path)
        self.table.check_model(table_hash(self.scenario), str(path))
        config = load_grid_text(attrs["config_text"], str(table_path), Path(path))
        self.grid = Grid(config, self.scenario.target.inertia_body_kg_m2, self.scenario.target_state.as_state())
        if self.grid.n_points != self.table.n_points:
            raise TableError(f"{table_path}: grid has {self.grid.n_points} points but the table {self.table.n_points}")
        self.scenario_path = Path(path)
        check_parameters(self.table, parameter_shapes(self.scenario))
        self.planner = Planner(self.scenario)
        self.records = {p: self.table.record(p) for p in range(self.table.n_points)}
        self.feasible = [p for p, r in self.records.items() if r.get("status") == "feasible"]
        self.refine_failure = ""
        self.load_time_s = time.perf_counter() - t0

    # ---- lookup + interpolation ------------------------------------------------------------

    def interpolate(self, state: TargetState) -> tuple[Record | None, list[int], str]:
        """Interpolated parameter record for ``state`` (or the nearest feasible one), corners used."""
        coords = self.grid.coordinates_of_state(state)
        cell = self.grid.locate(coords)
        rate = float(np.linalg.norm(state.omega_body_rad_s))
        period = 2 * np.pi / rate if rate > 0 else PERIOD_FREE
        candidates = []
        for corner, weight in zip(cell.corners, cell.weights, strict=True):
            rec = self.records[corner]
            if rec.get("status") != "feasible" or weight <= 0:
                continue
            tau = float(rec["start_delay_s"]) + self._phase_shift(corner, coords)
            candidates.append((corner, float(weight), tau % period if np.isfinite(period) else tau, rec))
        if candidates:
            # the largest-weight group of corners whose meeting times agree
            best_group: list = []
            for _, _, tau_ref, _ in candidates:
                group = [c for c in candidates if _circular_gap(c[2], tau_ref, period) <= CONSISTENT_DELAY_S]
                if sum(c[1] for c in group) > sum(c[1] for c in best_group):
                    best_group = group
            w = np.array([c[1] for c in best_group])
            w = w / w.sum()
            ref_tau = best_group[int(np.argmax(w))][2]
            rec: Record = {"status": "feasible"}
            for key in PARAMETER_KEYS:
                if key == "start_delay_s":
                    taus = np.array([ref_tau + _signed_gap(c[2], ref_tau, period) for c in best_group])
                    rec[key] = float(w @ taus)
                else:
                    rec[key] = sum(wi * np.asarray(c[3][key], dtype=float) for wi, c in zip(w, best_group, strict=True))
            return rec, [c[0] for c in best_group], "interpolated"
        if not self.feasible:
            return None, [], "none"
        nearest = min(self.feasible, key=lambda p: self.grid.normalised_distance(self.grid.coordinates(p), coords))
        rec = dict(self.records[nearest])
        rec["start_delay_s"] = float(rec["start_delay_s"]) + self._phase_shift(nearest, coords)
        return rec, [nearest], "nearest"

    def _phase_shift(self, point: int, coords: np.ndarray) -> float:
        names = self.grid.axis_names
        if "spin_phase_deg" not in names:
            return 0.0
        i = names.index("spin_phase_deg")
        rate = coords[names.index("spin_rate_deg_s")] if "spin_rate_deg_s" in names else None
        if rate is None or rate <= 0:
            return 0.0
        dphase_deg = coords[i] - self.grid.coordinates(point)[i]
        if abs(dphase_deg) <= PHASE_SNAP_DEG:
            # the corner's own phase, up to the roundoff of quaternion → angle: keep its start delay bit
            # for bit (a 1e-15 s shift feeds the tracking's finite differences and moves the plan ~1e-4)
            return 0.0
        return -dphase_deg / rate

    # ---- the whole query ---------------------------------------------------------------------

    def query(self, state: TargetState, budget_s: float = 100.0, refine: bool = False) -> QueryResult:
        """Lookup → interpolate → re-simulate + verify → refine if needed (or asked), within ``budget_s``.

        The refine runs in a child process killed at the budget (less :data:`FINISH_RESERVE_S` to
        re-simulate and verify its answer), so a query never overruns, whatever the solver does.
        """
        t_start = time.perf_counter()
        latency: dict[str, float] = {}
        rec, corners, source = self.interpolate(state)
        latency["lookup_interpolate_s"] = time.perf_counter() - t_start
        plan = report = None
        if rec is not None:
            plan, report = self._simulate_and_verify(state, rec, latency)
        # warm from the table's answer first, then cold (with its retries over grasps) in what the budget has left
        for warm, label in ((rec, "refined"), (None, "solved cold")) if rec is not None else ((None, "solved cold"),):
            remaining = budget_s - (time.perf_counter() - t_start) - FINISH_RESERVE_S
            if not (report is None or not report.feasible or refine) or remaining < MIN_REFINE_S:
                break
            t0 = time.perf_counter()
            refined = self._refine(state, warm, remaining)
            latency["refine_s"] = latency.get("refine_s", 0.0) + time.perf_counter() - t0
            if refined.get("status") in ("feasible", "infeasible") and has_parameters(refined):
                new_plan, new_report = self._simulate_and_verify(state, refined, {})
                if report is None or (new_report.feasible and (refine or not report.feasible)):
                    plan, report, source = new_plan, new_report, label
            else:
                self.refine_failure = str(refined.get("failure_reason", ""))
            refine = False  # an asked-for refine is the warm one; the cold solve only stands in for a missing plan
        if plan is None or report is None:
            why = self.refine_failure or f"there was no time left to solve (budget {budget_s:g} s)"
            raise LutgenError(f"the table has no feasible point near this state and the solve gave no plan: {why}")
        latency["total_s"] = time.perf_counter() - t_start
        return QueryResult(plan, report, source, corners, latency)

    def _simulate_and_verify(self, state: TargetState, rec: Record,
                             latency: dict[str, float]) -> tuple[GraspPlan, VerifyReport]:
        t0 = time.perf_counter()
        rate = float(np.linalg.norm(state.omega_body_rad_s))
        given = parameters_from_record(rec).shifted_in_time(0.0, 2 * np.pi / rate if rate > 0 else None,
                                                            self.scenario.phases.max_start_delay_s)
        plan = self.planner.simulate(state, given)
        latency["simulate_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        report = verify(plan)
        latency["verify_s"] = time.perf_counter() - t0
        return plan, report

    def _refine(self, state: TargetState, rec: Record | None, budget_s: float) -> Record:
        """A warm-started solve in a child process with a hard time limit of ``budget_s``.

        Each NLP's own wall-time limit is a fraction of the budget so that a solve returns its best
        iterate before the process is killed (approach, up to two rate-tightening re-solves and the
        stabilization run one after another).
        """
        warm = None
        if rec is not None:
            warm = {key: rec[key] for key in PARAMETER_KEYS}
            warm["status"] = "feasible"
        return run_point(DEFAULT_SOLVER, str(self.scenario_path), -1, state, warm, 0.0, timeout_s=budget_s,
                         max_wall_s=max(1.0, budget_s / 4),
                         timeout_name="the refine's share of --budget-s")


def parameter_shapes(scenario: Scenario) -> dict[str, tuple[int, ...]]:
    """Per-point shape of every parameter a query interpolates, for ``scenario``'s plans."""
    n = scenario.robot.n_joints
    approach = UniformCubicBSpline(scenario.approach.n_vertices, scenario.phases.approach_s)
    return {"approach_params": (n * approach.n_free_per_joint,), "base_offset_m": (2,), "start_delay_s": (),
            "q_tracking": (len(TRACKING_NODES), n),
            "stabilization_params": (n * stabilization_spline(scenario).n_free_per_joint,)}


def check_parameters(table: Table, shapes: dict[str, tuple[int, ...]]) -> None:
    """Raise :class:`TableError` unless every parameter dataset has the scenario's shape, holds floats, and is
    finite at every feasible point (what a query interpolates and re-simulates)."""
    feasible = table.status == STATUS_CODES["feasible"]
    if not feasible.any():
        return  # nothing will be read from it: the query solves from scratch
    for key, shape in shapes.items():
        if not table.has_field(key):
            raise TableError(f"{table.path}: missing dataset points/{key}, which a query interpolates")
        data = table.field(key)
        if data.shape[1:] != shape:
            raise TableError(f"{table.path}: points/{key} has per-point shape {data.shape[1:]}; this scenario's "
                             f"plans have {shape}")
        if data.dtype.kind != "f":
            raise TableError(f"{table.path}: points/{key} must hold floats, got dtype {data.dtype}")
        bad = np.flatnonzero(~np.isfinite(data[feasible].reshape(int(feasible.sum()), -1)).all(axis=1))
        if bad.size:
            raise TableError(f"{table.path}: points/{key} is not finite at feasible point "
                             f"{int(np.flatnonzero(feasible)[bad[0]])}")


def _circular_gap(a: float, b: float, period: float) -> float:
    return abs(_signed_gap(a, b, period))


def _signed_gap(a: float, b: float, period: float) -> float:
    """a − b wrapped into (−period/2, period/2] (plain difference when the period is infinite)."""
    d = a - b
    if np.isfinite(period):
        d = (d + period / 2) % period - period / 2
    return d
