"""Every valid state gets the table's answer, and the same state the same answer (the golden CI table).

The table's grid (``configs/grids/ci.toml``): flat spins of scenario II about orbital z, rate {3.5, 4} °/s,
phase {0, 20}°. A state off the flat-spin family or beyond the grid is answered at the nearest grid
coordinates and the answer says so; the same physical state given two ways (q and −q, a rate 1e-9 beyond a
bound, a phase of 359.999° next to 0°) gets the same corners and the same (or continuously close) parameters.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lut.query.table_query import TableQuery
from lut.table.grid_projection import project_to_grid
from planner.errors import StateFieldError
from planner.model.target import TargetState

GOLDEN = Path(__file__).resolve().parents[2] / "data" / "ci_golden.h5"
DEG = np.pi / 180.0


@pytest.fixture(scope="module")
def tq() -> TableQuery:
    return TableQuery(GOLDEN)


def _spin(rate_deg_s: float, phase_deg: float, sign: float = 1.0) -> TargetState:
    """Flat spin about orbital z (= body z) at ``phase_deg``; ``sign`` -1 gives the same attitude as −q."""
    half = 0.5 * phase_deg * DEG
    return TargetState(sign * np.array([np.cos(half), 0.0, 0.0, np.sin(half)]), [0.0, 0.0, rate_deg_s * DEG])


def _flat(answer) -> np.ndarray:
    p = answer.parameters
    return np.concatenate([p.approach.params, p.approach.base_offset_m, [p.approach.start_delay_s],
                           p.approach.q_tracking.ravel(), p.stabilization_params])


def test_q_and_minus_q_get_the_same_answer(tq):
    a, b = tq.interpolate(_spin(3.75, 10.0)), tq.interpolate(_spin(3.75, 10.0, sign=-1.0))
    assert a.corners == b.corners and a.source == b.source
    np.testing.assert_array_equal(_flat(a), _flat(b))


def test_a_rate_at_the_grid_edge_and_1e_9_beyond_get_the_same_answer(tq):
    edge, beyond = tq.interpolate(_spin(4.0, 5.0)), tq.interpolate(_spin(4.0 + 1e-9, 5.0))
    assert edge.corners == beyond.corners and not edge.notes and not beyond.notes
    delay = 2 + len(edge.parameters.approach.params)  # the start delay's index in _flat
    keep = np.arange(_flat(edge).size) != delay
    np.testing.assert_allclose(_flat(beyond)[keep], _flat(edge)[keep], rtol=0, atol=1e-8)
    # a carried plan keeps the spin angle at its meeting (m ≤ 100 s after the observation), which a rate 1e-9 °/s
    # higher reaches m·1e-9/4 s ≤ 2.5e-8 s earlier: continuous, not equal
    shift = beyond.parameters.approach.start_delay_s - edge.parameters.approach.start_delay_s
    assert -2.5e-8 <= shift < 0.0


def test_a_rate_beyond_the_grid_is_answered_at_its_edge_and_says_so(tq):
    edge, beyond = tq.interpolate(_spin(4.0, 0.0)), tq.interpolate(_spin(4.3, 0.0))
    assert beyond.corners == edge.corners
    np.testing.assert_array_equal(_flat(beyond), _flat(edge))  # phase 0: no start-delay shift either
    assert len(beyond.notes) == 1 and "spin_rate_deg_s = 4.3 not in [3.5, 4]" in beyond.notes[0]


def test_a_phase_of_359_999_is_answered_next_to_0(tq):
    """0.001° of phase at 3.75 °/s is 0.27 ms of start delay; the 20° corner weighs 3e-6 there."""
    zero, before = tq.interpolate(_spin(3.75, 0.0)), tq.interpolate(_spin(3.75, 359.999))
    assert set(zero.corners) <= set(before.corners)
    # the corners that weigh there and agree on the meeting time (3.75 °/s is midway between the rates: the 0° corners
    # of both weigh 0.5, and the table's two rates may hold different meeting times, so one is kept)
    heavy = {c for c, w in zip(*_cell(tq, _spin(3.75, 359.999)), strict=True) if w > 1e-3}
    assert set(before.corners) & heavy == set(zero.corners)
    tau0, tau1 = zero.parameters.approach.start_delay_s, before.parameters.approach.start_delay_s
    # carried back by the symmetry: Δφ / rate, plus what the 20° corners' ~1.5e-6 weight moves the mean by (their
    # carried meeting times differ from the 0° corners' by up to the spread below)
    state = _spin(3.75, 359.999)
    coords = project_to_grid(tq.grid, state).coords
    carried = [tq.points[c].parameters.approach.start_delay_s + tq.phase_shift_s(c, coords) for c in before.corners]
    weights = dict(zip(*_cell(tq, state), strict=True))
    light = sum(w for c, w in weights.items() if c in before.corners and w < 1e-3)
    assert abs((tau1 - tau0) - 0.001 / 3.75) < 1e-6 + light * (max(carried) - min(carried))
    np.testing.assert_allclose(before.parameters.approach.params, zero.parameters.approach.params, atol=1e-4)


def _cell(tq: TableQuery, state: TargetState) -> tuple[list[int], np.ndarray]:
    cell = tq.grid.locate(project_to_grid(tq.grid, state).coords)
    return cell.corners, cell.weights


def test_an_estimated_flat_spin_is_answered_at_the_nearest_flat_spin(tq):
    """0.3° of tilt and 0.03 °/s of transverse rate: the nearest flat spin's answer, with a note."""
    exact = _spin(3.6, 10.0)  # off the rates' midpoint, where two meeting-time families would tie
    tilt = np.array([np.cos(0.15 * DEG), np.sin(0.15 * DEG), 0.0, 0.0])  # 0.3° about orbital x
    w, x, y, z = exact.attitude_wxyz
    tw, tx, _, _ = tilt
    q = np.array([tw * w - tx * x, tw * x + tx * w, tw * y - tx * z, tw * z + tx * y])  # tilt ⊗ q
    noisy = TargetState(q, exact.omega_body_rad_s + np.array([0.03 * DEG, 0.0, 0.0]))
    a, b = tq.interpolate(exact), tq.interpolate(noisy)
    assert a.corners == b.corners and not a.notes
    assert len(b.notes) == 1 and "not a flat spin" in b.notes[0] and "nearest state of its family" in b.notes[0]
    coords = project_to_grid(tq.grid, noisy).coords
    np.testing.assert_allclose(coords, [np.hypot(3.6, 0.03), 90.0, 10.0], atol=0.02)


def test_a_malformed_state_never_reaches_the_table():
    """Only states off the grid are answered anyway: a NaN rate is refused where the state is made, naming it."""
    with pytest.raises(StateFieldError, match="omega_body_rad_s: must be finite"):
        TargetState([1.0, 0.0, 0.0, 0.0], [0.0, 0.0, np.nan])
