"""Which corners of a cell take part in a query's average (lut.query.interpolation.cheapest): those at the cell's
lowest weighted cost, within 1e-4 in the cost's units or 5 % of it, whichever is larger; and the order the corner
stage tries the rest in (cost_bands, corner_stage.corner_order): bands a factor 1.25 of cost apart, heaviest first in
each."""

from __future__ import annotations

import math

import pytest

from lut.query.corner_stage import CORNER_TRIES, corner_order
from lut.query.interpolation import COST_BAND_RATIO, SAME_COST_ABS, SAME_COST_REL, Candidate, cheapest, cost_bands


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


def _bands(*costs: float) -> list[int]:
    return cost_bands(_corners(*costs))


def test_bands_are_whole_factors_of_the_ratio_above_the_lowest_cost_touching_each_edge():
    r = COST_BAND_RATIO
    # 1.05 is cheapest's own edge (band 0); just past it band 1, up to (not including) a factor r, then band 2 at r
    assert _bands(1.0, 1.05, 1.06, r * 0.999, r, r * r * 0.999, r * r, 2.9) == [0, 0, 1, 1, 2, 2, 3, 1 + 4]


def test_a_negative_lowest_cost_bands_the_excess_by_the_lowests_size():
    # Eq. 14-15 are maximised, so their totals are negative: -10 and -7.4 differ by 26 % of the best's size
    top = 1 + int(math.log(3.0) / math.log(COST_BAND_RATIO))  # +10 lies 3 times the best's size above it
    assert _bands(-10.0, -9.5, -9.4, -7.4, -7.6, 10.0) == [0, 0, 1, 2, 1, top]


def test_costs_near_zero_share_a_band_and_unknown_costs_band_nothing():
    floor = SAME_COST_ABS / SAME_COST_REL  # 2e-3: costs far below it are alike
    assert _bands(0.0, 1e-9, 2e-4, floor * 0.2) == [0, 0, 1, 1]
    assert _bands(1e-9, math.nan, 0.5) == [0, 0, 0]
    assert cost_bands([]) == []


def test_one_corner_or_equal_costs_are_one_band():
    assert _bands(0.8) == [0]
    assert _bands(0.8, 0.8, 0.8) == [0, 0, 0]
    assert _bands(-0.8, -0.8) == [0, 0]


def test_the_corner_stage_tries_a_lighter_corner_of_a_cheaper_band_before_a_heavy_costly_one():
    # seed 7 state 13 of the optimal bench on flat_spin_II_energy_rates (docs/measurements.md, "Optimal tables"): the
    # 1.75 m² corner was the heaviest after the cheapest group and was answered; now the 0.93 m² one (1.55 times the
    # lowest) before it
    corners = [Candidate(58, 0.157, None, 0.674), Candidate(59, 0.118, None, 0.686), Candidate(61, 0.065, None, 0.601),
               Candidate(62, 0.049, None, 0.602), Candidate(67, 0.247, None, 1.75), Candidate(68, 0.185, None, 0.93),
               Candidate(70, 0.102, None, 0.769), Candidate(71, 0.076, None, 0.706)]
    assert [c.corner for c in corner_order(corners)] == [61, 62, 58, 59, 71, 68, 70, 67]


def test_the_corner_stage_keeps_its_weight_order_where_costs_are_alike_and_tries_at_most_its_limit():
    corners = [Candidate(i, w, None, 0.0) for i, w in enumerate((0.1, 0.4, 0.2, 0.05, 0.15, 0.01, 0.03, 0.02, 0.04))]
    assert [c.corner for c in corner_order(corners)] == [1, 2, 4, 0, 3, 8, 6, 7][:CORNER_TRIES]
