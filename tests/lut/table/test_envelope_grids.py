"""The bundled envelope grids (configs/grids/envelope_*.toml) hold every state of the paper's envelope (§3).

A flat spin at 1–4 °/s about the major axis, its axis anywhere in the orbital x–z plane, at any phase, must lie
inside its grid (no axis clamped); a general tumble within ±4 °/s per body axis at any attitude is inside but for
its pitch, which beyond ±60° is answered at the edge, never more than 30° away. The states are built here from
the envelope's definition (scipy rotations), not with the grid's own state maps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lut.table.grid import Grid
from lut.table.grid_config import load_grid
from lut.table.grid_projection import project_to_grid
from planner.config.scenario import load_scenario
from planner.model.target import TargetState

GRIDS = Path(__file__).resolve().parents[3] / "configs" / "grids"
FLAT_SPIN = ("envelope_flat_spin_I", "envelope_flat_spin_II", "envelope_flat_spin_II_coarse")
TUMBLE = ("envelope_tumble_I", "envelope_tumble_II")
PITCH_EDGE_DEG = 60.0


def _grid(name: str) -> Grid:
    config = load_grid(GRIDS / f"{name}.toml")
    scenario = load_scenario(config.scenario_path)
    default = TargetState(scenario.target_state.attitude_wxyz, scenario.target_state.omega_body_rad_s)
    return Grid(config, scenario.target.inertia_body_kg_m2, default)


def _wxyz(rotation: Rotation) -> np.ndarray:
    x, y, z, w = rotation.as_quat()
    return np.array([w, x, y, z])


def _flat_spin(grid: Grid, rate_deg_s: float, axis_deg: float, phase_deg: float) -> TargetState:
    """Spin at ``rate_deg_s`` about the major axis, which points along (cos α, 0, sin α) in the orbital frame."""
    e_body = grid.major_axis_body
    s_orbit = np.array([np.cos(np.radians(axis_deg)), 0.0, np.sin(np.radians(axis_deg))])
    align, _ = Rotation.align_vectors([s_orbit], [e_body])
    attitude = Rotation.from_rotvec(np.radians(phase_deg) * s_orbit) * align
    return TargetState(_wxyz(attitude), np.radians(rate_deg_s) * e_body)


def _flat_spins(grid: Grid) -> list[tuple[float, float, float]]:
    """Seeded states and the degenerate ones: the rate bounds exactly, angles next to the whole turn."""
    rng = np.random.default_rng(20)
    drawn = [(rng.uniform(1.0, 4.0), rng.uniform(0.0, 360.0), rng.uniform(0.0, 360.0)) for _ in range(40)]
    edges = [(1.0, 0.0, 0.0), (4.0, 359.999, 359.999), (4.0, 180.0, 180.0), (1.0, 90.0, 270.0),
             (2.5, 330.0, 0.001), (2.5, -0.001, 90.0)]
    return drawn + edges


@pytest.mark.parametrize("name", FLAT_SPIN)
def test_every_flat_spin_of_the_envelope_is_inside_its_grid(name):
    grid = _grid(name)
    for rate, axis, phase in _flat_spins(grid):
        projection = project_to_grid(grid, _flat_spin(grid, rate, axis, phase))
        assert projection.notes == (), (rate, axis, phase, projection.notes)
        assert projection.coords[0] == pytest.approx(rate, abs=1e-9)
        assert (projection.coords[1] - axis + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-7)
        grid.locate(projection.coords)  # a cell encloses it: no bound is crossed


def _tumbles() -> list[TargetState]:
    rng = np.random.default_rng(21)
    drawn = [TargetState(_wxyz(Rotation.random(random_state=rng)), np.radians(rng.uniform(-4.0, 4.0, 3)))
             for _ in range(60)]
    corner = np.radians([4.0, -4.0, 4.0])
    edges = [TargetState(_wxyz(Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True)), corner)
             for yaw, pitch, roll in [(359.999, 0.0, 359.999), (0.0, 89.9, 0.0), (180.0, -89.9, 90.0),
                                      (270.0, 60.0, 270.0), (0.001, -60.0, 180.0)]]
    return drawn + edges


@pytest.mark.parametrize("name", TUMBLE)
def test_every_tumble_of_the_envelope_is_inside_its_grid_but_for_a_steep_pitch(name):
    grid = _grid(name)
    pitch = grid.axis_names.index("pitch_deg")
    clamped = 0
    for state in _tumbles():
        own = grid.family_coordinates(state)
        projection = project_to_grid(grid, state)
        assert np.allclose(projection.coords[:3], np.degrees(state.omega_body_rad_s))
        if abs(own[pitch]) <= PITCH_EDGE_DEG + 1e-6:  # the grid takes its bounds to 1e-6
            assert projection.notes == (), projection.notes
        else:
            clamped += 1
            assert len(projection.notes) == 1 and "pitch_deg" in projection.notes[0]
            assert abs(projection.coords[pitch]) == PITCH_EDGE_DEG
            assert abs(own[pitch] - projection.coords[pitch]) < 30.0
        grid.locate(projection.coords)
    assert clamped >= 2  # the steep-pitch edge cases above were clamped
