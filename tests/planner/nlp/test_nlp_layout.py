"""Named NLP vector layouts (planner.nlp.layout) and solve outcomes (planner.nlp.outcome)."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest

from planner.nlp.layout import LayoutError, VectorLayout
from planner.nlp.outcome import SolveOutcome


def test_blocks_are_laid_out_in_order_with_their_bounds():
    layout = VectorLayout()
    assert layout.add("a", 2) == slice(0, 2)
    assert layout.add("b", 3, [0.0, 1.0, 2.0], 5.0) == slice(2, 5)
    layout.add("empty", 0)
    assert layout.add("c", 1, -1.0, 1.0) == slice(5, 6)
    assert layout.size == 6 and [b.name for b in layout] == ["a", "b", "empty", "c"]
    np.testing.assert_array_equal(layout.lower, [-np.inf, -np.inf, 0.0, 1.0, 2.0, -1.0])
    np.testing.assert_array_equal(layout.upper, [np.inf, np.inf, 5.0, 5.0, 5.0, 1.0])
    assert layout.slice("c") == slice(5, 6) and "b" in layout and "d" not in layout


def test_constraint_expressions_stack_in_the_order_of_their_blocks():
    x = ca.MX.sym("x", 3)
    g = VectorLayout()
    g.add_expression("first", x[:2], 0.0, 0.0)
    g.add("none", 0)
    g.add_expression("second", ca.sumsqr(x), -np.inf, 1.0)
    f = ca.Function("g", [x], [g.expression()])
    np.testing.assert_array_equal(np.asarray(f([1.0, 2.0, 3.0])).ravel(), [1.0, 2.0, 14.0])
    assert g.slice("second") == slice(2, 3) and g.size == 3


def test_pack_fills_the_blocks_in_order_and_checks_their_sizes():
    layout = VectorLayout()
    layout.add("q", 2)
    layout.add("R", 4)
    packed = layout.pack({"R": np.arange(4.0).reshape(2, 2), "q": [7.0, 8.0]})
    np.testing.assert_array_equal(packed, [7.0, 8.0, 0.0, 1.0, 2.0, 3.0])
    with pytest.raises(LayoutError, match="'q': expected 2 values, got 3"):
        layout.pack({"q": [1.0, 2.0, 3.0], "R": np.zeros(4)})


def test_a_wrong_name_or_bound_says_which_block():
    layout = VectorLayout()
    layout.add("a", 2)
    with pytest.raises(LayoutError, match="'a': added twice"):
        layout.add("a", 1)
    with pytest.raises(LayoutError, match="'b': not in the layout"):
        layout.slice("b")
    with pytest.raises(LayoutError, match="'c': 3 bounds for 2 entries"):
        layout.add("c", 2, [0.0, 0.0, 0.0])


def test_an_outcome_is_its_text_in_files_and_messages():
    assert SolveOutcome.SOLVED == "Solve_Succeeded" and f"{SolveOutcome.FEASIBLE_POINT_FOUND}" == "Feasible_Point_Found"
    assert json.dumps({"status": SolveOutcome.ITERATION_BUDGET_EXHAUSTED}) == '{"status": "Iteration_Budget_Exhausted"}'
    assert SolveOutcome.from_ipopt("Maximum_Iterations_Exceeded") is SolveOutcome.ITERATION_LIMIT
    assert SolveOutcome.from_ipopt("Something_New") is SolveOutcome.UNKNOWN
