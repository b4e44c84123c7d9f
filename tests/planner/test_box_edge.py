"""A refused plan's θ_b(0) on its base-offset box's edge (``planner.box_edge``): on a bound, at the tolerance and a hair
inside it, at a corner (both axes), and a pinned axis (a re-plan's, whose bounds coincide), which has no edge."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planner.box_edge import BOX_EDGE_NOTE, BOX_EDGE_TOL_M, box_edge_note, box_edges
from planner.config.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]
BOX = ((-1.0, 1.0), (-1.0, 1.0))


@pytest.mark.parametrize(("offset", "axes"), [
    ((0.3, 1.0), ("z",)),                           # exactly on the upper z bound
    ((-1.0 + 0.99 * BOX_EDGE_TOL_M, 0.0), ("x",)),  # just within the tolerance
    ((-1.0 + 1.01 * BOX_EDGE_TOL_M, 0.0), ()),      # a hair inside it
    ((1.0 - 2.6e-6, -1.0), ("x", "z")),             # a corner, as IPOPT leaves an active bound
    ((0.0, 0.0), ()),                               # the station
    ((0.999, 0.999), ()),                           # a millimetre inside both
])
def test_edges_are_the_bounds_within_a_millimetre(offset, axes):
    assert tuple(e.axis for e in box_edges(BOX, offset)) == axes


def test_a_pinned_axis_has_no_edge():
    pinned = ((0.4, 0.4), (-1.0, 1.0))  # x pinned where the chaser waits (lutgen replan)
    assert box_edges(pinned, (0.4, 0.2)) == ()
    assert [e.axis for e in box_edges(pinned, (0.4, 1.0))] == ["z"]


def test_the_note_names_each_bound_and_its_field():
    note = box_edge_note(BOX, np.array([1.0, -1.0]))
    assert note.startswith(BOX_EDGE_NOTE)
    assert "θ_b(0) x = +1.000 m, robot.base_offset_x_m = [-1, 1]" in note
    assert "θ_b(0) z = -1.000 m, robot.base_offset_z_m = [-1, 1]" in note
    assert box_edge_note(BOX, (0.2, 0.5)) is None


@pytest.mark.parametrize("name", ["scenario_I", "scenario_II", "scenario_I_wide"])
def test_the_bundled_boxes_edges_are_their_configured_bounds(name):
    sc = load_scenario(ROOT / "configs" / "scenarios" / f"{name}.toml")
    (x_lo, x_hi), (z_lo, z_hi) = sc.base_offset_bounds_m
    assert [e.bounds_m for e in box_edges(sc.base_offset_bounds_m, (x_hi, z_lo))] == [(x_lo, x_hi), (z_lo, z_hi)]
    assert box_edges(sc.base_offset_bounds_m, sc.base_offset_guess_m) == ()
