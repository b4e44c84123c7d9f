"""Success statistics: the Wilson interval against scipy's, the failure tally, and the largest 95 % scale."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binomtest

from lut.robustness.execution import RunOutcome
from lut.robustness.statistics import SuccessEstimate, failure_tally, success_estimate, wilson_interval
from lut.robustness.sweep import ScalePoint, largest_scale, parse_scales
from planner.errors import LutgenError


@pytest.mark.parametrize("k, n", [(0, 1), (0, 10), (5, 10), (10, 10), (197, 200), (200, 200), (1, 3)])
def test_wilson_interval_matches_scipy(k, n):
    ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert np.allclose(wilson_interval(k, n), (ref.low, ref.high), atol=1e-9)


def run(feasible: bool, failed: tuple[str, ...] = ()) -> RunOutcome:
    return RunOutcome(feasible, failed, {}, np.zeros(0), np.zeros(0), 0.0, 0.0)


def test_tally_counts_failures_and_first_failures():
    runs = [run(True), run(False, ("grasp_torque",)), run(False, ("collision", "grasp_torque")),
            run(False, ("grasp_torque", "collision")), run(False, ("execution",))]
    est = success_estimate(runs)
    assert (est.successes, est.runs, est.probability) == (1, 5, 0.2)
    tally = {t.check: (t.first, t.failed) for t in failure_tally(runs)}
    assert tally == {"grasp_torque": (2, 3), "collision": (1, 2), "execution": (1, 1)}
    assert failure_tally([run(True)]) == []


def point(scale: float, k: int, n: int = 20) -> ScalePoint:
    return ScalePoint(scale, SuccessEstimate(k, n, *wilson_interval(k, n)))


def test_largest_scale_is_the_last_before_the_first_miss():
    assert largest_scale([point(2, 10), point(0, 20), point(1, 19)]).scale == 1  # 19/20 = 0.95 meets it
    assert largest_scale([point(0, 20), point(1, 18), point(2, 20)]).scale == 0  # stops at the first miss
    none = largest_scale([point(0.5, 10), point(1, 20)])
    assert none.scale is None and not none.beyond_tested
    beyond = largest_scale([point(0, 20), point(3, 20)])
    assert beyond.scale == 3 and beyond.beyond_tested


def test_scales_always_hold_one_and_refuse_bad_values():
    assert parse_scales("2,0.5,0.5,0") == [0.0, 0.5, 1.0, 2.0]
    for bad in ("-1", "nan", "inf", "a,b"):
        with pytest.raises(LutgenError, match="--scales"):
            parse_scales(bad)
