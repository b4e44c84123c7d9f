"""A state whose grasp the arm never reaches within the start-delay window is infeasible in seconds, with
the reason (it searched ~250 s from the initial configuration before)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from lut.solve.point_worker import solve_point
from lut.table.records import PARAMETER_KEYS
from planner.config.scenario import load_scenario
from planner.model.target import TargetState
from planner.phases.approach import approach_spline
from planner.phases.approach_guess import FREE_AXIS_ANGLES_DEG, MeetingOutcome, reach_scan
from tests.support.cli import ROOT, lutgen

SCENARIO_II = ROOT / "configs" / "scenarios" / "scenario_II.toml"
UNREACHABLE_OMEGA_DEG_S = (0.0, 0.0, 40.0)  # 10× the default spin: the grasp sweeps past faster than the arm
FAST_S = 60.0  # the whole command, planner build included (the answer itself takes ~1.5 s)


@pytest.fixture(scope="module")
def scenario_II():
    return load_scenario(SCENARIO_II)


def _state(omega_deg_s) -> TargetState:
    return TargetState(np.array([1.0, 0.0, 0.0, 0.0]), np.radians(omega_deg_s))


def test_plan_of_an_unreachable_state_is_infeasible_in_seconds_with_the_reason(tmp_path):
    out = tmp_path / "p.json"
    t0 = time.perf_counter()
    proc = lutgen("plan", SCENARIO_II, "--omega-deg-s", ",".join(map(str, UNREACHABLE_OMEGA_DEG_S)), "--out", out,
                  timeout_s=FAST_S)
    elapsed = time.perf_counter() - t0
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    for words in ("INFEASIBLE", "out of reach", "start-delay window [0, 90] s"):
        assert words in proc.stderr, proc.stderr
    assert not out.exists()
    assert elapsed < FAST_S


def test_the_scan_tells_what_it_found_at_every_meeting_time(scenario_II):
    spline = approach_spline(scenario_II)
    unreachable = reach_scan(scenario_II, spline, _state(UNREACHABLE_OMEGA_DEG_S))
    reachable = reach_scan(scenario_II, spline, scenario_II.target_state.as_state())
    n_times = int(scenario_II.phases.max_start_delay_s // 2.0) + 1
    for scan in (unreachable, reachable):
        assert len(scan.outcomes) == n_times
    assert not unreachable.reachable and MeetingOutcome.REACHED not in unreachable.outcomes
    assert MeetingOutcome.BEYOND_REACH in unreachable.outcomes  # joint 1's reach, base frozen: part of the window
    # the scan's own three best meeting times, then one guess per angle about the boom it held the grasp frame at
    assert reachable.reachable and 3 <= len(reachable.guesses) <= 3 + len(FREE_AXIS_ANGLES_DEG)
    reached_times = {2.0 * i for i, o in enumerate(reachable.outcomes) if o is MeetingOutcome.REACHED}
    assert {g.start_delay_s for g in reachable.guesses} <= reached_times


def test_a_table_point_out_of_reach_is_recorded_infeasible_with_the_reason(scenario_II):
    state = _state(UNREACHABLE_OMEGA_DEG_S)
    rec = solve_point(str(SCENARIO_II), 7, state.attitude_wxyz, state.omega_body_rad_s, None, 0.0)
    assert rec["status"] == "infeasible" and rec["point"] == 7
    assert rec["failure_reason"].startswith("out of reach")
    assert not any(key in rec for key in PARAMETER_KEYS)
