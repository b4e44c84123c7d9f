#!/usr/bin/env python3
"""lutgen benchmark: speed against the paper, a finite-difference SQP baseline and pinocchio.

Usage (from the repository root, after ``./scripts/test`` has set up ``.venv``)::

    .venv/bin/python scripts/bench.py                 # full run (~30 min on 2 cores)
    .venv/bin/python scripts/bench.py --quick         # smoke run (≤ 3 min)
    .venv/bin/python scripts/bench.py --quick --trim  # structure only (the test runs this)

Writes JSON (default ``out/bench.json``) and prints a table. Every timing is
``{"median", "min", "max", "runs"}`` in seconds (``*_us``: microseconds); a part not run in the chosen
mode keeps its keys with ``{"skipped": reason}``. Sections:

* ``machine``: CPU count, platform, library versions;
* ``primitives``: µs per call of our CasADi forward kinematics, momentum map + J*, one 29-pair collision
  sweep and one dense verify, next to pinocchio's ``forwardKinematics`` / ``computeCentroidalMap``;
* ``planner``: time per phase and per plan, IPOPT iterations, scenario I and II (one core);
* ``baseline``: the approach NLP by IPOPT (exact derivatives) against ``scipy.optimize.minimize``
  SLSQP with finite-difference gradients (the paper's setting), same start and tolerance;
* ``build``: table build throughput (points/hour) with ``-j 1``, ``-j 2`` and Dask (2 workers on
  loopback) using the fake point solver, so it measures the harness and its scaling; plus the
  throughput the real solve times of the golden table imply;
* ``query``: lookup+interpolation, simulate, verify and refine latency over seeded in-grid states,
  fraction feasible from interpolation alone and after refine, peak memory of a query process.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

GOLDEN = ROOT / "tests" / "data" / "ci_golden.h5"
DEMO_TABLE = ROOT / "out" / "demo.h5"
SCENARIOS = ROOT / "configs" / "scenarios"
FAKE_SOLVER = "tests.support.fake_solver:solve"
LIBRARIES = ("numpy", "scipy", "pin", "casadi", "python-fcl", "h5py", "joblib", "distributed", "click", "lutgen")


# ---- statistics -------------------------------------------------------------------------------

def stats(samples: list[float]) -> dict:
    """Median/min/max of timings (same unit as the samples), or a skip marker when there are none."""
    if not samples:
        return {"skipped": "no samples"}
    a = np.asarray(samples, dtype=float)
    return {"median": float(np.median(a)), "min": float(a.min()), "max": float(a.max()), "runs": len(a)}


def stats_p95(samples: list[float]) -> dict:
    """:func:`stats` plus the 95th percentile (query latencies)."""
    out = stats(samples)
    if samples:
        out["p95"] = float(np.percentile(samples, 95))
    return out


def skipped(reason: str) -> dict:
    return {"skipped": reason}


def time_per_call_us(fn: Callable[[], object], repeats: int, min_time_s: float) -> dict:
    """µs per call of ``fn``: ``repeats`` batches, each long enough (≥ ``min_time_s``) to time reliably."""
    fn()  # warm caches and lazy initialisation
    t0 = time.perf_counter()
    n = 0
    while time.perf_counter() - t0 < min_time_s / 10 or n < 3:
        fn()
        n += 1
    per_call = (time.perf_counter() - t0) / n
    batch = max(1, int(min_time_s / per_call))
    results = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        results.append((time.perf_counter() - t0) / batch * 1e6)
    out = stats(results)
    out["calls_per_run"] = batch
    return out


# ---- sections ---------------------------------------------------------------------------------

def machine(mode: str, trim: bool) -> dict:
    versions = {}
    for lib in LIBRARIES:
        try:
            versions[lib] = importlib.metadata.version(lib)
        except importlib.metadata.PackageNotFoundError:
            versions[lib] = None
    return {"cpu_count": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(), "versions": versions, "mode": mode,
            "trim": trim, "timestamp_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}


def primitives(repeats: int, min_time_s: float) -> dict:
    """µs per call of the kinematic, momentum and collision primitives, and of one dense verify."""
    import pinocchio as pin

    from lut.query import TableQuery
    from lut.records import warm_start_from_record
    from planner.freefloating import FreeFloatingModel
    from planner.robot import fk_function, pin_configuration
    from planner.rotation import quat_to_matrix
    from planner.scenario import load_scenario
    from planner.scene import build_scene, world_poses
    from planner.verify import verify

    sc = load_scenario(SCENARIOS / "scenario_II.toml")
    robot = sc.robot
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.q_min, robot.q_max)
    quat = np.array([0.9, 0.1, -0.2, 0.3])
    quat /= np.linalg.norm(quat)
    p_base = np.array([0.3, -0.2, 0.1])
    q_pin = pin_configuration(p_base, quat, q)
    model = robot.pin_model
    data = model.createData()
    fk = fk_function(robot)
    ff = FreeFloatingModel(robot)
    scene = build_scene(sc)
    R = quat_to_matrix(quat)
    T_target = np.eye(4)
    T_target[:3, 3] = [0.0, 0.0, 4.0]  # target well in front: every pair is a real distance query
    fk_out = fk(q)
    poses = world_poses(robot, fk_out, R, p_base, T_target)

    def pin_fk() -> None:
        pin.forwardKinematics(model, data, q_pin)
        pin.updateFramePlacements(model, data)

    def momentum_and_jstar() -> None:
        ff.momentum(q)
        ff.gen_jacobian(q)

    out = {
        "forward_kinematics_casadi_us": time_per_call_us(lambda: fk(q), repeats, min_time_s),
        "forward_kinematics_pinocchio_us": time_per_call_us(pin_fk, repeats, min_time_s),
        "momentum_map_and_jstar_casadi_us": time_per_call_us(momentum_and_jstar, repeats, min_time_s),
        "centroidal_map_pinocchio_us": time_per_call_us(lambda: pin.computeCentroidalMap(model, data, q_pin),
                                                        repeats, min_time_s),
        "collision_sweep_us": time_per_call_us(lambda: scene.distances(poses), repeats, min_time_s),
        "collision_pairs": len(scene.pairs),
    }
    # one dense verify (≤ 0.02 s samples over the whole plan) of a plan re-simulated from the golden table
    tq = TableQuery(GOLDEN)
    point = tq.feasible[0]
    state = tq.grid.state(point)
    rate = float(np.linalg.norm(state.omega_body_rad_s))
    warm = warm_start_from_record(tq.records[point], 0.0, tq.scenario.phases.max_start_delay_s, 2 * np.pi / rate)
    plan = tq.planner.simulate(state, warm)
    verify_s = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        verify(plan)
        verify_s.append(time.perf_counter() - t0)
    out["verify_plan_s"] = stats(verify_s)
    out["verify_samples"] = int(len(plan.t))
    return out


def planner_section(runs: int, max_wall_s: float, scenarios: list[str]) -> dict:
    """Whole plans on one core: per-phase times, IPOPT iterations, feasibility by dense verification."""
    from planner.plan import Planner
    from planner.scenario import load_scenario
    from planner.target import TargetState
    from planner.verify import verify

    out: dict = {}
    for name in ("scenario_I", "scenario_II"):
        for variant in ("feasibility", "with_costs"):
            key = f"{name}_{variant}"
            if name not in scenarios or runs == 0:
                out[key] = skipped("not run in this mode (full mode runs it)")
                continue
            sc = load_scenario(SCENARIOS / f"{name}.toml")
            sc = replace(sc, solver=replace(sc.solver, max_wall_s=max_wall_s))
            if variant == "with_costs":
                # the paper's approach costs: manipulability (Eq. 14) + minimum distance (Eq. 15)
                sc = replace(sc, costs=replace(sc.costs, manipulability=1.0, min_distance=1.0))
            else:
                sc = replace(sc, costs=replace(sc.costs, manipulability=0.0, min_distance=0.0, approach_energy=0.0,
                                               attitude_disturbance=0.0, peak_wrench=0.0))
            state = TargetState(np.asarray(sc.target_state.attitude_wxyz), np.asarray(sc.target_state.omega_body_rad_s))
            phases: dict[str, list[float]] = {"approach_s": [], "tracking_s": [], "stabilization_s": [], "total_s": []}
            iters: dict[str, list[int]] = {"approach": [], "stabilization": []}
            feasible, statuses = [], []
            for _ in range(runs):
                t0 = time.perf_counter()
                planner = Planner(sc)
                plan = planner.plan(state)
                total = time.perf_counter() - t0
                t_app = plan.timings_s.get("approach_s", float("nan"))
                t_stab = plan.timings_s.get("stabilization_s", float("nan"))
                phases["approach_s"].append(t_app)
                phases["stabilization_s"].append(t_stab)
                phases["tracking_s"].append(max(0.0, plan.timings_s["total_s"] - t_app - t_stab))
                phases["total_s"].append(total)
                iters["approach"].append(plan.approach.iterations)
                iters["stabilization"].append(plan.stabilization.iterations)
                feasible.append(bool(verify(plan).feasible))
                statuses.append(f"{plan.approach.status} / {plan.stabilization.status}")
            out[key] = {**{k: stats(v) for k, v in phases.items()},
                        "ipopt_iterations": {k: stats([float(i) for i in v]) for k, v in iters.items()},
                        "feasible": feasible, "solver_status": statuses, "nlp_wall_cap_s": max_wall_s}
    return out


def baseline(cap_s: float, max_iter: int) -> dict:
    """The approach NLP: IPOPT with exact derivatives vs SLSQP with finite-difference gradients."""
    from scipy.optimize import minimize

    from planner.freefloating import FreeFloatingModel
    from planner.phases.approach import ApproachProblem
    from planner.phases.approach_guess import initial_guesses
    from planner.scenario import load_scenario
    from planner.target import TargetState

    sc = load_scenario(SCENARIOS / "scenario_II.toml")
    sc = replace(sc, solver=replace(sc.solver, max_wall_s=cap_s))
    prob = ApproachProblem(sc, FreeFloatingModel(sc.robot))
    state = TargetState(np.asarray(sc.target_state.attitude_wxyz), np.asarray(sc.target_state.omega_body_rad_s))
    guess = initial_guesses(sc, prob.spline, state, 1)[0]
    w0 = np.concatenate([guess.params, guess.base_offset_m, [guess.start_delay_s], guess.q_tracking.ravel()])
    w0 = np.clip(w0, prob.lbw[: prob.n_w], prob.ubw[: prob.n_w])
    if prob.n_extra:
        w0 = np.concatenate([w0, np.zeros(prob.n_extra)])
    p = np.concatenate([state.attitude_wxyz, state.omega_body_rad_s])
    f_fun, g_fun = prob.solver.get_function("nlp_f"), prob.solver.get_function("nlp_g")
    lbg, ubg = prob.lbg, prob.ubg

    def f(w: np.ndarray) -> float:
        return float(f_fun(w, p))

    def g(w: np.ndarray) -> np.ndarray:
        return np.asarray(g_fun(w, p)).ravel()

    def violation(w: np.ndarray) -> float:
        gw = g(w)
        box = np.maximum(prob.lbw - w, w - prob.ubw)
        return float(max(np.max(np.maximum(lbg - gw, gw - ubg)), np.max(box, initial=0.0)))

    t0 = time.perf_counter()
    sol = prob.solver(x0=w0, p=p, lbx=prob.lbw, ubx=prob.ubw, lbg=lbg, ubg=ubg)
    ipopt_s = time.perf_counter() - t0
    st = prob.solver.stats()
    w_ipopt = np.asarray(sol["x"]).ravel()

    # SLSQP: equalities and the two sides of every finite inequality bound as separate constraints
    eq = np.isfinite(lbg) & np.isfinite(ubg) & (lbg == ubg)
    lo = np.isfinite(lbg) & ~eq
    hi = np.isfinite(ubg) & ~eq
    cons = [{"type": "eq", "fun": lambda w: g(w)[eq] - lbg[eq]},
            {"type": "ineq", "fun": lambda w: np.concatenate([g(w)[lo] - lbg[lo], ubg[hi] - g(w)[hi]])}]
    bounds = list(zip(np.where(np.isfinite(prob.lbw), prob.lbw, None), np.where(np.isfinite(prob.ubw), prob.ubw, None),
                      strict=True))

    class _Cap(Exception):
        pass

    best = {"w": w0}
    t_start = time.perf_counter()

    def callback(w: np.ndarray) -> None:
        best["w"] = np.array(w)
        if time.perf_counter() - t_start > cap_s:
            raise _Cap

    capped = False
    t0 = time.perf_counter()
    try:
        res = minimize(f, w0, method="SLSQP", bounds=bounds, constraints=cons, callback=callback,
                       options={"maxiter": max_iter, "ftol": sc.solver.tol})
        w_slsqp, slsqp_status, slsqp_iter, slsqp_success = res.x, str(res.message), int(res.nit), bool(res.success)
    except _Cap:
        capped = True
        w_slsqp, slsqp_status, slsqp_iter, slsqp_success = best["w"], f"stopped at the {cap_s:g} s cap", -1, False
    slsqp_s = time.perf_counter() - t0
    return {
        "problem": {"variables": int(len(w0)), "constraints": int(len(lbg)), "scenario": "scenario_II"},
        "ipopt_exact": {"time_s": ipopt_s, "objective": float(sol["f"]), "max_violation": violation(w_ipopt),
                        "iterations": int(st["iter_count"]), "success": bool(st["success"]),
                        "status": str(st["return_status"])},
        "slsqp_finite_difference": {"time_s": slsqp_s, "objective": f(w_slsqp), "max_violation": violation(w_slsqp),
                                    "iterations": slsqp_iter, "success": slsqp_success, "status": slsqp_status,
                                    "capped": capped, "cap_s": cap_s},
        "time_ratio_slsqp_over_ipopt": slsqp_s / ipopt_s,
    }


def _grid_file(directory: Path, n_phases: int) -> Path:
    """A flat-spin grid of 2 × ``n_phases`` points for harness throughput (fake solver)."""
    path = directory / "bench_grid.toml"
    scenario = (SCENARIOS / "scenario_II.toml").as_posix()
    path.write_text(f'name = "bench"\nscenario = "{scenario}"\nkind = "flat_spin"\n'
                    '[[axes]]\nname = "spin_rate_deg_s"\nmin = 3.0\nmax = 4.0\ncount = 2\n'
                    f'[[axes]]\nname = "spin_phase_deg"\nmin = 0.0\nmax = 30.0\ncount = {n_phases}\n')
    return path


def build_section(n_phases: int, sleep_s: float) -> dict:
    """Points/hour of the build harness (fake solver sleeping ``sleep_s`` per point) at -j 1, -j 2, Dask."""
    from joblib.externals.loky import get_reusable_executor

    from lut.build import BuildOptions, run_build
    from lut.store import Table

    os.environ["PYTHONPATH"] = str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")
    os.environ["LUTGEN_FAKE_SLEEP_S"] = str(sleep_s)
    out: dict = {"fake_point_s": sleep_s}
    with tempfile.TemporaryDirectory() as tmp:
        grid = _grid_file(Path(tmp), n_phases)
        n = 2 * n_phases
        out["points"] = n

        def run(name: str, options: BuildOptions) -> None:
            get_reusable_executor().shutdown(wait=True, kill_workers=True)  # workers see the environment
            t0 = time.perf_counter()
            summary = run_build(grid, Path(tmp) / f"{name}.h5", options)
            wall = time.perf_counter() - t0
            out[name] = {"wall_s": wall, "points_per_hour": 3600 * n / wall, "feasible": summary.counts["feasible"]}

        run("loky_j1", BuildOptions(jobs=1, solver=FAKE_SOLVER, progress=False))
        run("loky_j2", BuildOptions(jobs=2, solver=FAKE_SOLVER, progress=False))
        try:
            import distributed

            with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                          dashboard_address=None) as cluster:
                run("dask_2_workers", BuildOptions(backend="dask", scheduler=cluster.scheduler_address,
                                                   solver=FAKE_SOLVER, progress=False))
        except ImportError:
            out["dask_2_workers"] = skipped("distributed is not installed (pip install -e .[dask])")
    os.environ.pop("LUTGEN_FAKE_SLEEP_S", None)
    j1, j2 = out["loky_j1"]["points_per_hour"], out["loky_j2"]["points_per_hour"]
    out["scaling_efficiency_j2"] = j2 / (2 * j1)
    if "points_per_hour" in out["dask_2_workers"]:
        out["scaling_efficiency_dask"] = out["dask_2_workers"]["points_per_hour"] / (2 * j1)
    # what the real planner implies: the golden table's per-point solve times plus the harness's own
    # per-point overhead measured above (process start, journal write); two cores count as twice one
    # because points are independent single-threaded solves (the continuation order can still idle a
    # worker while a layer waits for its parent, which this estimate ignores)
    golden = Table.open(GOLDEN)
    solve = golden.field("solve_time_s")
    solve = solve[np.isfinite(solve)]
    overhead = max(0.0, out["loky_j1"]["wall_s"] / n - sleep_s)
    per_point = float(np.mean(solve)) + overhead
    out["estimated_real"] = {"source": "tests/data/ci_golden.h5 solve_time_s", "mean_solve_s": float(np.mean(solve)),
                             "harness_overhead_per_point_s": overhead,
                             "points_per_hour_1_core": 3600 / per_point,
                             "points_per_hour_2_cores": 2 * 3600 / per_point}
    return out


def _in_grid_states(grid, n: int, seed: int) -> list:  # noqa: ANN001 - lut.grid.Grid
    """``n`` seeded states uniformly inside the grid's box (periodic axes over their covered span)."""
    rng = np.random.default_rng(seed)
    values = grid.axis_values
    coords = np.stack([rng.uniform(v.min(), v.max(), size=n) for v in values], axis=1)
    return [grid.state_at(c) for c in coords]


def query_section(table: Path, n_states: int, refine_budget_s: float | None, seed: int) -> dict:
    """Query latency and quality over seeded in-grid states; ``refine_budget_s`` None: no refine."""
    from lut.query import MIN_REFINE_S, TableQuery

    tq = TableQuery(table)
    states = _in_grid_states(tq.grid, n_states, seed)
    lookup, simulate, verify_s, refine, total = [], [], [], [], []
    interp_ok, final_ok, over_budget = 0, 0, 0
    for state in states:
        # interpolation alone: a budget too small for a refine to start
        res = tq.query(state, budget_s=MIN_REFINE_S / 2)
        lookup.append(res.latency_s["lookup_interpolate_s"])
        simulate.append(res.latency_s.get("simulate_s", float("nan")))
        verify_s.append(res.latency_s.get("verify_s", float("nan")))
        ok = bool(res.report.feasible)
        interp_ok += ok
        t_total = res.latency_s["total_s"]
        if not ok and refine_budget_s is not None:
            res = tq.query(state, budget_s=refine_budget_s)
            refine.append(res.latency_s.get("refine_s", 0.0))
            t_total += res.latency_s["total_s"]
            ok = bool(res.report.feasible)
            over_budget += res.latency_s["total_s"] > refine_budget_s
        final_ok += ok
        total.append(t_total)
    n = len(states)
    out = {"table": table.relative_to(ROOT).as_posix() if table.is_relative_to(ROOT) else table.name,
           "states": n, "seed": seed, "table_load_s": tq.load_time_s,
           "lookup_interpolate_ms": stats_p95([1e3 * x for x in lookup]),
           "simulate_s": stats_p95(simulate), "verify_s": stats_p95(verify_s),
           "fraction_feasible_interpolation": interp_ok / n}
    if refine_budget_s is None:
        out["refine_s"] = skipped("no refine in this mode")
        out["fraction_feasible_after_refine"] = skipped("no refine in this mode")
        out["queries_over_budget"] = skipped("no refine in this mode")
    else:
        out["refine_s"] = stats_p95(refine) if refine else skipped("every interpolated plan was feasible")
        out["refined_queries"] = len(refine)
        out["refine_budget_s"] = refine_budget_s
        out["fraction_feasible_after_refine"] = final_ok / n
        out["queries_over_budget"] = over_budget
    out["query_total_s"] = stats_p95(total)
    out["peak_memory_query_process_mib"] = _query_process_memory(table, states[0])
    return out


def _query_process_memory(table: Path, state) -> float:  # noqa: ANN001 - planner.target.TargetState
    """Peak resident memory (MiB) of one ``lutgen query`` CLI process, interpolation only (no refine)."""
    lutgen = Path(sys.executable).parent / "lutgen"
    att = ",".join(f"{x:.12f}" for x in state.attitude_wxyz)
    om = ",".join(f"{x:.12f}" for x in np.degrees(state.omega_body_rad_s))
    code = ("import resource, subprocess, sys; "
            "subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    with tempfile.TemporaryDirectory() as tmp:
        res = subprocess.run([sys.executable, "-c", code, str(lutgen), "query", str(table), "--attitude", att,
                              "--omega-deg-s", om, "--budget-s", "4", "--out", str(Path(tmp) / "plan.json")],
                             capture_output=True, text=True, check=True, cwd=ROOT)
    return int(res.stdout.strip().splitlines()[-1]) / 1024  # ru_maxrss is KiB on Linux


# ---- report -----------------------------------------------------------------------------------

def _fmt(entry: object, scale: float = 1.0, unit: str = "s") -> str:
    if isinstance(entry, dict) and "median" in entry:
        return f"{entry['median'] * scale:.4g} {unit} (min {entry['min'] * scale:.4g}, max {entry['max'] * scale:.4g})"
    if isinstance(entry, dict) and "skipped" in entry:
        return f"skipped: {entry['skipped']}"
    return str(entry)


def print_table(result: dict) -> None:
    m = result["machine"]
    print(f"lutgen bench ({m['mode']}{', trim' if m['trim'] else ''}) — {m['cpu_count']} CPUs, {m['platform']}")
    rows = []
    pr = result["primitives"]
    for key in ("forward_kinematics_casadi_us", "forward_kinematics_pinocchio_us", "momentum_map_and_jstar_casadi_us",
                "centroidal_map_pinocchio_us", "collision_sweep_us"):
        rows.append((f"primitive {key[:-3]}", _fmt(pr[key], unit="µs")))
    rows.append(("primitive verify one plan", _fmt(pr["verify_plan_s"])))
    for key, entry in result["planner"].items():
        if not isinstance(entry, dict):
            continue  # section_wall_s
        if "skipped" in entry:
            rows.append((f"plan {key}", _fmt(entry)))
            continue
        for phase in ("approach_s", "stabilization_s", "total_s"):
            rows.append((f"plan {key} {phase[:-2]}", _fmt(entry[phase])))
        rows.append((f"plan {key} feasible", str(entry["feasible"])))
    b = result["baseline"]
    if "skipped" in b:
        rows.append(("baseline", _fmt(b)))
    else:
        for key in ("ipopt_exact", "slsqp_finite_difference"):
            e = b[key]
            rows.append((f"approach NLP {key}", f"{e['time_s']:.3g} s, f = {e['objective']:.4g}, "
                                                 f"viol = {e['max_violation']:.2g}, {e['status']}"))
        rows.append(("approach NLP time ratio SLSQP/IPOPT", f"{b['time_ratio_slsqp_over_ipopt']:.3g}"))
    bu = result["build"]
    for key in ("loky_j1", "loky_j2", "dask_2_workers"):
        e = bu[key]
        rows.append((f"build {key}", f"{e['points_per_hour']:.4g} points/h" if "points_per_hour" in e else _fmt(e)))
    rows.append(("build scaling efficiency -j 2", f"{bu['scaling_efficiency_j2']:.3f}"))
    er = bu["estimated_real"]
    rows.append(("build real planner (golden)", f"{er['points_per_hour_1_core']:.3g} points/h/core, "
                                                f"{er['points_per_hour_2_cores']:.3g} points/h on 2 cores"))
    q = result["query"]
    rows.append((f"query lookup+interp ({q['states']} states)", _fmt(q["lookup_interpolate_ms"], unit="ms")))
    rows.append(("query simulate", _fmt(q["simulate_s"])))
    rows.append(("query verify", _fmt(q["verify_s"])))
    rows.append(("query refine", _fmt(q["refine_s"])))
    rows.append(("query feasible: interpolation", f"{q['fraction_feasible_interpolation']:.0%}"))
    after = q["fraction_feasible_after_refine"]
    rows.append(("query feasible: after refine", f"{after:.0%}" if isinstance(after, float) else _fmt(after)))
    rows.append(("query peak memory", f"{q['peak_memory_query_process_mib']:.0f} MiB"))
    width = max(len(r[0]) for r in rows)
    for name, value in rows:
        print(f"  {name:<{width}}  {value}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke run, ≤ 3 min: no whole plans, no refine")
    ap.add_argument("--trim", action="store_true", help="the smallest run that still fills every key (tests)")
    ap.add_argument("--out", default="out/bench.json", help="JSON output path (default out/bench.json)")
    ap.add_argument("--plan-runs", type=int, default=None,
                    help="whole plans per scenario and variant (full default 1: one plan takes minutes; "
                         "5 for the issue's median of 5)")
    ap.add_argument("--refine-budget-s", type=float, default=100.0, help="per-query budget when refining (s)")
    ap.add_argument("--table", default=None, help="table for the query section (default out/demo.h5 if built, "
                                                  "else the golden CI table)")
    ap.add_argument("--seed", type=int, default=7, help="seed of the random query states")
    args = ap.parse_args()
    full = not args.quick and not args.trim
    mode = "full" if full else "quick"
    t_start = time.perf_counter()
    result: dict = {"machine": machine(mode, args.trim)}

    def section(name: str, fn: Callable[[], dict]) -> None:
        t0 = time.perf_counter()
        print(f"bench: {name} ...", file=sys.stderr, flush=True)
        result[name] = fn()
        result[name]["section_wall_s"] = time.perf_counter() - t0

    repeats, min_time = (2, 0.05) if args.trim else (5, 0.2 if args.quick else 0.5)
    section("primitives", lambda: primitives(repeats, min_time))
    plan_runs = args.plan_runs if args.plan_runs is not None else (1 if full else 0)
    section("planner", lambda: planner_section(plan_runs, 150.0, ["scenario_I", "scenario_II"]))
    cap = 20.0 if args.trim else (60.0 if args.quick else 300.0)
    section("baseline", lambda: baseline(cap, 3 if args.trim else 500))
    section("build", lambda: build_section(2 if args.trim else 4, 0.2 if args.trim else 1.0))
    table = Path(args.table) if args.table else (DEMO_TABLE if full and DEMO_TABLE.is_file() else GOLDEN)
    n_states = 3 if args.trim else (10 if args.quick else 50)
    section("query", lambda: query_section(table, n_states, args.refine_budget_s if full else None, args.seed))
    result["wall_s"] = time.perf_counter() - t_start
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1))
    print_table(result)
    print(f"bench: wrote {out} in {result['wall_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
