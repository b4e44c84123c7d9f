"""The bench's ``optimal`` section (issue 21): its cost gap, fractions and bars judged on made-up runs, its states
seeded and off the grid, and ``--trim``'s run of it on the feasibility-only golden table (it says so)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))  # the benchmark's sections are scripts, not a package

from bench_sections import optimal as section  # noqa: E402
from bench_sections.common import GOLDEN_TABLE, coverage_settings, optimal_settings, settings_for  # noqa: E402

from lut.table.grid import Grid  # noqa: E402
from lut.table.grid_config import load_grid  # noqa: E402
from planner.config.scenario import load_scenario  # noqa: E402


def _query(total: float | None, source: str = "interpolated", latency_s: float = 2.0,
           feasible: bool = True) -> dict[str, Any]:
    return {"feasible": feasible, "feasible_without_resolve": feasible and source in section.WITHOUT_RESOLVE,
            "source": source, "latency_s": latency_s, "cost": None if total is None else {"total": total}}


def _optimum(total: float | None, feasible: bool = True) -> dict[str, Any]:
    return {"feasible": feasible, "wall_s": 40.0, "cost": None if total is None else {"total": total}}


def test_gap_is_relative_to_the_optimum_and_absolute_near_zero():
    near = section.cost_gap(_query(3e-5), _optimum(1e-12))
    assert near["absolute"] == pytest.approx(3e-5 - 1e-12) and near["within"]  # below the 1e-4 absolute tolerance
    assert not section.cost_gap(_query(2e-4), _optimum(0.0))["within"] and \
        section.cost_gap(_query(2e-4), _optimum(0.0))["relative"] is None
    big = section.cost_gap(_query(-0.94), _optimum(-1.0))  # a maximised term: 6 % worse than the optimum
    assert big["relative"] == pytest.approx(0.06) and not big["within"]
    assert section.cost_gap(_query(-0.96), _optimum(-1.0))["within"]
    assert section.cost_gap(_query(5.0), _optimum(1.0, feasible=False)) is None  # nothing to compare against
    assert section.cost_gap(_query(0.5), _optimum(1.0))["within"]  # better than the offline optimum


def test_summary_fractions_and_bars():
    queries = [_query(1e-6), _query(1e-6, "refined", latency_s=30.0), _query(1e-6, "solved cold", latency_s=120.0),
               _query(None, feasible=False)]
    runs = [{"query": q, "optimum": _optimum(0.0), "gap": section.cost_gap(q, _optimum(0.0))} for q in queries]
    s = section.summary(runs)
    assert s["states"] == 4 and s["fraction_feasible"] == 0.75 and s["fraction_feasible_without_resolve"] == 0.25
    assert s["sources"] == {"interpolated": 2, "refined": 1, "solved cold": 1}
    assert s["cost_gap"]["compared"] == 3 and s["cost_gap"]["fraction_within_tolerance"] == 1.0
    bars = s["bars"]
    assert bars["every_query_feasible_within_100_s"]["value"] == 0.5 and bars["every_query_feasible_within_100_s"][
        "met"] is False
    assert bars["latency_p95_s"]["met"] is False and bars["cost_within_tolerance_at_p95"]["met"] is True
    assert all(bar["enough_states"] is False for bar in bars.values())  # 4 states, the issue measures on 30


def test_states_are_seeded_inside_the_grid_box_and_off_its_points():
    config = load_grid(ROOT / "configs" / "grids" / "flat_spin_I_energy.toml")
    scenario = load_scenario(config.scenario_path)
    grid = Grid(config, scenario.target.inertia_body_kg_m2, scenario.target_state.as_state())
    a = section.off_grid_states(grid, 5, 7)
    b = section.off_grid_states(grid, 3, 7)
    for s, t in zip(a, b, strict=False):
        np.testing.assert_array_equal(s.attitude_wxyz, t.attitude_wxyz)
    for s in a:
        coords = grid.coordinates_of_state(s)
        for c, values in zip(coords, grid.axis_values, strict=True):
            assert values.min() <= c <= values.max()
        assert min(np.abs(coords[0] - grid.axis_values[0])) > 1e-9  # never on a grid value (continuous draws)


def test_trim_runs_the_section_on_the_golden_table_and_says_it_has_no_costs():
    settings = settings_for(True, True, 7, None, 60.0, False, 100.0, coverage_settings(True, True, None, 1, None))
    from dataclasses import replace

    settings = replace(settings, optimal=optimal_settings(True, True, None, None))
    assert settings.optimal.table == GOLDEN_TABLE and settings.optimal.states == 1
    out = section.optimal(settings)
    assert "feasibility-only" in out["skipped"] and out["runs"] is None and out["table"] == "tests/data/ci_golden.h5"
    missing = section.optimal(replace(settings, optimal=optimal_settings(True, True, ROOT / "nowhere.h5", None)))
    assert "no table at" in missing["skipped"] and set(section.SUMMARY_KEYS) <= missing.keys()


def test_the_offline_optimums_budget_is_an_option_that_refuses_nonsense():
    """Scenario II's costed plans descend to their budget, so its bench gives the optimum the table's own point
    timeout; the default stays 600 s, and a budget that is not a positive finite number is refused."""
    import bench

    assert optimal_settings(False, False, None, None).optimum_budget_s == 600.0
    args = bench.parse_args(["--optimal-budget-s", "145"])
    assert optimal_settings(False, False, None, None, args.optimal_budget_s).optimum_budget_s == 145.0
    for bad in ("0", "-5", "inf", "nan"):
        with pytest.raises(SystemExit):
            bench.parse_args(["--optimal-budget-s", bad])


def _earlier_run(tmp_path: Path, states: list, seed: int = 7, scenario: str = "scenario_II_energy",
                 name: str = "earlier") -> Path:
    """An earlier run's JSON of the optimal section with made-up optima at ``states``."""
    import json

    runs = [{"state": i, "attitude_wxyz": list(map(float, s.attitude_wxyz)),
             "omega_body_deg_s": list(map(float, np.degrees(s.omega_body_rad_s))),
             "optimum": _optimum(1.0 + i) | {"command": "lutgen plan …"}} for i, s in enumerate(states)]
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps({"optimal": {"scenario": scenario, "seed": [seed, section.SEED_SALT],
                                            "optimum_budget_s": 145.0, "runs": runs}}))
    return path


def test_stored_optima_are_taken_only_for_the_same_scenario_seed_and_states(tmp_path):
    config = load_grid(ROOT / "configs" / "grids" / "flat_spin_II_energy_fine.toml")
    scenario = load_scenario(config.scenario_path)
    grid = Grid(config, scenario.target.inertia_body_kg_m2, scenario.target_state.as_state())
    states = section.off_grid_states(grid, 4, 7)
    head = {"scenario": "scenario_II_energy", "seed": [7, section.SEED_SALT]}
    stored = section.stored_optima(_earlier_run(tmp_path, states), head, states[:3])  # a shorter run: its first 3
    assert [o["cost"]["total"] for o in stored.optima] == [1.0, 2.0, 3.0] and stored.budget_s == 145.0
    refusals = {"its scenario is": _earlier_run(tmp_path, states, scenario="scenario_I_energy", name="I"),
                "its seed is": _earlier_run(tmp_path, states, seed=8, name="seed8"),
                "holds 2 states": _earlier_run(tmp_path, states[:2], name="short"),
                "state 1 is not this run's": _earlier_run(tmp_path, [states[0], states[2], states[1], states[3]],
                                                          name="shuffled")}
    for words, path in refusals.items():
        with pytest.raises(SystemExit, match=words):
            section.stored_optima(path, head, states)
    (tmp_path / "earlier.json").write_text("{}")
    with pytest.raises(SystemExit, match="not a bench JSON"):
        section.stored_optima(tmp_path / "earlier.json", head, states)


def test_the_offline_optimum_names_its_scenario_so_that_its_process_finds_it(tmp_path, monkeypatch):
    """A table built outside the repository names a scenario outside it: the optimum's command gives its absolute path
    (its process runs in the repository), one inside it the path from there (once the file's bare name: not found)."""
    from types import SimpleNamespace

    from bench_sections.coverage_runs import CliRun

    from planner.model.target_state import TargetState

    asked: list[list[str]] = []
    monkeypatch.setattr(section, "run_cli", lambda args, timeout_s: asked.append(args) or CliRun(2, 1.0, "", "", None))
    state = TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.radians([0.0, 0.0, 4.0]))
    outside = tmp_path / "configs" / "scenario_II_energy.toml"
    inside = ROOT / "configs" / "scenarios" / "scenario_II.toml"
    for scenario, named in ((outside, str(outside.resolve())), (inside, "configs/scenarios/scenario_II.toml")):
        record = section.optimum_record(SimpleNamespace(scenario_path=scenario), state, 60.0)
        assert asked[-1][:2] == ["plan", named] and record["exit_code"] == 2 and record["cost"] is None
