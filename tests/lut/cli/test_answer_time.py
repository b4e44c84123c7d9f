"""An answer is on time only if its approach starts after it: the verdict's timing line, the late refusal at the
boundary, and ``--earliest-start-s`` checked before anything is solved."""

from __future__ import annotations

import math

import pytest

from lut.cli.answer_time import AnswerTime
from planner.deadline import START_LEAD_S
from tests.support.cli import ROOT, assert_one_line_error, lutgen_in_process

SCENARIO_I = ROOT / "configs" / "scenarios" / "scenario_I.toml"


def test_an_approach_starting_at_the_answer_is_on_time_and_a_nanosecond_earlier_late():
    assert not AnswerTime(5.0, 5.0).late  # the motion may begin as the answer arrives
    assert AnswerTime(5.0 - 1e-9, 5.0).late
    assert not AnswerTime(0.0, 0.0).late  # a window that opens at the observation, answered at once


def test_the_timing_line_and_the_refusal_say_both_instants():
    on_time, late = AnswerTime(32.7, 4.6), AnswerTime(0.04, 10.9)
    assert on_time.line().endswith("28.1 s ahead") and "32.70 s" in on_time.line()
    assert late.line().endswith("10.9 s late")
    assert late.reason().startswith("late: ") and "0.04 s" in late.reason() and "10.9 s" in late.reason()
    assert "--earliest-start-s" in late.reason()
    assert late.as_dict() == {"answered_s": 10.9, "start_delay_s": 0.04, "late": True}


def test_an_earliest_start_at_either_end_of_the_window_is_taken():
    from lut.cli.options import with_earliest_start
    from planner.config.scenario import load_scenario

    sc = load_scenario(SCENARIO_I)
    latest = sc.phases.max_start_delay_s
    assert with_earliest_start(sc, None) is sc
    assert with_earliest_start(sc, 0.0).phases.start_delay_window_s == (0.0, latest)
    assert with_earliest_start(sc, latest).phases.start_delay_window_s == (latest, latest)  # one start only


@pytest.mark.parametrize("value", ["-1", "90.5", "nan", "inf"])
def test_an_earliest_start_outside_the_scenarios_window_is_refused_in_one_line(value):
    proc = lutgen_in_process("plan", SCENARIO_I, "--earliest-start-s", value)
    line = assert_one_line_error(proc, "--earliest-start-s", "[0, 90] s", "phases.max_start_delay_s")
    assert value in line or (value == "nan" and "nan" in line) or (math.isinf(float(value)) and "inf" in line)


# a scenario I flat spin (coverage section, seed 7, state 17): planned offline its approach meets at 0.68 s
EARLY = ("--attitude", "0.378483351335,-0.0140455517503,0.597285821665,0.706967271149", "--omega-deg-s",
         "0,1.60531163556,0")


def test_a_live_plan_aims_after_its_answer_and_an_offline_one_is_not_judged(tmp_path):
    """Live: the approach starts past the lead (on an idle machine ~3 s after the answer), and the verdict is the
    answer's: on time and exit 0, or refused as late, never called feasible while late (the margin depends on the
    machine's load, the rule does not)."""
    import json

    live = lutgen_in_process("plan", SCENARIO_I, *EARLY, "--out", tmp_path / "live.json")
    answer = json.loads((tmp_path / "live.json").read_text())["answer"]
    assert answer["start_delay_s"] >= START_LEAD_S
    assert answer["late"] is (answer["start_delay_s"] < answer["answered_s"])
    if answer["late"]:
        assert live.returncode == 2 and "INFEASIBLE: late: " in live.stderr, live.stdout + live.stderr
    else:
        assert live.returncode == 0 and " s ahead" in live.stdout, live.stdout + live.stderr
    offline = lutgen_in_process("plan", SCENARIO_I, *EARLY, "--offline", "--out", tmp_path / "offline.json")
    assert offline.returncode == 0, offline.stdout + offline.stderr
    doc = json.loads((tmp_path / "offline.json").read_text())
    assert "answer" not in doc and "answered" not in offline.stdout
    assert doc["parameters"]["start_delay_s"] < 1.0  # the approach meets at once: fine for a study, not for a flight
