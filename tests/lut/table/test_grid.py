"""The look-up table grid (lut/table/grid.py): configs, state ↔ coordinates, flat-spin symmetry, cells, continuation."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from lut.table.grid import Grid
from lut.table.grid_config import Axis, GridConfig, load_grid, load_grid_text
from lut.table.grid_projection import project_to_grid
from lut.table.symmetry import phase_time_shift_s
from planner.config.scenario import load_scenario
from planner.errors import ConfigError, TargetStateError
from planner.model.rotation import axis_angle_to_matrix, matrix_to_quat, quat_to_matrix, rpy_to_matrix
from planner.model.target import TargetState, propagate

ROOT = Path(__file__).resolve().parents[3]
GRIDS = ROOT / "configs" / "grids"
SCEN_I = ROOT / "configs" / "scenarios" / "scenario_I.toml"
SCEN_II = ROOT / "configs" / "scenarios" / "scenario_II.toml"
BUNDLED = {"ci": 4, "ci_optimal": 4, "demo": 9, "flat_spin": 1092, "flat_spin_I_energy": 18, "flat_spin_II_energy": 18,
           "flat_spin_II_energy_fine": 30, "flat_spin_II_energy_finer": 54, "flat_spin_II_energy_axes": 81,
           "flat_spin_II_energy_rates": 153,
           "tumble": 1125, "envelope_flat_spin_I": 336, "envelope_flat_spin_II": 336,
           "envelope_flat_spin_II_coarse": 48, "envelope_tumble_I": 6000, "envelope_tumble_II": 6000}
# a three-axis flat-spin grid (3 rates × 2 spin-axis angles × 4 phases) owned by the tests
THREE_AXES = """
name = "three_axes"
scenario = "../scenarios/scenario_II.toml"
kind = "flat_spin"

[[axes]]
name = "spin_rate_deg_s"
min = 3.0
max = 4.0
count = 3

[[axes]]
name = "spin_axis_angle_deg"
min = 80.0
max = 90.0
count = 2

[[axes]]
name = "spin_phase_deg"
min = 0.0
max = 30.0
count = 4
"""


def _default(scenario) -> TargetState:
    return TargetState(scenario.target_state.attitude_wxyz, scenario.target_state.omega_body_rad_s)


@pytest.fixture(scope="module")
def scenarios():
    return {SCEN_I: load_scenario(SCEN_I), SCEN_II: load_scenario(SCEN_II)}


@pytest.fixture(scope="module")
def grids(scenarios):
    out = {}
    for name in BUNDLED:
        config = load_grid(GRIDS / f"{name}.toml")
        sc = scenarios.get(config.scenario_path) or load_scenario(config.scenario_path)
        out[name] = Grid(config, sc.target.inertia_body_kg_m2, _default(sc))
    config = load_grid_text(THREE_AXES, str(GRIDS / "three_axes.toml"))
    out["three_axes"] = Grid(config, scenarios[SCEN_II].target.inertia_body_kg_m2, _default(scenarios[SCEN_II]))
    return out


def _same_state(a: TargetState, b: TargetState) -> float:
    """Largest difference between two states (quaternions up to sign)."""
    dq = min(np.abs(a.attitude_wxyz - b.attitude_wxyz).max(), np.abs(a.attitude_wxyz + b.attitude_wxyz).max())
    return max(dq, np.abs(a.omega_body_rad_s - b.omega_body_rad_s).max())


# ---- configs ---------------------------------------------------------------------------------------


def test_bundled_configs_load_with_expected_sizes(grids):
    assert sorted(p.stem for p in GRIDS.glob("*.toml")) == sorted(BUNDLED)  # a new bundled grid is tested too
    for name, n in BUNDLED.items():
        g = grids[name]
        assert g.n_points == n == math.prod(g.shape), name
        assert g.config.scenario_path.is_file() and g.config.name == name
    assert grids["ci"].axis_names == ["spin_rate_deg_s", "spin_axis_angle_deg", "spin_phase_deg"]
    assert grids["ci"].shape == (2, 1, 2)  # the omitted spin-axis angle is a single value
    assert grids["tumble"].shape == (5, 5, 5, 1, 3, 3)


BASE = """
name = "t"
scenario = "{scenario}"
kind = "flat_spin"

[[axes]]
name = "spin_rate_deg_s"
min = 3.0
max = 4.0
count = 2

[[axes]]
name = "spin_phase_deg"
min = 0.0
max = 20.0
count = 2
"""

TUMBLE = """
name = "t"
scenario = "{scenario}"
kind = "tumble"

[[axes]]
name = "pitch_deg"
min = 0.0
max = 90.0
count = 2
"""


@pytest.mark.parametrize(("text", "old", "new", "field", "words"), [
    (BASE, 'name = "t"', 'name = "t"\ncolour = 1', "colour", "unknown field"),
    (BASE, 'kind = "flat_spin"', "", "kind", "missing"),
    (BASE, 'kind = "flat_spin"', 'kind = "spin"', "kind", "must be one of"),
    (BASE, 'name = "spin_rate_deg_s"', 'name = "spin_rate"', "axes[0].name", "unknown axis"),
    (BASE, 'name = "spin_rate_deg_s"', 'name = "roll_deg"', "axes[0].name", "unknown axis"),
    (BASE, 'name = "spin_phase_deg"', 'name = "spin_rate_deg_s"', "axes[1].name", "duplicate"),
    (BASE, "count = 2\n\n", "count = 0\n\n", "axes[0].count", ">= 1"),
    (BASE, "count = 2\n\n", 'count = "2"\n\n', "axes[0].count", "integer"),
    (BASE, "count = 2\n\n", "count = 2.5\n\n", "axes[0].count", "integer"),
    (BASE, "max = 4.0", "max = 2.0", "axes[0].max", "must be >= min"),
    (BASE, "count = 2\n\n", "count = 1\n\n", "axes[0].count", "min == max"),
    (BASE, "min = 3.0", "min = 0.0", "axes[0].min", "spin rate > 0"),
    (BASE, "max = 20.0", "max = 400.0", "axes[1].max", "< 360"),
    (BASE, "max = 4.0", "max = 4.0\nstep = 0.5", "axes[0].step", "unknown field"),
    (BASE, 'scenario = "{scenario}"', 'scenario = "nowhere.toml"', "scenario", "file not found"),
    (BASE, "[[axes]]", "[[axis]]", "axes", "missing"),
    (BASE, 'name = "t"', 'name = "t"\nname = "u"', "", "not valid TOML"),
    (TUMBLE, "", "", "axes[0].max", "(-90, 90)"),
])
def test_load_grid_errors_name_the_field(tmp_path, text, old, new, field, words):
    path = tmp_path / "grid.toml"
    body = text.replace(old, new) if old else text
    path.write_text(body.format(scenario=SCEN_II.as_posix()))
    with pytest.raises(ConfigError) as info:
        load_grid(path)
    assert info.value.field == field
    assert str(path) in str(info.value) and words in info.value.problem


def test_grid_config_errors_from_the_model(tmp_path, scenarios):
    sc_i, sc_ii = scenarios[SCEN_I], scenarios[SCEN_II]
    path = tmp_path / "grid.toml"
    path.write_text(BASE.format(scenario=SCEN_I.as_posix()))
    config = load_grid(path)
    # scenario I's default spins about the orbit normal y: no spin-axis angle in the x–z plane to fix
    with pytest.raises(ConfigError, match="spin_axis_angle_deg.*x–z plane") as info:
        Grid(config, sc_i.target.inertia_body_kg_m2, _default(sc_i))
    assert info.value.field == "axes"
    with pytest.raises(ConfigError, match="unique major axis") as info:
        Grid(config, np.diag([3000.0, 7000.0, 7000.0]), _default(sc_ii))
    assert info.value.field == "kind"


def test_load_grid_text_resolves_or_overrides_the_scenario(tmp_path):
    text = BASE.format(scenario="../configs/scenarios/scenario_II.toml")
    config = load_grid_text(text, str(ROOT / "tests" / "table.h5"))
    assert config.scenario_path == SCEN_II and config.text == text
    other = tmp_path / "elsewhere.toml"
    assert load_grid_text(text, str(tmp_path / "t.h5"), other).scenario_path == other
    with pytest.raises(ConfigError, match="file not found"):
        load_grid_text(text, str(tmp_path / "t.h5"))


# ---- indices, states and coordinates -----------------------------------------------------------------


def test_flat_indices_are_c_order(grids):
    g = grids["three_axes"]
    assert g.index_of(0) == (0, 0, 0) and g.index_of(1) == (0, 0, 1) and g.index_of(23) == (2, 1, 3)
    assert all(g.flat_of(g.index_of(p)) == p for p in range(g.n_points))
    np.testing.assert_array_equal(g.coordinates(g.flat_of((1, 0, 2))), [3.5, 80.0, 20.0])
    with pytest.raises(IndexError):
        g.index_of(24)
    with pytest.raises(IndexError):
        g.flat_of((3, 0, 0))


@pytest.mark.parametrize("name", ["demo", "three_axes", "tumble", "flat_spin"])
def test_state_to_coordinates_round_trip_on_every_point(grids, name):
    g = grids[name]
    for p in range(g.n_points):
        np.testing.assert_allclose(g.coordinates_of_state(g.state(p)), g.coordinates(p), rtol=0, atol=1e-9,
                                   err_msg=f"{name} point {p}")


def test_default_states_map_to_their_coordinates(grids, scenarios):
    # scenario II: identity attitude, 4 °/s about body z (major) → rate 4, spin axis +z (α = 90°), phase 0
    for name in ("ci", "flat_spin"):
        g = grids[name]
        default = _default(scenarios[SCEN_II])
        np.testing.assert_allclose(g.coordinates_of_state(default), [4.0, 90.0, 0.0], atol=1e-12)
        assert _same_state(g.state_at([4.0, 90.0, 0.0]), default) < 1e-15
    assert grids["ci"].axes[1] == Axis("spin_axis_angle_deg", 90.0, 90.0, 1)
    tumble = grids["tumble"]
    np.testing.assert_allclose(tumble.coordinates_of_state(_default(scenarios[SCEN_I])), [0, 4, 0, 0, 0, 0],
                               atol=1e-12)
    assert tumble.axes[3] == Axis("roll_deg", 0.0, 0.0, 1)


def test_flat_spin_states_spin_about_the_major_axis_in_the_orbital_plane(grids):
    g = grids["flat_spin"]
    e = np.array([0.0, 0.0, 1.0])  # scenario II: Izz = 7000 is the largest moment
    for p in range(0, g.n_points, 7):
        rate, alpha, phi = np.radians(g.coordinates(p))
        st = g.state(p)
        R = quat_to_matrix(st.attitude_wxyz)
        np.testing.assert_allclose(st.omega_body_rad_s, rate * e, atol=1e-15)
        np.testing.assert_allclose(R @ e, [np.cos(alpha), 0.0, np.sin(alpha)], atol=1e-12)
        # φ turns the body about the world spin axis: phase 0 → phase φ is R(s, φ)
        R0 = quat_to_matrix(g.state_at(np.degrees([rate, alpha, 0.0])).attitude_wxyz)
        np.testing.assert_allclose(R @ R0.T, axis_angle_to_matrix(R @ e, phi), atol=1e-12)
        assert propagate(g.inertia_body_kg_m2, st, 1.0).is_closed_form  # a steady (pure) spin


def test_flat_spin_with_a_rotated_principal_frame():
    # a target whose inertia is not diagonal: the major axis is the top eigenvector, signed positive
    Q = rpy_to_matrix([0.3, -0.5, 1.1])
    inertia = Q @ np.diag([300.0, 450.0, 200.0]) @ Q.T
    axes = (Axis("spin_rate_deg_s", 2.0, 4.0, 3), Axis("spin_axis_angle_deg", -30.0, 30.0, 3),
            Axis("spin_phase_deg", 0.0, 90.0, 4))
    config = GridConfig("mem", "", "rot", SCEN_II, "flat_spin", axes)
    g = Grid(config, inertia, TargetState([1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0]))  # default: not a flat spin
    e = Q[:, 1] * np.sign(Q[np.argmax(np.abs(Q[:, 1])), 1])
    np.testing.assert_allclose(g.major_axis_body, e, atol=1e-12)
    assert g.default_coordinates is None and g.seed_point() == g.flat_of((1, 1, 2))
    for p in range(g.n_points):
        st = g.state(p)
        rate, alpha, _ = np.radians(g.coordinates(p))
        np.testing.assert_allclose(st.omega_body_rad_s, rate * e, atol=1e-14)
        np.testing.assert_allclose(quat_to_matrix(st.attitude_wxyz) @ e, [np.cos(alpha), 0, np.sin(alpha)], atol=1e-12)
        np.testing.assert_allclose(g.coordinates_of_state(st), g.coordinates(p), atol=1e-9)


def test_states_that_are_not_grid_flat_spins_are_rejected(grids, scenarios):
    g = grids["three_axes"]
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    rate = np.radians(4.0)
    # within the 1e-6 rad tolerance: accepted
    tiny = TargetState(matrix_to_quat(axis_angle_to_matrix([1, 0, 0], 1e-8)), rate * np.array([1e-8, 0, 1]))
    np.testing.assert_allclose(g.coordinates_of_state(tiny), [4.0, 90.0, 0.0], atol=1e-5)
    cases = [
        (TargetState(q0, rate * np.array([1e-4, 0.0, 1.0])), "major principal axis"),
        (TargetState(q0, rate * np.array([0.0, 0.0, -1.0])), "-e"),
        (TargetState(q0, [0.0, 0.0, 0.0]), "does not rotate"),
        (TargetState(matrix_to_quat(axis_angle_to_matrix([1, 0, 0], 1e-4)), [0, 0, rate]), "x–z plane"),
        (SimpleNamespace(attitude_wxyz=q0, omega_body_rad_s=np.array([0.0, np.nan, rate])), "finite"),
        (SimpleNamespace(attitude_wxyz=np.array([np.inf, 0, 0, 0]), omega_body_rad_s=np.zeros(3)), "finite"),
    ]
    for state, words in cases:
        with pytest.raises(TargetStateError, match=words):
            g.coordinates_of_state(state)
    with pytest.raises(TargetStateError, match="pitch ±90"):
        grids["tumble"].coordinates_of_state(TargetState(matrix_to_quat(rpy_to_matrix([0, np.pi / 2, 0])), q0[1:]))


def test_angles_are_taken_in_the_axis_window(grids):
    g = grids["three_axes"]
    # a state of phase -20° is phase 340° (the window is [0, 360)); α is taken nearest the axis centre
    np.testing.assert_allclose(g.coordinates_of_state(g.state_at([3.2, 85.0 - 720.0, -20.0])), [3.2, 85.0, 340.0],
                               atol=1e-9)
    t = grids["tumble"]
    np.testing.assert_allclose(t.coordinates_of_state(t.state_at([1, 2, 3, 0.0, 10.0, 20.0 + 360.0])),
                               [1, 2, 3, 0, 10, 20], atol=1e-9)


def test_degenerate_states_are_answered_at_the_nearest_grid_coordinates(grids):
    """The states the strict inverse refuses (ω = 0, a spin about -e, a spin axis along the orbit normal,
    pitch exactly 90°) still get in-bounds coordinates with a note saying why: the query never fails on them."""
    g, t = grids["three_axes"], grids["tumble"]
    q0, rate = np.array([1.0, 0.0, 0.0, 0.0]), np.radians(4.0)
    h = math.sqrt(0.5)
    cases = [
        (g, TargetState(q0, [0.0, 0.0, 0.0]), ["does not rotate", "spin_rate_deg_s = 0 not in [3, 4]"],
         [3.0, 90.0, 0.0]),
        (g, TargetState(q0, rate * np.array([0.0, 0.0, -1.0])), ["-e"], [4.0, 90.0, 0.0]),
        (g, TargetState(matrix_to_quat(axis_angle_to_matrix([1, 0, 0], -np.pi / 2)), [0.0, 0.0, rate]),
         ["x–z plane"], None),  # s = +y: α is undefined, any in-bounds answer will do
        (t, TargetState(np.array([h, 0.0, h, 0.0]), np.radians([1.0, 2.0, 3.0])),
         ["pitch ±90", "pitch_deg = 90 not in [-30, 30]"], [1.0, 2.0, 3.0, 0.0, 30.0, 0.0]),
    ]
    for grid, state, words, expected in cases:
        projection = project_to_grid(grid, state)
        assert len(projection.notes) == len(words)
        for note, word in zip(projection.notes, words, strict=True):
            assert word in note
        for x, ax in zip(projection.coords, grid.axes, strict=True):
            assert ax.periodic or ax.min <= x <= ax.max, ax.name
        if expected is not None:
            np.testing.assert_allclose(projection.coords, expected, atol=1e-9)
        assert grid.locate(projection.coords).weights.sum() == pytest.approx(1.0)
    # at pitch 90° the family's coordinates (roll 0) are still the state's own attitude
    tilted = cases[-1][1]
    assert _same_state(t.state_at(t.family_coordinates(tilted)), tilted) < 1e-12


# ---- symmetry --------------------------------------------------------------------------------------


def test_phase_time_shift_values():
    assert phase_time_shift_s(0.0, 20.0, 4.0) == pytest.approx(5.0)
    assert phase_time_shift_s(350.0, 10.0, 4.0) == pytest.approx(5.0)
    assert phase_time_shift_s(20.0, 0.0, 4.0) == pytest.approx(85.0)
    assert phase_time_shift_s(10.0, 10.0, 4.0) == 0.0
    assert phase_time_shift_s(0.0, 740.0, 2.0) == pytest.approx(10.0)
    assert phase_time_shift_s(0.0, -1e-13, 4.0) == 0.0  # a full turn within round-off is no shift
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError):
            phase_time_shift_s(0.0, 10.0, bad)


def test_a_phase_offset_is_a_time_shift(grids):
    g = grids["three_axes"]
    for p in range(g.n_points):
        rate, alpha, phi0 = g.coordinates(p)
        for phi1 in (0.0, 10.0, 30.0, 200.0, phi0):
            dt = phase_time_shift_s(phi0, phi1, rate)
            assert 0.0 <= dt < 360.0 / rate
            traj = propagate(g.inertia_body_kg_m2, g.state(p), dt + 1.0)
            moved = TargetState(traj.attitude_wxyz(dt)[0], traj.omega_body(dt)[0])
            assert _same_state(moved, g.state_at([rate, alpha, phi1])) <= 1e-9, (p, phi1)
    # the same with the general integrator (no closed form), over most of a period
    rate, alpha, phi0 = g.coordinates(5)
    dt = phase_time_shift_s(phi0, phi0 - 30.0, rate)
    traj = propagate(g.inertia_body_kg_m2, g.state(5), dt + 1.0, force_integration=True)
    moved = TargetState(traj.attitude_wxyz(dt)[0], traj.omega_body(dt)[0])
    assert _same_state(moved, g.state_at([rate, alpha, phi0 - 30.0])) <= 1e-9


def _attitude_at(g: Grid, coords, t_s: float):
    """The target's attitude (wxyz) ``t_s`` [s] after the state at grid ``coords``."""
    traj = propagate(g.inertia_body_kg_m2, g.state_at(coords), t_s + 1.0)
    return traj.attitude_wxyz(t_s)[0]


@pytest.mark.parametrize("forward_turn", [False, True])
def test_a_plan_carried_to_another_rate_meets_the_target_at_the_same_angle(grids, forward_turn):
    """Oracle: the propagated spin. A plan made at (rate r₀, phase φ₀) meets the target m [s] after its observation;
    carried to (r₁, φ₁) it must meet the target in the same attitude. The phase shift alone misses by (r₀ − r₁)·m:
    30° for 0.5 °/s over 60 s, the handle 0.5 m away from where the arm reaches."""
    g = grids["three_axes"]
    meeting_s = 250.0  # late enough that every carried meeting (a forward turn is up to a period earlier) is after 0
    for a, b in [((3.0, 80.0, 0.0), (3.5, 80.0, 10.0)), ((4.0, 90.0, 30.0), (3.0, 90.0, 0.0)),
                 ((3.5, 80.0, 20.0), (3.5, 80.0, 359.0)), ((3.0, 90.0, 10.0), (4.0, 90.0, 10.0))]:
        shift = g.start_delay_shift_s(np.array(a), np.array(b), forward_turn=forward_turn, meeting_s=meeting_s)
        before, after = _attitude_at(g, a, meeting_s), _attitude_at(g, b, meeting_s + shift)
        assert min(np.linalg.norm(before - after), np.linalg.norm(before + after)) < 1e-9, (a, b)
        phase_only = g.start_delay_shift_s(np.array(a), np.array(b), forward_turn=forward_turn)
        assert shift - phase_only == pytest.approx((a[0] - b[0]) * meeting_s / b[0], abs=1e-12)


def test_a_plan_carried_to_its_own_rate_or_node_shifts_as_the_phase_alone(grids):
    """Same rate: the meeting time plays no part (bit for bit the phase shift); the node itself: no shift at all."""
    g = grids["three_axes"]
    a, b = np.array([3.5, 80.0, 10.0]), np.array([3.5, 80.0, 25.0])
    assert g.start_delay_shift_s(a, b, meeting_s=70.0) == g.start_delay_shift_s(a, b) == -15.0 / 3.5
    assert g.start_delay_shift_s(a, a, meeting_s=70.0) == 0.0
    # a non-positive target rate (no spin to carry along) and a meeting at the observation itself
    from lut.table.symmetry import start_delay_shift_s

    assert start_delay_shift_s(10.0, 25.0, 0.0, rate_from_deg_s=3.5, meeting_s=70.0) == 0.0
    assert start_delay_shift_s(10.0, 25.0, 3.0, rate_from_deg_s=4.0, meeting_s=0.0) == -15.0 / 3.0


# ---- cells -----------------------------------------------------------------------------------------


def _check_cell(g: Grid, coords) -> None:
    cell = g.locate(coords)
    d = sum(ax.count > 1 for ax in g.axes)
    assert len(cell.corners) == 2**d == len(cell.weights) == len(cell.corner_coords)
    assert np.all(cell.weights >= 0) and cell.weights.sum() == pytest.approx(1.0, abs=1e-12)
    varying = [i for i, ax in enumerate(g.axes) if ax.count > 1]
    np.testing.assert_allclose((cell.weights @ cell.corner_coords)[varying], cell.coords[varying], atol=1e-9)
    for corner, cc in zip(cell.corners, cell.corner_coords, strict=True):
        diff = g.coordinates(corner) - cc
        diff[[i for i, ax in enumerate(g.axes) if ax.periodic]] %= 360.0
        np.testing.assert_allclose(diff, 0.0, atol=1e-9)
    shift = np.asarray(coords, dtype=float) - cell.coords  # only the phase may move, by whole turns
    np.testing.assert_allclose(np.round(shift / 360.0) * 360.0, shift, atol=1e-9)


def test_locate_interpolates_inside_cells(grids):
    rng = np.random.default_rng(7)
    g = grids["three_axes"]
    for _ in range(200):
        _check_cell(g, [rng.uniform(3, 4), rng.uniform(80, 90), rng.uniform(-720, 720)])
    t = grids["tumble"]
    for _ in range(50):
        _check_cell(t, [*rng.uniform(-4, 4, 3), 0.0, rng.uniform(-30, 30), rng.uniform(-30, 30)])
    _check_cell(grids["ci"], [3.7, 90.0, 5.0])  # α is single-valued there: 4 corners
    # on a grid point, all of the weight is on it
    for p in (0, 7, 23):
        cell = g.locate(g.coordinates(p))
        assert cell.weights[cell.corners.index(p)] == pytest.approx(1.0)


def test_locate_wraps_the_phase(grids):
    g = grids["three_axes"]  # phases 0, 10, 20, 30: between 30 and 360 the cell wraps to 0
    cell = g.locate([3.5, 90.0, 200.0])
    phases = {g.coordinates(c)[2] for c in cell.corners}
    assert phases == {30.0, 0.0}
    w30 = sum(w for c, w in zip(cell.corners, cell.weights, strict=True) if g.coordinates(c)[2] == 30.0)
    assert w30 == pytest.approx(160.0 / 330.0)
    same = g.locate([3.5, 90.0, 200.0 - 3 * 360.0])
    assert same.corners == cell.corners and np.allclose(same.weights, cell.weights)
    assert g.locate([3.5, 90.0, 365.0]).corners == g.locate([3.5, 90.0, 5.0]).corners


def test_locate_outside_the_grid_names_the_axis(grids):
    g = grids["three_axes"]
    with pytest.raises(TargetStateError, match=r"outside the grid: spin_rate_deg_s = 5.2 not in \[3, 4\]"):
        g.locate([5.2, 85.0, 0.0])
    with pytest.raises(TargetStateError, match="spin_axis_angle_deg = 95 not in"):
        g.locate(g.coordinates_of_state(g.state_at([3.5, 95.0, 0.0])))
    with pytest.raises(TargetStateError, match="spin_axis_angle_deg = 80 .*fixes this axis at 90"):
        grids["ci"].locate([3.7, 80.0, 0.0])
    with pytest.raises(TargetStateError, match="omega_z_deg_s"):
        grids["tumble"].locate([0, 0, -4.5, 0, 0, 0])
    with pytest.raises(TargetStateError, match="spin_phase_deg = nan"):
        g.locate([3.5, 85.0, np.nan])
    with pytest.raises(TargetStateError, match="not finite"):
        g.locate([np.inf, 85.0, 0.0])


# ---- continuation ----------------------------------------------------------------------------------


def test_neighbours_are_axis_adjacent(grids):
    g = grids["three_axes"]
    assert g.neighbours(g.flat_of((1, 0, 1))) == sorted(
        g.flat_of(i) for i in [(0, 0, 1), (2, 0, 1), (1, 1, 1), (1, 0, 0), (1, 0, 2)])
    assert g.flat_of((1, 0, 0)) not in g.neighbours(g.flat_of((1, 0, 3)))  # 30 → 0 is a 330° gap
    f = grids["flat_spin"]  # phases every 30° over the full turn: 330 and 0 are neighbours
    assert f.flat_of((4, 3, 0)) in f.neighbours(f.flat_of((4, 3, 11)))


@pytest.mark.parametrize("name", list(BUNDLED))
def test_continuation_order_covers_every_point_after_its_parent(grids, name):
    g = grids[name]
    order = g.continuation_order()
    assert sorted(p for p, _ in order) == list(range(g.n_points))
    seed, parent = order[0]
    assert parent is None and seed == g.seed_point()
    position = {p: k for k, (p, _) in enumerate(order)}
    for k, (p, parent) in enumerate(order[1:], start=1):
        assert parent is not None and position[parent] < k and parent in g.neighbours(p), (p, parent)
    assert g.continuation_order() == order  # deterministic
    if g.kind == "flat_spin" and g.default_coordinates is not None:  # the scenario default: 4 °/s about +z, phase 0
        np.testing.assert_allclose(g.default_coordinates, [4.0, 90.0, 0.0])
        # the seed is the default where it is a grid point, else a point nearest to it (flat_spin_II_energy: α 85 or 95)
        gaps = [g.normalised_distance(g.coordinates(p), g.default_coordinates) for p in range(g.n_points)]
        assert gaps[seed] == min(gaps)
        assert (min(gaps) == 0) == all(x in v for x, v in zip(g.default_coordinates, g.axis_values, strict=True))
    elif g.default_coordinates is None:  # scenario I's default spins about the orbit normal: the grid's centre
        assert g.index_of(seed) == tuple(n // 2 for n in g.shape)


def _full_turn_grid(scenarios, axes: dict[str, tuple[float, float, int]], kind: str = "flat_spin") -> Grid:
    text = f'name = "full_turn"\nscenario = "../scenarios/scenario_II.toml"\nkind = "{kind}"\n' + "".join(
        f'\n[[axes]]\nname = "{n}"\nmin = {lo}\nmax = {hi}\ncount = {c}\n' for n, (lo, hi, c) in axes.items())
    sc = scenarios[SCEN_II]
    return Grid(load_grid_text(text, str(GRIDS / "full_turn.toml")), sc.target.inertia_body_kg_m2, _default(sc))


def test_an_angle_round_the_whole_turn_wraps_like_the_phase(scenarios, grids):
    """The spin axis anywhere in the orbital plane (paper §3): α every 30° round the turn; 330° and 0° enclose a
    cell, so no α is beyond the grid and 359.999° sits next to 0°. A partial α range stays bounded."""
    g = _full_turn_grid(scenarios, {"spin_rate_deg_s": (3.0, 4.0, 2), "spin_axis_angle_deg": (0.0, 330.0, 12),
                                    "spin_phase_deg": (0.0, 270.0, 4)})
    alpha = g.axes[1]
    assert alpha.periodic and not grids["three_axes"].axes[1].periodic and not grids["flat_spin"].axes[1].periodic
    cell = g.locate([3.5, 350.0, 0.0])
    w = {g.coordinates(c)[1]: 0.0 for c in cell.corners}
    for c, wc in zip(cell.corners, cell.weights, strict=True):
        w[g.coordinates(c)[1]] += wc
    assert w == pytest.approx({330.0: 1.0 / 3.0, 0.0: 2.0 / 3.0})
    _check_cell(g, [3.5, 350.0, 0.0])
    before, after = g.locate([3.5, 359.999, 0.0]), g.locate([3.5, -0.001, 0.0])
    assert before.corners == after.corners and np.allclose(before.weights, after.weights)
    for a in (345.0, 359.999, 15.0):  # a state anywhere round the turn is answered where it is, without a note
        projection = project_to_grid(g, g.state_at([3.5, a, 100.0]))
        assert projection.notes == ()
        np.testing.assert_allclose(projection.coords, [3.5, a, 100.0], atol=1e-7)
    assert g.flat_of((0, 0, 0)) in g.neighbours(g.flat_of((0, 11, 0)))  # 330° → 0° is one step


def test_roll_and_yaw_round_the_whole_turn_wrap_and_pitch_never_does(scenarios):
    t = _full_turn_grid(scenarios, {"omega_x_deg_s": (-4.0, 4.0, 2), "roll_deg": (-180.0, 150.0, 12),
                                    "pitch_deg": (-60.0, 60.0, 3), "yaw_deg": (-180.0, 135.0, 8)}, kind="tumble")
    periodic = {ax.name: ax.periodic for ax in t.axes if ax.count > 1}
    assert periodic == {"omega_x_deg_s": False, "roll_deg": True, "pitch_deg": False, "yaw_deg": True}
    _check_cell(t, [1.0, 0.0, 4.0, 175.0, 10.0, 170.0])
    cell = t.locate([1.0, 0.0, 4.0, 179.999, 10.0, -179.999])
    rolls = {t.coordinates(c)[3] for c in cell.corners}
    yaws = {t.coordinates(c)[5] for c in cell.corners}
    assert rolls == {150.0, -180.0} and yaws == {-180.0, -135.0}  # 179.999° wraps next to -180°; -179.999° is there


def test_point_at_finds_a_grid_point_within_the_tolerance_and_across_the_phase_wrap(grids):
    g = grids["three_axes"]  # rates 3, 3.5, 4; axes 80, 90; phases 0, 10, 20, 30
    assert g.point_at([3.5, 90.0, 20.0]) == g.flat_of((1, 1, 2))
    assert g.point_at([3.0 - 0.9e-6, 80.0 + 0.9e-6, 30.0 + 0.9e-6]) == g.flat_of((0, 0, 3))  # touching: on it
    assert g.point_at([4.0, 80.0, 360.0]) == g.flat_of((2, 0, 0))  # a whole turn is the same phase
    assert g.point_at([4.0, 80.0, -0.5e-6]) == g.flat_of((2, 0, 0))  # just below 0° is 0°, not 359.9999995°
    for off in ([3.0 - 1.1e-6, 80.0, 0.0], [3.25, 80.0, 0.0], [3.0, 85.0, 0.0], [3.0, 80.0, 5.0], [3.0, 80.0, 180.0]):
        assert g.point_at(off) is None, off
    demo = grids["demo"]  # its spin axis fixed at one value
    fixed = [i for i, ax in enumerate(demo.axes) if ax.count == 1]
    assert fixed, "the demo grid fixes an axis"
    on = demo.coordinates(0)
    assert demo.point_at(on) == 0
    on[fixed[0]] += 1.0
    assert demo.point_at(on) is None
    assert all(g.point_at(g.coordinates(p)) == p for p in range(g.n_points))
