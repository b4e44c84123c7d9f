"""One plan executed against many true target states, each run verified densely, in parallel worker processes.

A run is :meth:`planner.plan.Planner.simulate` at the true state with the plan's parameters (approach as
planned, tracking IK closing on the true grasp frame, stabilization spline applied from the actual grasp
state, or, with ``resolve_iterations``, the stabilization NLP solved warm from the plan's spline at that grasp
state within that many iterations, its answer flown if the solve succeeds), then the full
:func:`planner.verify.verifier.verify` of that run. Each worker process loads the
scenario and builds its :class:`~planner.plan.Planner` once (seconds) and keeps it for every later chunk;
a worker is sent the scenario's path, never objects. Identical states (every run at error scale 0) are
executed once and their outcome shared.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from planner.model.target_state import TargetState
from planner.plan_parameters import PlanParameters

if TYPE_CHECKING:  # the planner is imported in the workers, when they first run
    from planner.plan import Planner

Array = NDArray[np.float64]
CHUNKS_PER_JOB = 4  # chunks per worker: progress granularity and load balance against per-chunk overhead

_PLANNERS: dict[str, Planner] = {}  # scenario path → Planner, one per worker process


@dataclass(frozen=True)
class RunOutcome:
    """One run's verdict: which checks failed, each check's margin, the smallest clearance over time, its cost."""

    feasible: bool
    failed: tuple[str, ...]  # failed checks, earliest worst value first; "execution" if the run could not be made
    margins: dict[str, float]  # check name → margin (≥ 0 satisfied, the check's unit)
    t_s: Array  # (m,) verified times [s since the observation]
    min_distance_m: Array  # (m,) smallest signed distance over the fully held pairs [m]
    simulate_s: float  # wall time of the re-simulation [s]
    verify_s: float  # wall time of verify [s]
    error: str = ""  # why the run could not be made (empty when it was)
    resolved: bool = False  # the stabilization flown is a successful warm re-solve (not the planned spline)
    resolve_iterations: int = 0  # IPOPT iterations of the warm re-solve (0: none made)

    @property
    def first_failed(self) -> str:
        """The failed check whose worst value comes first ("" when the run is feasible)."""
        return self.failed[0] if self.failed else ""


def planner_for(scenario_path: str) -> Planner:
    """This process' Planner of ``scenario_path`` (built on first use)."""
    if scenario_path not in _PLANNERS:
        from planner.config.scenario import load_scenario
        from planner.plan import Planner

        _PLANNERS[scenario_path] = Planner(load_scenario(scenario_path))
    return _PLANNERS[scenario_path]


def register_planner(scenario_path: str, planner: Planner) -> None:
    """Use ``planner`` for ``scenario_path``'s runs in this process (a caller that already built one)."""
    _PLANNERS[scenario_path] = planner


def run_one(planner: Planner, state: TargetState, parameters: PlanParameters, step_s: float,
            resolve_iterations: int | None = None) -> RunOutcome:
    """Execute ``parameters`` against ``state`` with ``planner`` (the stabilization re-solved warm within
    ``resolve_iterations`` when given) and verify the run at ``step_s`` [s]."""
    from planner.nlp.outcome import SolveOutcome
    from planner.verify.verifier import verify

    t0 = time.perf_counter()
    try:
        plan = planner.simulate(state, parameters, resolve_iterations)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError) as exc:
        return RunOutcome(False, ("execution",), {}, np.zeros(0), np.zeros(0), time.perf_counter() - t0, 0.0,
                          str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    t1 = time.perf_counter()
    report = verify(plan, step_s)
    t2 = time.perf_counter()
    failed = sorted((c for c in report.checks.values() if not c.passed),
                    key=lambda c: np.inf if c.t_s is None else c.t_s)
    return RunOutcome(bool(report.feasible), tuple(c.name for c in failed),
                      {name: float(c.margin) for name, c in report.checks.items()},
                      np.asarray(report.t, dtype=float), np.asarray(report.min_distance_m, dtype=float),
                      t1 - t0, t2 - t1, resolved=plan.stabilization.success and plan.stabilization.status
                      != SolveOutcome.GIVEN, resolve_iterations=plan.stabilization.iterations)


def run_chunk(scenario_path: str, parameters: PlanParameters, states: Sequence[TargetState], step_s: float,
              resolve_iterations: int | None = None) -> tuple[list[RunOutcome], float]:
    """Runs of one chunk in this worker, and the Planner build time it paid (0 when already built) [s]; the
    stabilization NLP of a re-solving run is built once per worker too (the Planner keeps it)."""
    t0 = time.perf_counter()
    planner = planner_for(scenario_path)
    build_s = time.perf_counter() - t0
    return [run_one(planner, s, parameters, step_s, resolve_iterations) for s in states], build_s


def _state_key(state: TargetState) -> bytes:
    """Bytes identifying a state exactly (identical draws share one run)."""
    return np.asarray(state.attitude_wxyz).tobytes() + np.asarray(state.omega_body_rad_s).tobytes()


@dataclass(frozen=True)
class BatchCost:
    """What a batch of runs cost: wall time, runs actually executed, Planner builds paid in workers [s]."""

    wall_s: float
    executed: int
    planner_build_s: float


def run_states(scenario_path: str, parameters: PlanParameters, states: Sequence[TargetState], step_s: float,
               jobs: int, on_done: Callable[[int], None] | None = None,
               resolve_iterations: int | None = None) -> tuple[list[RunOutcome], BatchCost]:
    """Every state's outcome, in order; ``jobs`` worker processes (1: in this process); ``on_done(k)`` after each
    chunk with the number of runs it finished; ``resolve_iterations``: :func:`run_one`'s."""
    t0 = time.perf_counter()
    unique: dict[bytes, int] = {}
    for s in states:
        unique.setdefault(_state_key(s), len(unique))
    distinct = list({_state_key(s): s for s in states}.values())
    n_chunks = max(1, min(len(distinct), jobs * CHUNKS_PER_JOB)) if jobs > 1 else 1
    bounds = np.linspace(0, len(distinct), n_chunks + 1).round().astype(int)
    chunks = [(a, distinct[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]
    results: list[RunOutcome] = [RunOutcome(False, (), {}, np.zeros(0), np.zeros(0), 0.0, 0.0)] * len(distinct)
    build_s = 0.0
    for start, (outcomes, built) in _map_chunks(scenario_path, parameters, chunks, step_s, jobs, resolve_iterations):
        results[start:start + len(outcomes)] = outcomes
        build_s += built
        if on_done is not None:
            on_done(len(outcomes))
    ordered = [results[unique[_state_key(s)]] for s in states]
    return ordered, BatchCost(time.perf_counter() - t0, len(distinct), build_s)


def _map_chunks(scenario_path: str, parameters: PlanParameters, chunks: list[tuple[int, list[TargetState]]],
                step_s: float, jobs: int,
                resolve_iterations: int | None) -> Iterator[tuple[int, tuple[list[RunOutcome], float]]]:
    """``run_chunk`` over the chunks: in this process for one job, else joblib's loky workers, as they finish."""
    if jobs <= 1:
        for start, chunk in chunks:
            yield start, run_chunk(scenario_path, parameters, chunk, step_s, resolve_iterations)
        return
    import joblib

    tasks = (joblib.delayed(_indexed_chunk)(start, scenario_path, parameters, chunk, step_s, resolve_iterations)
             for start, chunk in chunks)
    yield from joblib.Parallel(n_jobs=jobs, backend="loky", return_as="generator_unordered")(tasks)


def _indexed_chunk(start: int, scenario_path: str, parameters: PlanParameters, states: Sequence[TargetState],
                   step_s: float, resolve_iterations: int | None) -> tuple[int, tuple[list[RunOutcome], float]]:
    """:func:`run_chunk` tagged with the chunk's first index (unordered results find their place)."""
    return start, run_chunk(scenario_path, parameters, states, step_s, resolve_iterations)
