"""One rule for "how far past its limits": relative to each limit, absolute where the limit is ~0, NaN infinite.

Shared by the NLP's least violating iterate (planner/nlp/feasibility_stop.py) and the query's least violating answer
(lut/query/least_violating.py); the degenerate limits on purpose."""

from __future__ import annotations

import numpy as np
import pytest

from planner.excess import ZERO_LIMIT, relative_excess_sum


def test_an_excess_counts_in_units_of_its_limit_whatever_the_limit_s_sign():
    # 2 N·m over a 10 N·m limit, 1 cm short of a 2 cm clearance, 0.5 rad past a −2.09 rad lower bound
    assert relative_excess_sum([2.0, 0.01, 0.5], [10.0, 0.02, -2.0]) == pytest.approx(0.2 + 0.5 + 0.25)


def test_a_zero_limit_counts_the_excess_itself_and_an_infinite_limit_nothing():
    assert relative_excess_sum([0.1, 0.3], [0.0, ZERO_LIMIT]) == pytest.approx(0.4)  # at the threshold: still zero
    assert relative_excess_sum([0.1], [2 * ZERO_LIMIT]) == pytest.approx(0.1 / (2 * ZERO_LIMIT))
    assert relative_excess_sum([5.0], [np.inf]) == 0.0


def test_nothing_over_is_zero_and_a_nan_or_infinite_excess_is_infinite():
    assert relative_excess_sum([], []) == 0.0 and relative_excess_sum([0.0, 0.0], [10.0, 0.0]) == 0.0
    assert relative_excess_sum([np.nan, 1.0], [10.0, 10.0]) == np.inf
    assert relative_excess_sum([np.inf], [10.0]) == np.inf
