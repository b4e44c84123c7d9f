"""Which corners of a cell take part in a query's average (lut.query.interpolation.cheapest): those at the cell's
lowest weighted cost, within 1e-4 in the cost's units or 5 % of it, whichever is larger."""

from __future__ import annotations

import math

import pytest

from lut.query.interpolation import SAME_COST_ABS, SAME_COST_REL, Candidate, cheapest


def _corners(*costs: float) -> list[Candidate]:
    return [Candidate(i, 1.0, None, c) for i, c in enumerate(costs)]  # parameters play no part here


def _kept(*costs: float) -> list[int]:
    return [c.corner for c in cheapest(_corners(*costs))]


def test_a_corner_in_a_local_minimum_is_left_out():
    assert _kept(1e-9, 0.3, 3e-9) == [0, 2]


def test_the_absolute_tolerance_holds_at_its_edge_and_not_past_it():
    assert _kept(0.0, SAME_COST_ABS) == [0, 1]
    assert _kept(0.0, math.nextafter(SAME_COST_ABS, 1.0)) == [0]


@pytest.mark.parametrize("best", [10.0, -10.0])  # Eq. 14-15 are maximised: their totals are negative
def test_the_relative_tolerance_is_of_the_best_costs_size(best):
    assert _kept(best, best + SAME_COST_REL * abs(best)) == [0, 1]
    assert _kept(best, best + 1.01 * SAME_COST_REL * abs(best)) == [0]


def test_equal_costs_a_feasibility_table_or_an_unknown_cost_keep_every_corner():
    assert _kept(0.0, 0.0, 0.0) == [0, 1, 2]
    assert _kept(1e-9, math.nan, 0.5) == [0, 1, 2]  # a table without the clearance Eq. 15 needs
    assert cheapest([]) == []
