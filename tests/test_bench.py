"""``scripts/bench.py --quick --trim`` runs end to end and its JSON carries every figure of issue 6.

Structure only: the timings are the benchmark's business and never asserted here; but every measured
number must be finite and positive, and a part a mode does not measure must keep its keys and say why.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
LIBRARIES = ("numpy", "scipy", "pin", "casadi", "python-fcl", "h5py", "joblib", "distributed", "lutgen")
PLANNER_KEYS = ("approach_s", "tracking_s", "stabilization_s", "total_s", "planner_build_s", "ipopt_iterations",
                "feasible", "solver_status", "cost_weights")
REFINE_KEYS = ("refine_s", "query_with_refine_total_s", "fraction_feasible_after_refine", "refined_queries",
               "queries_over_budget", "budget_s")


def _reject_constant(name: str) -> None:
    raise ValueError(f"non-finite number {name} in the JSON")


def _bench(out: Path, *args: str) -> subprocess.CompletedProcess:
    """``scripts/bench.py --quick --trim --out OUT ARGS``; Dask's scratch space goes beside ``out``, not into
    the machine's /tmp."""
    env = dict(os.environ, DASK_TEMPORARY_DIRECTORY=str(out.parent / "dask-scratch"))
    return subprocess.run([sys.executable, "scripts/bench.py", "--quick", "--trim", "--out", str(out), *args],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def run_path(tmp_path_factory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("bench") / "bench.json"
    proc = _bench(out)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return out, proc.stdout


@pytest.fixture(scope="module")
def run(run_path) -> tuple[dict[str, Any], str]:
    return json.loads(run_path[0].read_text(), parse_constant=_reject_constant), run_path[1]


@pytest.fixture(scope="module")
def bench(run) -> dict[str, Any]:
    return run[0]


def _positive(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and value > 0


def _assert_timing(entry: Any, what: str, p95: bool = False) -> None:
    assert isinstance(entry, dict), what
    assert isinstance(entry.get("runs"), int) and entry["runs"] >= 1, what
    assert all(_positive(entry[k]) for k in ("median", "min", "max")), (what, entry)
    assert entry["min"] <= entry["median"] <= entry["max"], (what, entry)
    if p95:
        assert entry["min"] <= entry["p95"] <= entry["max"], (what, entry)


def _assert_skipped(entry: dict[str, Any], keys: tuple[str, ...], what: str) -> None:
    assert isinstance(entry.get("skipped"), str) and entry["skipped"].strip(), what
    assert all(key in entry for key in keys), (what, set(keys) - entry.keys())


def _walk_skips(node: Any, where: str = "") -> None:
    if isinstance(node, dict):
        if "skipped" in node:
            assert isinstance(node["skipped"], str) and node["skipped"].strip(), where
        for key, value in node.items():
            _walk_skips(value, f"{where}.{key}")
    elif isinstance(node, list):
        for i, value in enumerate(node):
            _walk_skips(value, f"{where}[{i}]")


def test_every_section_is_there_and_every_skip_says_why(run):
    bench, stdout = run
    assert list(bench) == ["machine", "primitives", "query", "build", "planner", "baseline", "wall_s"]
    _walk_skips(bench)
    for section in ("primitives", "query", "build", "planner", "baseline"):
        assert _positive(bench[section]["section_wall_s"]), section
    # the readable table names every section
    for title in ("lutgen bench", "primitives", "query", "build", "planner", "baseline", "wrote"):
        assert title in stdout, title


def test_machine_names_cpus_mode_and_every_library_version(bench):
    m = bench["machine"]
    assert isinstance(m["cpu_count"], int) and m["cpu_count"] >= 1
    assert m["platform"] and m["python"] and m["timestamp_utc"]
    assert m["mode"] == "quick" and m["trim"] is True
    for lib in LIBRARIES:
        assert isinstance(m["versions"].get(lib), str) and m["versions"][lib], lib


def test_primitives_sit_next_to_pinocchio(bench):
    p = bench["primitives"]
    for key in ("forward_kinematics_casadi_us", "forward_kinematics_pinocchio_us", "momentum_map_and_jstar_casadi_us",
                "centroidal_map_pinocchio_us", "collision_sweep_us", "collision_sweep_23_points_us",
                "collision_verify_1000_samples_s", "verify_plan_s"):
        _assert_timing(p[key], key)
    assert p["collision_pairs"] == 37
    assert p["collision_engines_max_difference_m"] <= 1e-6  # the NLPs' and verify's engines agree
    assert p["verify_plan"]["plan_samples"] > 1000  # a whole plan, not a fragment
    assert _positive(p["verify_plan_simulate_s"])


def test_query_latencies_quality_memory_and_skipped_refine(bench):
    q = bench["query"]
    assert q["states"] >= 1 and q["table"] == "tests/data/ci_golden.h5"
    for key in ("lookup_interpolate_ms", "simulate_s", "verify_s", "query_total_s"):
        _assert_timing(q[key], key, p95=True)
    assert 0.0 <= q["fraction_feasible_interpolation"] <= 1.0
    _assert_skipped(q["refine"], REFINE_KEYS, "refine")
    assert q["refine"]["refine_s"] is None and q["refine"]["fraction_feasible_after_refine"] is None
    assert q["peak_memory_query_process_mib"] > 50  # Python + CasADi + pinocchio cannot fit in less
    assert _positive(q["query_process_wall_s"]) and q["query_process_exit_code"] in (0, 2)


def test_build_throughput_for_loky_and_dask_and_the_real_estimate(bench):
    b = bench["build"]
    for key in ("loky_j1", "loky_j2", "dask_2_workers"):
        _assert_timing(b[key]["wall_s"], key)
        assert _positive(b[key]["points_per_hour"]) and b[key]["feasible"] == b["points"], key
    for key in ("scaling_efficiency_j2", "scaling_efficiency_dask", "ideal_speedup_j2"):
        assert _positive(b[key]), key
    est = b["estimated_real"]
    for key in ("points_per_hour_1_core", "points_per_hour_2_cores"):
        assert _positive(est[key]), key
    _assert_timing(est["solve_time_s"], "golden solve times")


def test_planner_keys_exist_for_both_scenarios_and_variants(bench):
    p = bench["planner"]
    for name in ("scenario_I", "scenario_II"):
        for variant in ("feasibility", "with_costs"):
            entry = p[name][variant]
            if "skipped" in entry:  # quick mode: whole plans take minutes
                _assert_skipped(entry, PLANNER_KEYS, f"{name} {variant}")
                continue
            for key in ("approach_s", "stabilization_s", "total_s"):
                _assert_timing(entry[key], f"{name} {variant} {key}")
    assert isinstance(p["compiled_functions"]["enabled"], bool)
    assert isinstance(p["compiled_functions"]["fallbacks"], list)


def test_baseline_reports_both_solvers_on_the_same_problem(bench):
    b = bench["baseline"]
    assert b["problem"]["variables"] > 0 and b["problem"]["constraints"] > 0
    for key in ("ipopt_exact", "slsqp_finite_difference"):
        e = b[key]
        assert _positive(e["time_s"]), key
        assert math.isfinite(e["objective"]) and math.isfinite(e["max_violation"]) and e["max_violation"] >= 0, key
        assert isinstance(e["success"], bool) and e["status"], key
    # a ratio only between converged solves (--trim gives SLSQP one iteration: it cannot have converged)
    assert b["ipopt_exact"]["success"] and b["ipopt_exact"]["iterations"] > 0, b["ipopt_exact"]
    assert b["time_ratio_slsqp_over_ipopt"] is None and "SLSQP did not converge" in b["not_comparable"]
    assert b["paper_costs"] == {"skipped": "--trim"}


def test_only_reruns_the_named_section_and_keeps_the_others(run_path, tmp_path):
    before = json.loads(run_path[0].read_text())
    out = tmp_path / "bench.json"
    out.write_text(run_path[0].read_text())
    proc = _bench(out, "--only", "primitives")
    assert proc.returncode == 0, proc.stderr[-4000:]
    after = json.loads(out.read_text())
    for section in ("query", "build", "planner", "baseline", "wall_s"):
        assert after[section] == before[section], section
    assert after["machine"]["sections_rerun"] == ["primitives"]
    assert after["primitives"]["section_wall_s"] != before["primitives"]["section_wall_s"]  # measured again
    bad = _bench(out, "--only", "primitivs")
    assert bad.returncode == 2 and "primitivs" in bad.stderr
