"""``lutgen build``: solve every grid point, crash-safe, resumable, in parallel (DESIGN §6).

* **Order.** Points are solved in continuation layers: every point is warm-started from a solved
  neighbour (its parent in :meth:`Grid.continuation_order`), which keeps neighbours in the same local
  minimum and makes interpolation meaningful. A layer runs in parallel; the next waits for it. On a
  flat-spin grid the warm start's meeting time is shifted by the phase ↔ time symmetry.
* **Isolation.** Each point runs in its own child process (:mod:`lut.build.point_worker`) with a hard
  time limit: a point that times out or crashes its process is recorded as failed with the reason.
* **Crash safety.** Every finished point is appended to a checksummed journal beside the output at
  once; ``--resume`` skips what the journal holds. The HDF5 table is assembled at the end atomically;
  once it holds every point, the journal is removed.
* **Parallelism.** joblib: ``loky`` locally, or ``dask`` with a ``distributed`` scheduler address for
  a cluster (the workers need lutgen installed and the config files at the same paths).
* **Determinism.** Same config ⇒ same warm-start tree ⇒ same table (up to points that hit the time
  limit, which depends on the machine).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path

import numpy as np

from lut.build.parent_watch import exit_with_parent
from lut.build.point_worker import load_npz, save_npz
from lut.output.paths import Output, check_outputs
from lut.table.grid import Grid, GridConfig, load_grid, phase_time_shift_s
from lut.table.journal import Journal, JournalStatus, journal_status
from lut.table.records import Record, failed_record
from lut.table.store import STATUS_CODES, Table, model_hash, write_table
from planner.config.scenario import Scenario, load_scenario
from planner.errors import LutgenError
from planner.model.target import TargetState

DEFAULT_SOLVER = "lut.build.point_worker:solve_point"


MAX_POINT_TIMEOUT_S = 7 * 86400.0  # a longer per-point limit is surely a typo (s)


@dataclass
class BuildOptions:
    jobs: int = 1
    backend: str = "loky"  # or "dask"
    scheduler: str | None = None  # dask: tcp://HOST:PORT
    point_timeout_s: float = 900.0
    resume: bool = False  # continue the journal; a complete table is left as it is
    force: bool = False  # start over: an existing table (replaced when the new one is complete) or journal
    solver: str = DEFAULT_SOLVER  # module:function run in the point process
    progress: bool = True


class BuildOutcome(Enum):
    BUILT = "built"  # points were solved (or all were journaled) and the table written
    ALREADY_COMPLETE = "already complete"  # --resume of a complete table: nothing solved, nothing written


@dataclass
class BuildSummary:
    table: Path
    n_points: int
    counts: dict[str, int]
    solved_now: int
    wall_time_s: float
    failures: list[str] = field(default_factory=list)
    outcome: BuildOutcome = BuildOutcome.BUILT


def table_hash(scenario: Scenario) -> str:
    """Hash of robot URDF + target + scenario text: a table answers only for this model."""
    urdf = Path(scenario.robot.urdf_path).read_text(encoding="utf-8")
    target = Path(scenario.target.source).read_text(encoding="utf-8")
    return model_hash(urdf, target, scenario.text)


def journal_path(table_path: Path) -> Path:
    return table_path.with_name(table_path.name + ".journal")


def prepare(grid_path: str | Path) -> tuple[GridConfig, Scenario, Grid]:
    """Load and validate the grid config, its scenario, and the grid over target states."""
    config = load_grid(grid_path)
    scenario = load_scenario(config.scenario_path)
    return config, scenario, Grid(config, scenario.target.inertia_body_kg_m2, scenario.target_state.as_state())


def run_point(solver: str, scenario_path: str, point: int, state: TargetState, warm: Record | None,
              warm_shift_s: float, timeout_s: float, max_wall_s: float | None = None,
              timeout_name: str = "--point-timeout") -> Record:
    """Solve one point in a child process; timeouts and crashes become failed records.

    ``max_wall_s`` (s), when given, lowers the per-NLP wall-time limit of the solve (see
    :func:`lut.build.point_worker.solve_point`); ``timeout_s`` is the hard limit of the whole process, which a
    timeout's reason names as ``timeout_name`` (the option that set it).
    """
    with tempfile.TemporaryDirectory(prefix="lutgen-point-") as tmp:
        in_path, out_path = Path(tmp) / "in.npz", Path(tmp) / "out.npz"
        args = {"scenario_path": scenario_path, "point": point, "attitude_wxyz": state.attitude_wxyz,
                "omega_body_rad_s": state.omega_body_rad_s, "warm_shift_s": warm_shift_s}
        if max_wall_s is not None:
            args["max_wall_s"] = max_wall_s
        if warm is not None:
            args.update({f"warm/{k}": v for k, v in warm.items()})
        save_npz(in_path, args)
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, "-m", "lut.build.point_worker", solver, str(in_path), str(out_path),
                                   str(os.getpid())], capture_output=True, text=True, timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return failed_record(point, f"timeout: exceeded {timeout_name} {timeout_s:g} s", time.perf_counter() - t0)
        if proc.returncode != 0 or not out_path.exists():
            last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            how = f"signal {-proc.returncode}" if proc.returncode < 0 else f"exit code {proc.returncode}"
            return failed_record(point, f"worker crashed ({how}): {last}", time.perf_counter() - t0)
        return load_npz(out_path)


def _layers(order: list[tuple[int, int | None]]) -> list[list[tuple[int, int | None]]]:
    depth: dict[int, int] = {}
    layers: list[list[tuple[int, int | None]]] = []
    for point, parent in order:
        d = 0 if parent is None else depth[parent] + 1
        depth[point] = d
        while len(layers) <= d:
            layers.append([])
        layers[d].append((point, parent))
    return layers


def _parallel(options: BuildOptions):  # noqa: ANN202
    """A joblib ``Parallel`` for the chosen backend (loky here, dask on a distributed cluster)."""
    import joblib

    if options.backend == "loky":
        # every worker ends itself when the build dies (loky's own idle timeout would keep it 300 s)
        with joblib.parallel_config(backend="loky", initializer=exit_with_parent, initargs=(os.getpid(),)):
            return joblib.Parallel(n_jobs=options.jobs, return_as="generator_unordered"), None
    if options.backend == "dask":
        try:
            from distributed import Client
        except ImportError:
            raise LutgenError("--backend dask: the 'distributed' package is missing (pip install 'lutgen[dask]')") \
                from None
        try:
            client = Client(options.scheduler, timeout="10s")
        except (OSError, ValueError) as exc:
            raise LutgenError(f"--scheduler {options.scheduler}: cannot connect ({exc})") from None
        # parallel_config resolves joblib's lazily registered external backends ("dask"); Parallel(backend=…)
        # alone does not
        with joblib.parallel_config(backend="dask"):
            return joblib.Parallel(return_as="generator_unordered"), client
    raise LutgenError(f"--backend: must be loky or dask, got {options.backend!r}")


def check_options(options: BuildOptions) -> None:
    """Raise :class:`LutgenError` for an option value no build can use (before any file is touched)."""
    if options.resume and options.force:
        raise LutgenError("--resume and --force exclude each other: continue the journal, or start over")
    if not (np.isfinite(options.point_timeout_s) and 0 < options.point_timeout_s <= MAX_POINT_TIMEOUT_S):
        raise LutgenError(f"--point-timeout: must be in (0, {MAX_POINT_TIMEOUT_S:g}] s, got {options.point_timeout_s}")
    if options.jobs < 1:
        raise LutgenError(f"-j/--jobs: must be >= 1, got {options.jobs}")
    if options.backend not in ("loky", "dask"):
        raise LutgenError(f"--backend: must be loky or dask, got {options.backend!r}")
    if options.backend == "dask" and not options.scheduler:
        raise LutgenError("--backend dask needs --scheduler tcp://HOST:PORT")


def _existing_work(table_path: Path, jpath: Path, options: BuildOptions, mhash: str, config: GridConfig) -> bool:
    """Apply the overwrite and resume rules (README, workflow 1) to what is at ``table_path``: raise
    :class:`LutgenError` where the build must not start, delete an interrupted journal under ``--force``,
    and return True when the table is complete and ``--resume`` leaves it as it is."""
    status = journal_status(jpath)
    if status is JournalStatus.IN_USE:
        raise LutgenError(f"{jpath}: another build of {table_path} is running (its journal is locked); "
                          "wait for it, or stop it first")
    if status is JournalStatus.INTERRUPTED:
        if options.force:
            jpath.unlink()
        elif not options.resume:
            raise LutgenError(f"{jpath} exists: an earlier build of {table_path} was interrupted; rerun with "
                              "--resume to continue it, or --force to start over")
        return False
    if not table_path.exists() or options.force:
        return False
    if not options.resume:
        raise LutgenError(f"{table_path} exists: --force to build it again (the old table stays until the new "
                          "one is complete), or another --out")
    table = Table.open(table_path)
    if table.model_hash != mhash or table.attrs.get("config_text") != config.text:
        raise LutgenError(f"{table_path} was built from another grid config, robot, target or scenario: nothing "
                          "to resume; --force to build it again")
    if table.counts()["pending"]:
        raise LutgenError(f"{table_path} has pending points but no journal to resume; --force to build it again")
    return True


def _complete_summary(table_path: Path, t_start: float) -> BuildSummary:
    table = Table.open(table_path)
    reasons = table.field("failure_reason")
    failures = [f"point {p}: {reasons[p]}" for p in np.flatnonzero(table.status == STATUS_CODES["failed"])]
    return BuildSummary(table_path, table.n_points, table.counts(), 0, time.perf_counter() - t_start, failures,
                        BuildOutcome.ALREADY_COMPLETE)


def run_build(grid_path: str | Path, table_path: str | Path, options: BuildOptions,
              on_record: Callable[[Record], None] | None = None) -> BuildSummary:
    """Build (or resume) the table of ``grid_path`` into ``table_path``.

    Everything that can refuse the build (options, configs, output paths, an existing table or journal)
    is checked before a file is created; a build that stops before its first record leaves no journal.
    """
    t_start = time.perf_counter()
    table_path = Path(table_path)
    check_options(options)
    config, scenario, grid = prepare(grid_path)
    jpath = journal_path(table_path)
    inputs = [grid_path, config.scenario_path, scenario.robot.urdf_path, scenario.target.source]
    check_outputs(inputs, [Output("--out", table_path), Output("--out (its journal)", jpath)], tables_allowed=True)
    mhash = table_hash(scenario)
    if _existing_work(table_path, jpath, options, mhash, config):
        return _complete_summary(table_path, t_start)
    parallel, client = _parallel(options)
    try:
        journal = Journal(jpath, {"model_hash": mhash, "grid_text": config.text})
    except BaseException:
        if client is not None:
            client.close()
        raise
    try:
        done, solved_now = _solve_layers(grid, config, options, journal, parallel, on_record)
    except BaseException:
        if journal.started and not journal.records():
            journal.discard()  # nothing was solved: leave no journal that would ask for --resume
        raise
    finally:
        journal.close()
        if client is not None:
            client.close()
    write_table(table_path, grid_axes=list(zip(grid.axis_names, grid.axis_values, strict=True)),
                grid_kind=config.kind, config_text=config.text, scenario_text=scenario.text, model_hash=mhash,
                records=done, n_points=grid.n_points,
                scenario_path=os.path.relpath(config.scenario_path, table_path.absolute().parent))
    counts = {name: sum(1 for r in done.values() if r["status"] == name) for name in STATUS_CODES}
    counts["pending"] = grid.n_points - len(done)
    if counts["pending"] == 0:
        # the table now holds every point durably; a leftover journal would only block the next build
        jpath.unlink(missing_ok=True)
    failures = [f"point {p}: {r['failure_reason']}" for p, r in sorted(done.items()) if r["status"] == "failed"]
    return BuildSummary(table_path, grid.n_points, counts, solved_now, time.perf_counter() - t_start, failures)


def _solve_layers(grid: Grid, config: GridConfig, options: BuildOptions, journal: Journal, parallel,  # noqa: ANN001
                  on_record: Callable[[Record], None] | None) -> tuple[dict[int, Record], int]:
    """Solve every point the journal does not hold yet, layer by layer; the records of all points, and how
    many were solved now."""
    import joblib

    done = journal.records()
    order = grid.continuation_order()
    todo = sum(1 for p, _ in order if p not in done)
    bar = _progress(len(order), len(order) - todo, options.progress)
    solved_now = 0
    scenario_path = str(config.scenario_path)
    try:
        for layer in _layers(order):
            tasks = []
            for point, parent in layer:
                if point in done:
                    continue
                warm = done.get(parent) if parent is not None else None
                if warm is not None and warm.get("status") != "feasible":
                    warm = None
                shift = 0.0
                if warm is not None and config.kind == "flat_spin":
                    shift = _phase_shift(grid, parent, point)
                tasks.append(joblib.delayed(run_point)(options.solver, scenario_path, point, grid.state(point), warm,
                                                       shift, options.point_timeout_s))
            if not tasks:
                continue
            for rec in parallel(tasks):
                journal.append(rec)
                done[int(rec["point"])] = rec
                solved_now += 1
                if on_record is not None:
                    on_record(rec)
                bar.update(rec)
    finally:
        bar.close()
    return done, solved_now


def _phase_shift(grid: Grid, parent: int, point: int) -> float:
    """Start-delay shift of the flat-spin symmetry from ``parent`` to ``point`` (s; 0 off the phase axis)."""
    names = grid.axis_names
    if "spin_phase_deg" not in names:
        return 0.0
    i = names.index("spin_phase_deg")
    cp, cc = grid.coordinates(parent), grid.coordinates(point)
    rate = cc[names.index("spin_rate_deg_s")] if "spin_rate_deg_s" in names else \
        np.degrees(np.linalg.norm(grid.state(point).omega_body_rad_s))
    if cp[i] == cc[i]:
        return 0.0
    # the child reaches the parent's configuration Δφ/rate earlier
    return -phase_time_shift_s(cp[i], cc[i], rate)


class _Progress:
    def __init__(self, total: int, initial: int, enabled: bool) -> None:
        self.failed = 0
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=initial, unit="point", desc="build", dynamic_ncols=True,
                            file=sys.stderr)

    def update(self, rec: Record) -> None:
        if rec["status"] == "failed":
            self.failed += 1
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failed, last=rec["status"])
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _progress(total: int, initial: int, enabled: bool) -> _Progress:
    return _Progress(total, initial, enabled)
