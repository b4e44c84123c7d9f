"""``scripts/bench.py --quick --trim`` runs end to end and its JSON carries every figure of issues 6 and 20.

Structure only: the timings are the benchmark's business and never asserted here; but every measured
number must be finite and positive, and a part a mode does not measure must keep its keys and say why.
The coverage section's pieces (envelope states, failure reasons, tables, bars) are checked on their own too.
"""

from __future__ import annotations

import gzip
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))  # the benchmark's sections are scripts, not a package

from bench_sections import carry, coverage, coverage_tables  # noqa: E402
from bench_sections.coverage_runs import CliRun, failure_reasons, run_record  # noqa: E402
from bench_sections.envelope import EnvelopeState, flat_spin_state, major_axis_body, tumble_state, wxyz  # noqa: E402
from bench_sections.failure_kinds import (  # noqa: E402
    EARLIEST_COLD_START_S,
    PROBLEM_BUILD_S,
    FailureKind,
    cut_by_the_budget,
    failure_kind,
    record_failure_kind,
)
from scipy.spatial.transform import Rotation  # noqa: E402

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
    assert list(bench) == ["machine", "primitives", "query", "build", "planner", "baseline", "coverage", "optimal",
                           "reach", "carry", "wall_s"]
    _walk_skips(bench)
    for section in ("primitives", "query", "build", "planner", "baseline", "coverage", "optimal", "reach", "carry"):
        assert _positive(bench[section]["section_wall_s"]), section
    # the readable table names every section
    for title in ("lutgen bench", "primitives", "query", "build", "planner", "baseline", "coverage", "optimal",
                  "reach", "carry", "wrote"):
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
                "collision_verify_1000_samples_s", "verify_plan_s", "approach_jacobian_ms",
                "stabilization_jacobian_ms"):
        _assert_timing(p[key], key)
    assert p["nlp_jacobian_shapes"]["approach"][0] > 1000  # every constraint row of the NLP, not a block
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
    for section in ("query", "build", "planner", "baseline", "coverage", "optimal", "wall_s"):
        assert after[section] == before[section], section
    assert after["machine"]["sections_rerun"] == ["primitives"]
    assert after["primitives"]["section_wall_s"] != before["primitives"]["section_wall_s"]  # measured again
    bad = _bench(out, "--only", "primitivs")
    assert bad.returncode == 2 and "primitivs" in bad.stderr


# ---- coverage (issue 20) ------------------------------------------------------------------------------------

KIND_NAMES = ("scenario_I_flat_spin", "scenario_II_flat_spin", "scenario_I_tumble", "scenario_II_tumble")
SUMMARY_KEYS = ("states", "feasible_on_time", "feasible_fraction", "wall_s", "reasons", "failures_by_first_reason",
                "failures_by_kind", "cut_by_the_budget", "over_budget", "killed", "runs")
RECORD_KEYS = ("command", "exit_code", "wall_s", "feasible_on_time", "reasons", "notes", "source", "violations",
               "solver", "start_delay_s", "free_axis_angle_deg", "refine_failure", "last_line")


def _assert_summary(entry: dict[str, Any], command: str, what: str) -> None:
    assert set(SUMMARY_KEYS) <= entry.keys(), what
    runs = entry["runs"]
    assert entry["states"] == len(runs) == 1, what
    _assert_timing(entry["wall_s"], what, p95=True)
    assert entry["feasible_on_time"] == sum(r["feasible_on_time"] for r in runs), what
    assert entry["feasible_fraction"] == entry["feasible_on_time"] / entry["states"], what
    tally: dict[str, int] = {}
    for r in runs:
        assert set(RECORD_KEYS) <= r.keys(), what
        assert r["command"].startswith(f"OMP_NUM_THREADS=1 lutgen {command} ") and "--attitude " in r["command"]
        assert r["exit_code"] in (0, 2, None), (what, r)  # 1 (bad input) or 64 (usage) would be a bug here
        assert r["feasible_on_time"] == (not r["reasons"]), (what, r)
        assert _positive(r["wall_s"]) and isinstance(r["notes"], list), what
        for reason in r["reasons"]:
            tally[reason["reason"]] = tally.get(reason["reason"], 0) + 1
    assert entry["reasons"] == tally, what
    assert sum(entry["failures_by_first_reason"].values()) == entry["states"] - entry["feasible_on_time"], what
    assert sum(entry["failures_by_kind"].values()) == entry["states"] - entry["feasible_on_time"], what
    assert set(entry["failures_by_kind"]) <= {k.value for k in FailureKind}, what
    assert entry["cut_by_the_budget"] == sum(any(x["reason"] == "budget ran out" for x in r["reasons"]) for r in runs)
    assert entry["killed"] == sum(r["exit_code"] is None for r in runs), what


def test_coverage_plans_queries_and_bars_keep_their_keys(bench):
    c = bench["coverage"]
    assert c["states_per_kind"] == 1 and c["budget_s"] == 2.0 and c["kill_after_s"] > c["budget_s"]
    assert isinstance(c["plan_budget_option"], bool) and c["jobs"] == 1
    assert c["queries"]["tables"] == ["tests/data/ci_golden.h5: scenario_II flat_spin"]
    for name in KIND_NAMES:
        if name == "scenario_II_flat_spin":  # --trim runs this kind only, and the golden table answers it
            _assert_summary(c["plans"][name], "plan configs/scenarios/scenario_II.toml", name)
            _assert_summary(c["queries"][name], "query tests/data/ci_golden.h5", name)
            assert c["queries"][name]["table"] == "tests/data/ci_golden.h5"
            continue
        _assert_skipped(c["plans"][name], SUMMARY_KEYS, name)
        _assert_skipped(c["queries"][name], SUMMARY_KEYS, name)
    expected_bars = {*(f"plan_feasible_{k}" for k in KIND_NAMES), *(f"plan_p95_wall_s_{k}" for k in KIND_NAMES),
                     "plans_over_budget", "query_feasible_all_kinds", "query_p95_wall_s_all_kinds"}
    assert set(c["bars"]) == expected_bars
    for name, bar in c["bars"].items():
        assert bar["enough_states"] is False, name  # 1 state per kind, the issue measures on 20
        measured = "scenario_II_flat_spin" in name or "all_kinds" in name or name == "plans_over_budget"
        assert (bar["value"] is not None) == measured and (bar["met"] is None) == (not measured), name
    assert c["bars"]["plan_feasible_scenario_II_flat_spin"]["bar"] == 0.90
    assert c["bars"]["plan_feasible_scenario_I_tumble"]["bar"] == 0.95


def test_major_axis_is_read_from_the_inertia():
    for name, axis in (("scenario_I", [0, 1, 0]), ("scenario_II", [0, 0, 1])):  # the paper: body y, body z
        inertia = coverage.load_scenario_named(name).target.inertia_body_kg_m2
        assert np.allclose(major_axis_body(inertia), axis, atol=1e-12), name
    # an inertia not in principal axes: the axis of its largest moment, whatever frame it is written in
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    found = major_axis_body(R @ np.diag([1.0, 5.0, 2.0]) @ R.T)
    assert np.isclose(abs(found @ R[:, 1]), 1.0, atol=1e-12)


def test_envelope_states_lie_in_the_envelope():
    rng = np.random.default_rng(3)
    axis = np.array([0.0, 0.0, 1.0])
    for _ in range(200):
        s = flat_spin_state(rng, axis)
        assert np.isclose(np.linalg.norm(s.attitude_wxyz), 1.0)
        w, x, y, z = s.attitude_wxyz
        world_axis = Rotation.from_quat([x, y, z, w]).apply(axis)
        assert abs(world_axis[1]) < 1e-12  # the spin axis lies in the orbital x–z plane
        assert np.allclose(np.cross(s.omega_body_deg_s, axis), 0.0)  # pure spin about the major axis
        assert 1.0 <= s.omega_body_deg_s @ axis <= 4.0
        t = tumble_state(rng)
        assert np.all(np.abs(t.omega_body_deg_s) <= 4.0) and np.isclose(np.linalg.norm(t.attitude_wxyz), 1.0)
    assert np.allclose(wxyz(Rotation.identity()), [1, 0, 0, 0])


def test_coverage_states_are_seeded_and_a_longer_run_starts_with_the_same_states():
    kind = coverage.KINDS[1]
    five, three = coverage.kind_states(kind, 5, 7), coverage.kind_states(kind, 3, 7)
    assert all(np.array_equal(a.attitude_wxyz, b.attitude_wxyz) for a, b in zip(three, five[:3], strict=True))
    other_kind = coverage.kind_states(coverage.KINDS[0], 3, 7)
    assert not np.allclose(other_kind[0].attitude_wxyz, three[0].attitude_wxyz)
    assert not np.allclose(coverage.kind_states(kind, 1, 8)[0].attitude_wxyz, three[0].attitude_wxyz)


def test_failure_reasons_name_the_failing_checks_of_a_stored_infeasible_plan():
    doc = json.loads(gzip.open(ROOT / "tests/data/truth/plan_scenario_II_tumble_10.json.gz", "rt").read())
    metrics = doc["metrics"]
    reasons = failure_reasons(CliRun(2, 80.0, "", "INFEASIBLE: …", metrics), budget_s=100.0)
    # independent reference: the plan's own violation lines start with the check's name
    assert [r["reason"] for r in reasons] == [v.split(":")[0] for v in metrics["violations"]]
    by_name = {r["reason"]: r for r in reasons}
    assert by_name["joint_position"]["phase"] == "stabilization" and by_name["collision"]["phase"] == "tracking"
    assert by_name["grasp_torque"]["margin"] < 0 and by_name["grasp_torque"]["limit"] == 10.0
    # the same plan, late: over budget as well
    late = failure_reasons(CliRun(2, 120.0, "", "", metrics), budget_s=100.0)
    assert [r["reason"] for r in late][-1] == "over budget" and len(late) == len(reasons) + 1
    # a plan its deadline ended: the budget is named first, then the checks where the solve stood
    cut = {**metrics, "notes": ["the plan's time budget ran out (Out_Of_Time after 9 stabilization iterations): …"],
           "solver": {**metrics["solver"], "stabilization": {**metrics["solver"]["stabilization"],
                                                            "status": "Out_Of_Time"}}}
    ran_out = failure_reasons(CliRun(2, 97.0, "", "", cut), budget_s=100.0)
    assert [r["reason"] for r in ran_out] == ["budget ran out", *(r["reason"] for r in reasons)]
    assert "stabilization Out_Of_Time" in ran_out[0]["detail"] and "time budget ran out" in ran_out[0]["detail"]
    record = run_record(["plan", "s.toml"], CliRun(2, 80.0, "note: made from another grasp\n", "", metrics), 100.0)
    assert record["notes"][0] == "made from another grasp" and metrics["notes"][0] in record["notes"]
    # a query prints its solve's notes, which its plan file keeps too: each once in the record
    solved = {**metrics, "notes": ["simulated from given parameters", "approach re-solved"]}
    queried = run_record(["query", "t.h5"], CliRun(0, 9.0, "note: the solve: approach re-solved\n", "", solved), 100.0)
    assert queried["notes"] == ["approach re-solved", "simulated from given parameters"]
    assert record["command"] == "OMP_NUM_THREADS=1 lutgen plan s.toml --out plan.json"


@pytest.mark.parametrize(("run", "expected"), [
    (CliRun(0, 30.0, "FEASIBLE\n", "", None), []),
    (CliRun(0, 100.5, "FEASIBLE\n", "", None), ["over budget"]),  # feasible, but too late to use
    (CliRun(None, 130.0, "", "built in 3.8 s; solving…", None), ["over budget"]),
    (CliRun(2, 6.5, "", "planning…\nINFEASIBLE (1.5 s): out of reach: no meeting time\nno plan written: …", None),
     ["out of reach"]),
    (CliRun(1, 2.0, "", "error: --attitude: not a unit quaternion", None), ["bad input"]),
    (CliRun(-11, 9.0, "", "", None), ["exit -11"]),
])
def test_failure_reasons_without_a_plan_file(run, expected):
    reasons = failure_reasons(run, budget_s=100.0)
    assert [r["reason"] for r in reasons] == expected
    assert all(r["detail"] for r in reasons)


def _stored_infeasible_plan() -> dict[str, Any]:
    """The metrics of a stored scenario II tumble plan verify refuses (a collision during its tracking, and braking)."""
    return json.loads(gzip.open(ROOT / "tests/data/truth/plan_scenario_II_tumble_10.json.gz", "rt").read())["metrics"]


def test_failure_kind_of_a_stored_plan_is_read_from_where_its_checks_fail():
    metrics = _stored_infeasible_plan()
    reasons = failure_reasons(CliRun(2, 80.0, "", "", metrics), budget_s=100.0)
    phases = {r["reason"]: r["phase"] for r in reasons}
    assert phases["collision"] == "tracking" and phases["grasp_torque"] == "stabilization"  # the premise
    assert failure_kind(reasons) is FailureKind.NO_GRASP_HELD and not cut_by_the_budget(reasons)
    # the same plan with only its checks from the grasp on failing: the grasp held, the braking did not
    braking = [r for r in reasons if r["phase"] == "stabilization"]
    assert braking and failure_kind(braking) is FailureKind.BRAKING
    # its deadline cut the braking short: still braking (where the solve stood), and counted as cut
    cut = [{"reason": "budget ran out", "detail": "stabilization Out_Of_Time"}, *braking]
    assert failure_kind(cut) is FailureKind.BRAKING and cut_by_the_budget(cut)
    # the same plan late: over budget, whatever else failed
    late = failure_reasons(CliRun(2, 120.0, "", "", metrics), budget_s=100.0)
    assert failure_kind(late) is FailureKind.OVER_BUDGET


def test_a_feasible_plan_answered_after_its_approach_began_is_a_late_start():
    """Verified feasible (no failed check), refused by the command as late: told apart from an unexplained failure;
    a plan both infeasible and late is its physics' failure first."""
    metrics = _stored_infeasible_plan()
    passed = {**metrics, "checks": {k: {**c, "passed": True} for k, c in metrics["checks"].items()}}
    answer = {"answer": {"answered_s": 10.9, "start_delay_s": 0.04, "late": True}}
    reasons = failure_reasons(CliRun(2, 11.2, "", "INFEASIBLE: late: …", passed, answer), budget_s=100.0)
    assert [r["reason"] for r in reasons] == ["late start"] and "10.9 s" in reasons[0]["detail"]
    assert failure_kind(reasons) is FailureKind.LATE_START
    both = failure_reasons(CliRun(2, 80.0, "", "", metrics, answer), budget_s=100.0)
    assert "late start" in [r["reason"] for r in both] and failure_kind(both) is FailureKind.NO_GRASP_HELD
    on_time = {"answer": {**answer["answer"], "late": False}}
    assert [r["reason"] for r in failure_reasons(CliRun(2, 11.2, "", "INFEASIBLE", passed, on_time), 100.0)] == \
        ["infeasible"]


def _check(name: str, phase: str | None) -> dict[str, Any]:
    return {"reason": name, "phase": phase, "value": 1.0, "limit": 0.5, "margin": -0.5, "where": ""}


@pytest.mark.parametrize(("reasons", "kind"), [
    ([], None),
    ([_check("grasp_torque", "stabilization"), _check("collision", "stabilization")], FailureKind.BRAKING),
    # a grasp missed at its instant is not the braking's, even when the braking fails too
    ([_check("grasp_torque", "stabilization"), _check("grasp_position", "grasp")], FailureKind.NO_GRASP_HELD),
    ([_check("collision", "approach")], FailureKind.NO_GRASP_HELD),
    ([_check("joint_velocity", None)], FailureKind.UNEXPLAINED),  # no phase: nothing says where
    ([_check("grasp_torque", "stabilization"), _check("momentum_chaser", None)], FailureKind.UNEXPLAINED),
    ([{"reason": "infeasible", "detail": "INFEASIBLE"}], FailureKind.UNEXPLAINED),
    ([{"reason": "budget ran out", "detail": "…"}], FailureKind.UNEXPLAINED),
    ([{"reason": "over budget", "detail": "130 s"}], FailureKind.OVER_BUDGET),  # feasible, but late
])
def test_failure_kind_of_given_reasons(reasons, kind):
    assert failure_kind(reasons) is kind


def test_the_earliest_cold_start_is_the_planners_own_floor_after_the_problems_build(monkeypatch):
    from types import SimpleNamespace

    import planner.deadline as deadline

    monkeypatch.setattr(deadline, "time", SimpleNamespace(monotonic=lambda: 100.0 + PROBLEM_BUILD_S))  # built
    observed = deadline.Deadline.after(100.0).observed(100.0)
    assert observed.earliest_start_s() == EARLIEST_COLD_START_S == 7.0


@pytest.mark.parametrize(("windows", "kind"), [
    ([[0.0, 6.0]], FailureKind.ONLY_TOO_EARLY),  # the scan's last reached start delay 6 s: before 7 s
    ([[0.0, 0.0]], FailureKind.ONLY_TOO_EARLY),
    ([[0.0, 2.0], [4.0, 6.0]], FailureKind.ONLY_TOO_EARLY),
    ([[0.0, EARLIEST_COLD_START_S]], FailureKind.NO_GRASP_HELD),  # a start a cold plan can take: the plan's failure
    ([[0.0, 2.0], [40.0, 60.0]], FailureKind.NO_GRASP_HELD),  # reachable later too
    ([], FailureKind.NO_GRASP_HELD),  # no window known to be reached: what the plan failed
    (None, FailureKind.NO_GRASP_HELD),  # not known (a query's record)
])
def test_a_state_reachable_only_before_a_cold_plan_can_start_fails_for_that(windows, kind):
    no_grasp = [_check("grasp_position", "grasp"), _check("collision", "approach")]
    assert failure_kind(no_grasp, None, windows) is kind
    assert record_failure_kind({"reasons": no_grasp, "reach_windows_s": windows}) is kind


def test_reachable_only_too_early_comes_after_what_says_more():
    early = [[0.0, 2.0]]
    assert failure_kind([{"reason": "over budget", "detail": "130 s"}], None, early) is FailureKind.OVER_BUDGET
    assert failure_kind([{"reason": "out of reach", "detail": "…"}], None, early) is FailureKind.OUT_OF_REACH
    assert failure_kind([{"reason": "exit 70", "detail": "…"}], None, early) is FailureKind.BUG
    braking = [_check("grasp_torque", "stabilization")]
    assert failure_kind(braking, None, early) is FailureKind.ONLY_TOO_EARLY
    assert failure_kind([], None, early) is None  # feasible: no failure


def test_a_query_out_of_reach_is_out_of_reach_whatever_its_table_plan_fails():
    table_plan = [_check("grasp_position", "grasp"), _check("grasp_torque", "stabilization")]
    assert failure_kind(table_plan) is FailureKind.NO_GRASP_HELD  # the premise: the table's plan read alone
    assert failure_kind(table_plan, "out of reach: no meeting time of the window") is FailureKind.OUT_OF_REACH
    assert failure_kind(table_plan, "killed at its time limit") is FailureKind.NO_GRASP_HELD
    assert failure_kind([], "out of reach: …") is None  # a feasible answer is not a failure
    assert failure_kind(table_plan, "out of reach (proven): at every start delay …") is FailureKind.OUT_OF_REACH_PROVEN
    assert failure_kind(table_plan, "reachable only too early: the scan …") is FailureKind.ONLY_TOO_EARLY


@pytest.mark.parametrize(("run", "kind"), [
    (CliRun(0, 30.0, "FEASIBLE\n", "", None), None),
    (CliRun(None, 130.0, "", "built in 3.8 s; solving…", None), FailureKind.OVER_BUDGET),
    (CliRun(2, 6.5, "", "INFEASIBLE (1.5 s): out of reach: no meeting time", None), FailureKind.OUT_OF_REACH),
    (CliRun(2, 0.9, "", "INFEASIBLE (0.1 s): out of reach (proven): at every start delay", None),
     FailureKind.OUT_OF_REACH_PROVEN),
    (CliRun(2, 9.0, "", "INFEASIBLE (9.0 s): no plan: the solve gave none", None), FailureKind.NO_PLAN),
    (CliRun(2, 3.8, "", "INFEASIBLE (3.8 s): reachable only too early: the scan of the start-delay window [0, 90] s "
                        "reaches the grasp only at start delays 0–6 s", None), FailureKind.ONLY_TOO_EARLY),
    (CliRun(1, 2.0, "", "error: --attitude: not a unit quaternion", None), FailureKind.BUG),
    (CliRun(70, 2.0, "", "internal error: …", None), FailureKind.BUG),
    (CliRun(-11, 9.0, "", "", None), FailureKind.BUG),
])
def test_failure_kind_of_a_run_without_a_plan_file(run, kind):
    assert failure_kind(failure_reasons(run, budget_s=100.0)) is kind


def test_a_querys_latency_line_is_read_stage_by_stage():
    from bench_sections.coverage_runs import query_latency_s

    line = ("source interpolated (corners [3]); table load 1.03 s; lookup_interpolate 0.9 ms, simulate 547.1 ms, "
            "verify 267.2 ms, repair 0.0 ms, corners 3555.6 ms, refine 85173.1 ms, total 91335.9 ms")
    assert query_latency_s(line) == pytest.approx({"table_load": 1.03, "lookup_interpolate": 0.0009, "simulate": 0.5471,
                                                   "verify": 0.2672, "repair": 0.0, "corners": 3.5556,
                                                   "refine": 85.1731, "total": 91.3359})


def test_summary_tallies_reasons_and_bars_judge_them():
    def record(ok: bool, wall: float, *reasons: str) -> dict[str, Any]:
        return {"feasible_on_time": ok, "wall_s": wall, "exit_code": 0 if ok else 2,
                "reasons": [{"reason": r} for r in reasons]}

    runs = [record(True, 10.0), record(False, 50.0, "collision", "grasp_torque"), record(False, 70.0, "collision")]
    s = coverage.summary(runs)
    assert s["feasible_on_time"] == 1 and s["feasible_fraction"] == 1 / 3 and s["killed"] == 0
    assert s["reasons"] == {"collision": 2, "grasp_torque": 1} and s["wall_s"]["max"] == 70.0
    assert s["failures_by_first_reason"] == {"collision": 2}
    assert s["failures_by_kind"] == {"unexplained": 2} and s["cut_by_the_budget"] == 0  # these reasons name no phase
    phased = [record(False, 50.0, "collision"), record(False, 96.0, "budget ran out", "grasp_torque"),
              record(False, 1.4, "out of reach")]
    phased[0]["reasons"][0]["phase"] = "tracking"
    phased[1]["reasons"][1]["phase"] = "stabilization"
    p = coverage.summary(phased)
    assert p["failures_by_kind"] == {"no grasp held": 1, "braking": 1, "out of reach": 1}
    assert p["cut_by_the_budget"] == 1
    plans = {k.name: coverage.summary([record(True, 10.0)] * 20) for k in coverage.KINDS}
    late = [record(False, 101.0, "over budget")] * 2
    plans["scenario_II_tumble"] = coverage.summary([record(True, 10.0)] * 18 + late)
    queries = {k.name: coverage.skipped("no table", SUMMARY_KEYS) for k in coverage.KINDS}
    b = coverage.bars(plans, queries, 20)
    assert b["plan_feasible_scenario_I_tumble"]["met"] is True
    assert b["plan_feasible_scenario_II_tumble"]["value"] == 0.9 and b["plan_feasible_scenario_II_tumble"]["met"]
    assert b["plan_p95_wall_s_scenario_II_tumble"]["met"] is False  # p95 of 18 × 10 s and 2 × 101 s
    assert b["plans_over_budget"]["value"] == 2 and b["plans_over_budget"]["met"] is False
    assert b["query_feasible_all_kinds"]["met"] is None and b["query_feasible_all_kinds"]["enough_states"] is False


def test_the_reach_edge_counts_the_failures_nearer_the_reach_than_every_feasible_plan():
    def record(ok: bool, slack_m: float) -> dict[str, Any]:
        return {"feasible_on_time": ok, "wall_s": 1.0, "exit_code": 0 if ok else 2, "reach_slack_m": slack_m,
                "reasons": [] if ok else [{"reason": "collision", "phase": "approach"}]}

    runs = [record(True, -0.5), record(True, -0.3), record(False, -0.1), record(False, -0.4), record(False, 0.2),
            record(False, -0.3)]  # as near as the nearest feasible plan: not nearer
    assert coverage.summary(runs)["reach_edge"] == {"feasible_nearest_m": -0.3, "failures": 4,
                                                    "failures_nearer_the_edge": 2}
    assert coverage.reach_edge([record(False, -0.9)])["failures_nearer_the_edge"] == 1  # no feasible plan to compare
    assert coverage.reach_edge([record(True, -1.0)])["failures"] == 0
    no_slack = [{k: v for k, v in r.items() if k != "reach_slack_m"} for r in runs]
    assert coverage.summary(no_slack)["reach_edge"] is None


def test_a_coverage_states_slack_is_its_reach_proofs_and_the_outcomes_are_drawn_against_it(tmp_path):
    """Seed 8's third scenario I flat spin is proven out of reach (the reach section's test): its slack is positive,
    a state planned feasible elsewhere in the envelope negative; the figure is a PNG with one row per kind."""
    from bench_sections.reach_figure import draw_outcomes_by_reach

    states = coverage.kind_states(coverage.KINDS[0], 3, 8)
    slacks = coverage.reach_slacks(states, "scenario_I")
    assert slacks[2] > 0.5 and all(np.isfinite(slacks))
    default = coverage.reach_slacks([EnvelopeState(np.array([1.0, 0, 0, 0]), np.array([0, 4.0, 0]))], "scenario_I")
    assert default[0] < 0  # scenario I's default state, which every plan test plans feasible
    runs = coverage.with_slacks([{"feasible_on_time": i != 2, "reasons": [] if i != 2 else [
        {"reason": "out of reach (proven)"}]} for i in range(3)], slacks)
    figure = draw_outcomes_by_reach({"scenario_I_flat_spin": runs}, tmp_path, "8")
    assert figure == tmp_path / "coverage_reach.png" and figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_failures_reach_windows_are_the_scans_reached_meeting_times_and_are_drawn_against_its_answer(tmp_path):
    """Seed 8's third scenario I flat spin is proven out of reach: no window; scenario I's default state, planned
    feasible by every plan test, is reached in disjoint intervals inside the start-delay window, on the scan's 2 s
    grid; only failures get windows, and the figure draws the failures that have any (none: no figure)."""
    from bench_sections.failure_kinds import offline_start_s
    from bench_sections.reach_windows import draw_failure_windows, reach_windows_s, with_windows

    from planner.phases.approach import approach_spline

    sc = coverage.load_scenario_named("scenario_I")
    proven = coverage.kind_states(coverage.KINDS[0], 3, 8)[2]
    assert reach_windows_s(sc, approach_spline(sc), proven) == []
    default = EnvelopeState(np.array([1.0, 0, 0, 0]), np.array([0, 4.0, 0]))
    windows = reach_windows_s(sc, approach_spline(sc), default)
    assert windows and all(0.0 <= a <= b <= 90.0 and a % 2.0 == 0 and b % 2.0 == 0 for a, b in windows)
    gaps = [later[0] - earlier[1] for earlier, later in zip(windows[:-1], windows[1:], strict=True)]
    assert all(gap > 2.0 for gap in gaps)  # disjoint, not touching
    braking = {"feasible_on_time": False, "wall_s": 30.0, "start_delay_s": 40.0, "reasons": [
        {"reason": "grasp_torque", "phase": "stabilization", "value": 12.0, "limit": 10.0, "margin": -2.0}]}
    held_early = {**braking, "offline": {"exit_code": 0, "wall_s": 6.0, "start_delay_s": 0.07}}
    runs = with_windows([{"feasible_on_time": True, "reasons": []}, braking, held_early], [default] * 3, "scenario_I")
    assert "reach_windows_s" not in runs[0] and runs[1]["reach_windows_s"] == windows
    assert [offline_start_s(r.get("offline")) for r in runs] == [None, None, 0.07]
    assert offline_start_s({"exit_code": 2, "wall_s": 95.0, "start_delay_s": 3.0}) is None
    assert offline_start_s({"exit_code": None, "wall_s": 130.0, "start_delay_s": None}) is None  # killed
    figure = draw_failure_windows({"scenario_I_flat_spin": runs}, tmp_path, "8")
    assert figure == tmp_path / "coverage_windows.png" and figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    out_of_reach = with_windows([{"feasible_on_time": False, "reasons": [{"reason": "out of reach (proven)"}]}],
                                [proven], "scenario_I")
    assert draw_failure_windows({"scenario_I_flat_spin": out_of_reach}, tmp_path / "none", "8") is None


def test_queries_only_runs_no_plan_and_kinds_narrow_the_section(monkeypatch):
    import bench
    from bench_sections.common import settings_for

    commands: list[list[str]] = []

    def fake_run_all(jobs, settings):
        commands.extend(jobs)
        return [{"feasible_on_time": True, "wall_s": 1.0, "exit_code": 0, "reasons": []} for _ in jobs]

    monkeypatch.setattr(coverage, "run_all", fake_run_all)
    args = bench.parse_args(["--coverage-queries-only", "--coverage-kinds", "scenario_II_flat_spin",
                             "--coverage-states", "2", "--coverage-tables", str(ROOT / "tests" / "data")])
    c = coverage.coverage(settings_for(False, False, 7, None, 60.0, False, 100.0, bench.coverage_settings_of(args)))
    assert [cmd[0] for cmd in commands] == ["query", "query"]  # the golden table answers scenario II's flat spins
    assert c["queries"]["scenario_II_flat_spin"]["feasible_on_time"] == 2
    assert c["plans"]["scenario_II_flat_spin"]["skipped"] == "--coverage-queries-only"
    assert c["plans"]["scenario_I_tumble"]["skipped"].startswith("only scenario_II_flat_spin")  # not asked for
    with pytest.raises(SystemExit):
        bench.parse_args(["--coverage-kinds", "scenario_III_flat_spin"])


def test_the_coverage_budget_is_each_commands_budget_and_its_kill_time(monkeypatch):
    """``--coverage-budget-s S`` gives every plan and query the section runs ``--budget-s S`` and kills it S + the
    margin after its start; without it, issue 20's 100 s."""
    import bench
    from bench_sections.common import COVERAGE_BUDGET_S, settings_for

    seen: list[tuple[list[str], float]] = []
    monkeypatch.setattr(coverage, "run_cli", lambda args, kill_after_s: seen.append((args, kill_after_s)) or
                        CliRun(2, 1.0, "INFEASIBLE (1.0 s): out of reach: stand-in\n", "", None))
    base = ["--coverage-kinds", "scenario_II_flat_spin", "--coverage-states", "2", "--coverage-tables",
            str(ROOT / "tests" / "data")]
    for extra, budget in (([], COVERAGE_BUDGET_S), (["--coverage-budget-s", "60"], 60.0)):
        seen.clear()
        cov = bench.coverage_settings_of(bench.parse_args(base + extra))
        coverage.coverage(settings_for(False, False, 7, None, 60.0, False, 100.0, cov))
        assert sorted(args[0] for args, _ in seen) == ["plan", "plan", "query", "query"]
        assert all(args[args.index("--budget-s") + 1] == f"{budget:g}" and kill_after_s == budget + cov.kill_margin_s
                   for args, kill_after_s in seen)
    with pytest.raises(SystemExit):
        bench.parse_args(["--coverage-budget-s", "0"])


def test_a_variant_plans_the_same_states_with_its_own_scenario_files(monkeypatch):
    import bench
    from bench_sections.common import settings_for

    commands: list[list[str]] = []

    def fake_run_all(jobs, settings):
        commands.extend(jobs)
        return [{"feasible_on_time": False, "wall_s": 1.0, "exit_code": 2, "reasons": [{"reason": "out of reach"}]}
                for _ in jobs]

    monkeypatch.setattr(coverage, "run_all", fake_run_all)
    base = ["--coverage-kinds", "scenario_I_tumble,scenario_II_flat_spin", "--coverage-states", "2",
            "--coverage-tables", str(ROOT / "tests" / "data")]
    runs = {}
    for variant in ([], ["--coverage-variant", "wide"]):
        commands.clear()
        args = bench.parse_args(base + variant)
        runs[bool(variant)] = (coverage.coverage(settings_for(False, False, 7, None, 60.0, False, 100.0,
                                                               bench.coverage_settings_of(args))), list(commands))
    (bundled, bundled_cmds), (wide, wide_cmds) = runs[False], runs[True]
    # in the order of KINDS: scenario II's flat spins, then scenario I's tumbles
    assert [c[1] for c in wide_cmds if c[0] == "plan"] == ["configs/scenarios/scenario_II_wide.toml"] * 2 + [
        "configs/scenarios/scenario_I_wide.toml"] * 2
    assert [c[2:] for c in wide_cmds] == [c[2:] for c in bundled_cmds if c[0] == "plan"]  # the same seeded states
    assert wide["variant"] == "wide" and bundled["variant"] is None
    # the golden table answers the bundled scenario II, not its variant: no query with the variant
    assert wide["queries"]["scenario_II_flat_spin"]["skipped"].startswith("no table")
    assert any(c[0] == "query" for c in bundled_cmds)
    with pytest.raises(SystemExit):
        bench.parse_args(["--coverage-variant", "energyy"])  # scenario_I_energyy.toml does not exist


def test_tables_are_matched_by_scenario_and_grid_kind(tmp_path, monkeypatch):
    found, lines = coverage_tables.find_tables(ROOT / "tests" / "data", [(k.name, k.scenario, k.motion)
                                                                         for k in coverage.KINDS])
    assert found == {"scenario_II_flat_spin": ROOT / "tests" / "data" / "ci_golden.h5"}
    assert lines == ["tests/data/ci_golden.h5: scenario_II flat_spin"]
    (tmp_path / "a_tumble.h5").write_bytes(b"")
    (tmp_path / "b_broken.h5").write_bytes(b"not hdf5")
    real = coverage_tables.table_identity
    monkeypatch.setattr(coverage_tables, "table_identity",
                        lambda p: ("scenario_I", "tumble") if p.name == "a_tumble.h5" else real(p))
    found, lines = coverage_tables.find_tables(tmp_path, [(k.name, k.scenario, k.motion) for k in coverage.KINDS])
    # a flat spin is a tumble: scenario I's tumble table answers both its kinds; scenario II has none
    assert found == {"scenario_I_flat_spin": tmp_path / "a_tumble.h5", "scenario_I_tumble": tmp_path / "a_tumble.h5"}
    assert lines[0].endswith("a_tumble.h5: scenario_I tumble") and "refused" in lines[1]
    assert coverage_tables.find_tables(tmp_path / "absent", []) == ({}, [])


def test_reach_counts_each_what_if_over_the_coverage_states(bench):
    """The reach section scans the coverage section's states (the same kinds and count) under every what-if, and each
    count is the length of its list of state indices."""
    r = bench["reach"]
    assert r["what_ifs"][0] == "scenario" and len(r["what_ifs"]) == 4
    kinds = [k for k in r if k.startswith("scenario_")]
    assert kinds == list(bench["coverage"]["plans"].keys() & set(kinds)) and kinds
    for kind in kinds:
        for name in r["what_ifs"]:
            e = r[kind][name]
            assert e["states"] == r["states_per_kind"] and e["out_of_reach"] == len(e["indices"])
            assert all(0 <= i < e["states"] for i in e["indices"])
            # a state the proof settles is one the scan reaches no meeting time of; its slack is the proof's
            assert set(e["proven_indices"]) <= set(e["indices"]) and e["proven"] == len(e["proven_indices"])
            proven = [slack > 0 for slack in e["slack_m"]]
            assert proven == [i in e["proven_indices"] for i in e["indices"]]


def test_the_reach_section_tells_the_proven_states_apart_and_draws_them(tmp_path):
    """Seed 8's first three scenario I flat spins: state 2's grasp stays beyond the arm's reach (proven), and the
    figure draws each state out of reach at the scenario's settings."""
    from dataclasses import replace

    from bench_sections.common import coverage_settings, load_scenario_named, settings_for
    from bench_sections.reach import reach

    cov = coverage_settings(False, False, 3, 1, None, ("scenario_I_flat_spin",))
    settings = replace(settings_for(True, False, 8, None, 300.0, False, 100.0, cov), reach_plot=tmp_path / "fig")
    r = reach(settings)
    e = r["scenario_I_flat_spin"]["scenario"]
    assert e["indices"] == [2] and e["proven_indices"] == [2] and e["slack_m"][0] > 0.5
    # how far the chaser would have to wait: the proof's, beyond the ±1 m box (every offset of norm ≤ 1 m lies in it)
    from planner.phases.reach_proof import reach_proof

    state = coverage.kind_states(coverage.KINDS[0], 3, 8)[2].target_state()
    least = reach_proof(load_scenario_named("scenario_I"), state).least_offset_m
    assert e["proven_least_offset_m"] == [least] and least > 1.0
    figure = tmp_path / "fig" / "reach_slack.png"
    assert r["figure"] == "reach_slack.png"  # a folder outside the repository: no machine path in the JSON
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_reach_digest_says_how_far_the_chaser_would_have_to_wait():
    from bench_sections.report import _reach

    entry = {"out_of_reach": 3, "states": 20, "proven": 3, "proven_least_offset_m": [2.004, 1.138, None]}
    rows = dict(_reach({"states_per_kind": 20, "scenario_I_flat_spin": {"scenario": entry}})[1])
    assert rows["scenario_I_flat_spin scenario"] == (
        "3/20 out of reach, 3 of them proven; the chaser would have to wait at least 1.14–2.00 m from its station, 1 "
        "within reach at no base offset")
    for never in (None, math.inf):  # the section's inf, and the null its JSON holds
        only_never = {**entry, "proven": 1, "proven_least_offset_m": [never]}
        rows = dict(_reach({"states_per_kind": 20, "k": {"scenario": only_never}})[1])
        assert rows["k scenario"].endswith("1 of them proven; 1 within reach at no base offset")
    none_proven = {**entry, "proven": 0, "proven_least_offset_m": []}
    assert dict(_reach({"states_per_kind": 20, "k": {"scenario": none_proven}})[1])["k scenario"].endswith("proven")


def test_the_reach_what_if_of_a_2_m_box_is_the_wide_variants_box():
    from bench_sections.common import load_scenario_named
    from bench_sections.reach import WHAT_IFS

    for name in ("scenario_I", "scenario_II"):
        widened = WHAT_IFS["base_offset_x_-2_2_z_-2_2"](load_scenario_named(name))
        assert widened.base_offset_bounds_m == load_scenario_named(f"{name}_wide").base_offset_bounds_m


def test_carry_measures_every_displacement_of_the_coverage_kinds(bench):
    """Trim: the coverage section's one kind and state, planned within its 2 s budget (no feasible plan), so every
    displacement is there with no plan carried."""
    r = bench["carry"]
    kinds = [k for k in r if k.startswith("scenario_")]
    assert kinds == ["scenario_II_flat_spin"] and r["states_per_kind"] == 1
    entry = r["scenario_II_flat_spin"]
    assert entry["feasible_plans"] == 0
    assert entry["largest_spin_axis_deg"] is None and entry["largest_rate_deg_s"] is None
    assert "largest_attitude_deg" not in entry  # a flat spin is carried along its family
    assert len(entry["steps"]) == len(r["spin_axis_steps_deg"]) + len(r["spin_rate_steps_deg_s"])
    assert all(d["plans"] == 0 and d["as_is"] is None for d in entry["steps"].values())


def test_a_displaced_state_is_that_far_in_attitude_and_rate():
    from planner.model.target_state import TargetState

    state = TargetState(np.array([0.5, 0.5, -0.5, 0.5]), np.radians([1.0, -2.0, 3.0]))
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    moved = carry.displaced(state, 20.0, 0.5, axis)
    w, x, y, z = state.attitude_wxyz
    W, X, Y, Z = moved.attitude_wxyz
    relative = Rotation.from_quat([x, y, z, w]).inv() * Rotation.from_quat([X, Y, Z, W])
    np.testing.assert_allclose(relative.as_rotvec(), np.radians(20.0) * axis, atol=1e-12)  # body frame, on the right
    np.testing.assert_allclose(moved.omega_body_rad_s - state.omega_body_rad_s, np.radians(0.5) * axis, atol=1e-15)


def test_no_displacement_is_the_state_itself_and_a_half_turn_is_exact():
    from planner.model.target_state import TargetState

    state = TargetState(np.array([0.5, 0.5, -0.5, 0.5]), np.radians([1.0, -2.0, 3.0]))
    axis = np.array([0.0, 0.0, 1.0])  # a body axis exactly
    same = carry.displaced(state, 0.0, 0.0, axis)
    np.testing.assert_allclose(same.attitude_wxyz, state.attitude_wxyz, atol=1e-15)
    np.testing.assert_array_equal(same.omega_body_rad_s, state.omega_body_rad_s)
    w, x, y, z = state.attitude_wxyz
    W, X, Y, Z = carry.displaced(state, 180.0, 0.0, axis).attitude_wxyz
    relative = Rotation.from_quat([x, y, z, w]).inv() * Rotation.from_quat([X, Y, Z, W])
    assert abs(relative.magnitude() - np.pi) < 1e-12
    np.testing.assert_allclose(np.abs(relative.as_rotvec()), [0.0, 0.0, np.pi], atol=1e-12)  # ±π about z: one turn


def test_the_largest_carry_stops_at_the_first_displacement_below_the_bar():
    steps = {"attitude_deg 2.5": {"repaired": 1.0}, "attitude_deg 5": {"repaired": 0.9},
             "attitude_deg 10": {"repaired": 0.5}, "attitude_deg 20": {"repaired": 0.95},
             "rate_deg_s 0.25": {"repaired": 0.8}, "rate_deg_s 0.5": {"repaired": 1.0}}
    entry = {"steps": steps}
    assert carry.largest_carry(entry, "attitude_deg") == 5.0  # 20° passing again does not count: 10° did not
    assert carry.largest_carry(entry, "rate_deg_s") is None
    assert carry.largest_carry({"steps": {"rate_deg_s 0.25": {"repaired": None}}}, "rate_deg_s") is None


@pytest.mark.parametrize(("turn_deg", "rate_deg_s"), [(30.0, 0.0), (-45.0, 0.0), (180.0, 0.0), (0.0, 0.5),
                                                      (0.0, -1.0), (0.0, 0.0)])
def test_a_flat_spin_displaced_along_its_family_is_that_far_in_spin_axis_and_rate(turn_deg, rate_deg_s):
    """Read back by the grid's own coordinates (rate, spin axis, phase): the other coordinates unchanged."""
    from lut.table.grid import Grid
    from lut.table.grid_config import load_grid
    from planner.config.scenario import load_scenario

    config = load_grid(ROOT / "configs/grids/envelope_flat_spin_II.toml")
    sc = load_scenario(config.scenario_path)
    grid = Grid(config, sc.target.inertia_body_kg_m2, sc.target_state.as_state())
    state = grid.state_at([2.7, 110.0, 250.0])
    moved = carry.flat_spin_displaced(state, turn_deg, rate_deg_s)
    before, after = grid.coordinates_of_state(state), grid.coordinates_of_state(moved)  # refuses a non-flat spin
    delta = after - before
    delta[1:] = (delta[1:] + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(delta, [rate_deg_s, (turn_deg + 180.0) % 360.0 - 180.0, 0.0], atol=1e-9)


@pytest.mark.parametrize(("rate_from", "rate_to", "tau"), [(3.0, 3.5, 40.0), (3.0, 2.0, 40.0), (1.2, 1.0, 40.0),
                                                     (2.5, 2.5, 40.0),
                                                     (3.0, 4.0, 2.0)])  # shifted before 0 s: one turn (90 s) later
def test_a_flat_spin_plan_carried_to_another_rate_meets_the_target_at_the_same_spin_angle(rate_from, rate_to, tau):
    from planner.config.scenario import load_scenario
    from planner.plan_parameters import ApproachParameters, PlanParameters

    sc = load_scenario(ROOT / "configs/scenarios/scenario_II.toml")
    plan = PlanParameters(ApproachParameters(np.zeros(4), np.zeros(2), tau, np.zeros((3, 7))), np.zeros(5))
    moved = carry.carried_to_rate(plan, sc, rate_from, rate_to)
    meets_before = rate_from * (tau + sc.phases.approach_s)  # spin angle swept by the meeting [deg]
    meets_after = rate_to * (moved.approach.start_delay_s + sc.phases.approach_s)
    assert abs((meets_after - meets_before + 180.0) % 360.0 - 180.0) < 1e-9
    earliest, latest = sc.phases.start_delay_window_s
    assert earliest <= moved.approach.start_delay_s <= latest


@pytest.mark.parametrize(("offline", "kind"), [
    ({"exit_code": 0, "start_delay_s": 2.0}, FailureKind.HELD_ONLY_TOO_EARLY),  # a plan, before a live one can start
    ({"exit_code": 0, "start_delay_s": 0.0}, FailureKind.HELD_ONLY_TOO_EARLY),
    ({"exit_code": 0, "start_delay_s": np.nextafter(EARLIEST_COLD_START_S, 0.0)}, FailureKind.HELD_ONLY_TOO_EARLY),
    ({"exit_code": 0, "start_delay_s": EARLIEST_COLD_START_S}, FailureKind.MISSED_LIVE),  # a start a live plan can take
    ({"exit_code": 0, "start_delay_s": 31.2}, FailureKind.MISSED_LIVE),
    ({"exit_code": 2, "start_delay_s": 2.0}, FailureKind.NO_GRASP_HELD),  # no plan offline either: what it failed
    ({"exit_code": None, "start_delay_s": None}, FailureKind.NO_GRASP_HELD),  # killed: nothing known
    (None, FailureKind.NO_GRASP_HELD),  # not planned offline
])
def test_an_offline_plan_tells_a_grasp_held_only_too_early_from_one_the_live_search_missed(offline, kind):
    no_grasp = [_check("grasp_position", "grasp"), _check("collision", "approach")]
    assert failure_kind(no_grasp, None, [[0.0, 90.0]], offline) is kind
    assert record_failure_kind({"reasons": no_grasp, "offline": offline}) is kind
    braking = [_check("grasp_torque", "stabilization")]
    expected = FailureKind.BRAKING if kind is FailureKind.NO_GRASP_HELD else kind
    assert failure_kind(braking, None, None, offline) is expected


def test_an_offline_plan_does_not_overrule_what_says_more():
    feasible = {"exit_code": 0, "start_delay_s": 20.0}
    assert failure_kind([{"reason": "out of reach", "detail": "…"}], None, None, feasible) is FailureKind.OUT_OF_REACH
    assert failure_kind([{"reason": "over budget", "detail": "130 s"}], None, None, feasible) is FailureKind.OVER_BUDGET
    early = [_check("collision", "approach")]
    assert failure_kind(early, None, [[0.0, 2.0]], feasible) is FailureKind.ONLY_TOO_EARLY  # the scan says when


def test_the_offline_check_plans_only_the_failures_it_can_explain_with_offline(monkeypatch):
    import bench
    from bench_sections import recheck
    from bench_sections.common import settings_for

    outcomes = [[], [_check("grasp_torque", "stabilization")], [{"reason": "out of reach", "detail": "…"}],
                [_check("collision", "approach")]]

    def fake_run_all(jobs, settings):
        return [{"feasible_on_time": not reasons, "wall_s": 1.0, "exit_code": 2 if reasons else 0, "reasons": reasons}
                for reasons in outcomes[: len(jobs)]]

    offline_runs: list[list[str]] = []

    def fake_run_cli(args, kill_after_s):
        offline_runs.append(args)
        return CliRun(0, 3.0, "", "", {"start_delay_s": 1.5, "checks": {}})

    monkeypatch.setattr(coverage, "run_all", fake_run_all)
    monkeypatch.setattr(coverage, "with_windows", lambda records, states, scenario: records)
    monkeypatch.setattr(recheck, "run_cli", fake_run_cli)
    args = bench.parse_args(["--coverage-kinds", "scenario_I_tumble", "--coverage-states", "4",
                             "--coverage-offline-check", "--coverage-tables", str(ROOT / "tests" / "data")])
    c = coverage.coverage(settings_for(False, False, 7, None, 60.0, False, 100.0, bench.coverage_settings_of(args)))
    runs = c["plans"]["scenario_I_tumble"]["runs"]
    # the braking and the no-grasp-held failures, not the feasible plan nor the state out of reach
    assert [a[-1] for a in offline_runs] == ["--offline"] * 2
    assert ["offline" in r for r in runs] == [False, True, False, True]
    assert runs[1]["offline"] == {"exit_code": 0, "wall_s": 3.0, "start_delay_s": 1.5, "base_offset_m": None}
    assert c["plans"]["scenario_I_tumble"]["failures_by_kind"] == {"held only too early": 2, "out of reach": 1}
    assert c["offline_check"] is True
    assert not bench.coverage_settings_of(bench.parse_args([])).offline_check  # off unless asked for


def test_the_variant_check_plans_every_failure_of_the_state_again_with_the_variant(monkeypatch):
    import bench
    from bench_sections import recheck
    from bench_sections.common import settings_for
    from bench_sections.report import _coverage

    from planner.box_edge import BOX_EDGE_NOTE

    edge_note = f"{BOX_EDGE_NOTE} (θ_b(0) z = +1.000 m, robot.base_offset_z_m = [-1, 1]): …"
    outcomes = [([], []), ([_check("grasp_torque", "stabilization")], []),
                ([{"reason": "out of reach (proven)", "detail": "…"}], []),
                ([_check("collision", "approach")], [edge_note]), ([{"reason": "exit 70", "detail": "…"}], []),
                ([{"reason": "over budget", "detail": "131 s"}], [])]

    def fake_run_all(jobs, settings):
        return [{"feasible_on_time": not reasons, "wall_s": 1.0, "exit_code": 2 if reasons else 0,
                 "reasons": reasons, "notes": notes} for reasons, notes in outcomes[: len(jobs)]]

    variant_runs: list[list[str]] = []

    def fake_run_cli(args, kill_after_s):  # the variant plans the no-grasp-held state only
        variant_runs.append(args)
        held = len(variant_runs) == 3
        return CliRun(0 if held else 2, 7.0, "", "", {"start_delay_s": 30.0, "base_offset_m": {"x": 0.5, "z": 1.7},
                                                        "checks": {}} if held else None)

    monkeypatch.setattr(coverage, "run_all", fake_run_all)
    monkeypatch.setattr(coverage, "with_windows", lambda records, states, scenario: records)
    monkeypatch.setattr(recheck, "run_cli", fake_run_cli)
    args = bench.parse_args(["--coverage-kinds", "scenario_I_tumble", "--coverage-states", "6",
                             "--coverage-variant-check", "wide", "--coverage-tables", str(ROOT / "tests" / "data")])
    c = coverage.coverage(settings_for(False, False, 7, None, 60.0, False, 100.0, bench.coverage_settings_of(args)))
    kind = c["plans"]["scenario_I_tumble"]
    # the braking, the proven out of reach and the no-grasp-held failures: not the feasible plan, the bug, the overrun
    assert [a[1] for a in variant_runs] == ["configs/scenarios/scenario_I_wide.toml"] * 3
    planned = [coverage.plan_args("scenario_I", s, 100.0) for s in coverage.kind_states(coverage.KINDS[2], 6, 7)]
    assert [a[2:] for a in variant_runs] == [b[2:] for b in planned[1:4]]  # the same states, the same options
    assert ["variant_plan" in r for r in kind["runs"]] == [False, True, True, True, False, False]
    assert kind["runs"][3]["variant_plan"] == {"exit_code": 0, "wall_s": 7.0, "start_delay_s": 30.0,
                                               "base_offset_m": [0.5, 1.7]}
    assert kind["failures_planned_by_variant"] == {"checked": 3, "no grasp held": 1}
    assert kind["failures_at_box_edge"] == 1
    assert c["variant_check"] == "wide"
    header, rows = _coverage(c)
    assert "failures planned again with the wide variant" in header
    line = dict(rows)["plans scenario_I_tumble"]
    assert "1 refused on the box's edge" in line and "the variant plans 1/3 failures (no grasp held 1)" in line


def test_the_variant_check_takes_a_plan_command_and_not_a_variant_run():
    import bench
    from bench_sections.variant_check import variant_arguments

    assert variant_arguments(["plan", "configs/scenarios/scenario_II.toml", "--attitude", "1,0,0,0"], "wide") == [
        "plan", "configs/scenarios/scenario_II_wide.toml", "--attitude", "1,0,0,0"]
    with pytest.raises(ValueError, match="not a plan command"):
        variant_arguments(["query", "tables/t.h5"], "wide")
    with pytest.raises(SystemExit):
        bench.parse_args(["--coverage-variant", "wide", "--coverage-variant-check", "wide"])
    with pytest.raises(SystemExit):
        bench.parse_args(["--coverage-variant-check", "nonexistent"])
    assert bench.coverage_settings_of(bench.parse_args([])).variant_check is None  # off unless asked for
