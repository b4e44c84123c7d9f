"""scripts/bench.py --quick --trim runs end to end and its JSON carries every figure the issue asks for.

Structure only: the timings are the benchmark's business (never asserted here), but every measured
number must be finite and positive, and a part not run must say why.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

TIMING = {"median", "min", "max", "runs"}


def _is_timing(entry: dict) -> bool:
    return TIMING <= entry.keys() and all(math.isfinite(entry[k]) and entry[k] >= 0 for k in ("median", "min", "max"))


def _timing_or_skip(entry: dict) -> bool:
    return _is_timing(entry) or (isinstance(entry.get("skipped"), str) and entry["skipped"] != "")


@pytest.fixture(scope="module")
def bench(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("bench") / "bench.json"
    res = subprocess.run([sys.executable, str(ROOT / "scripts" / "bench.py"), "--quick", "--trim", "--out", str(out)],
                         capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "lutgen bench" in res.stdout and "query verify" in res.stdout
    return json.loads(out.read_text())


def test_machine_names_cpus_and_every_library(bench):
    m = bench["machine"]
    assert m["cpu_count"] >= 1 and m["mode"] == "quick" and m["trim"] is True
    for lib in ("numpy", "scipy", "pin", "casadi", "python-fcl", "h5py", "joblib", "distributed", "lutgen"):
        assert m["versions"][lib], lib


def test_primitives_sit_next_to_pinocchio(bench):
    p = bench["primitives"]
    for key in ("forward_kinematics_casadi_us", "forward_kinematics_pinocchio_us", "momentum_map_and_jstar_casadi_us",
                "centroidal_map_pinocchio_us", "collision_sweep_us", "verify_plan_s"):
        assert _is_timing(p[key]) and p[key]["median"] > 0, key
    assert p["collision_pairs"] == 29
    assert p["verify_samples"] > 1000  # a whole plan at ≤ 0.02 s: tens of seconds of motion


def test_planner_entries_exist_for_both_scenarios_and_variants(bench):
    for name in ("scenario_I", "scenario_II"):
        for variant in ("feasibility", "with_costs"):
            entry = bench["planner"][f"{name}_{variant}"]
            assert "skipped" in entry or all(_is_timing(entry[k]) for k in ("approach_s", "stabilization_s", "total_s"))


def test_baseline_reports_both_solvers_on_the_same_problem(bench):
    b = bench["baseline"]
    assert b["problem"]["variables"] > 0 and b["problem"]["constraints"] > 0
    for key in ("ipopt_exact", "slsqp_finite_difference"):
        e = b[key]
        assert e["time_s"] > 0 and math.isfinite(e["objective"]) and math.isfinite(e["max_violation"]), key
    assert b["time_ratio_slsqp_over_ipopt"] > 0


def test_build_throughput_for_loky_and_dask(bench):
    b = bench["build"]
    for key in ("loky_j1", "loky_j2", "dask_2_workers"):
        assert b[key]["points_per_hour"] > 0 and b[key]["feasible"] == b["points"], key
    assert 0 < b["scaling_efficiency_j2"] <= 1.5
    assert b["estimated_real"]["points_per_hour_1_core"] > 0


def test_query_latency_quality_and_memory(bench):
    q = bench["query"]
    assert q["states"] >= 3
    for key in ("lookup_interpolate_ms", "simulate_s", "verify_s", "query_total_s"):
        assert _is_timing(q[key]) and "p95" in q[key], key
    assert 0.0 <= q["fraction_feasible_interpolation"] <= 1.0
    for key in ("refine_s", "fraction_feasible_after_refine", "queries_over_budget"):
        assert key in q and (not isinstance(q[key], dict) or _timing_or_skip(q[key])), key
    assert q["peak_memory_query_process_mib"] > 50  # python + casadi + pinocchio cannot fit in less
