"""A tumble table's plans keep their start: a tumble never repeats its attitude, so no spin period moves them.

Once a tumble table's query moved every plan by 2π/|ω| (a flat spin's period) into [0, 2π/|ω|): at its own grid
point (4, 4, 4) °/s, whose plan starts at 77 s (2π/|ω| = 52 s), the stored plan was simulated at 25.5 s, 0.9 m from the
handle at the grasp, and the answer was INFEASIBLE after a refine."""

from __future__ import annotations

from pathlib import Path

import pytest

from lut.query.result import QuerySource
from lut.query.table_query import TableQuery
from tests.support.cli import lutgen_in_process

ROOT = Path(__file__).resolve().parents[3]
AXES = {"omega_x_deg_s": 4.0, "omega_y_deg_s": 4.0, "omega_z_deg_s": 4.0, "roll_deg": 0.0, "pitch_deg": 0.0,
        "yaw_deg": 0.0}


@pytest.fixture(scope="module")
def tumble_table(tmp_path_factory) -> Path:
    """A one-point scenario I tumble table at (4, 4, 4) °/s, attitude identity (seconds to build)."""
    folder = tmp_path_factory.mktemp("tumble")
    scenario = (ROOT / "configs" / "scenarios" / "scenario_I.toml").as_posix()
    axes = "".join(f'[[axes]]\nname = "{n}"\nmin = {v}\nmax = {v}\ncount = 1\n' for n, v in AXES.items())
    grid = folder / "tumble1.toml"
    grid.write_text(f'name = "tumble1"\nscenario = "{scenario}"\nkind = "tumble"\n{axes}')
    out = folder / "tumble1.h5"
    built = lutgen_in_process("build", grid, "--out", out, "--no-progress")
    assert built.returncode == 0, built.stderr
    return out


def test_a_tumble_tables_query_at_its_own_point_answers_with_its_plan_as_stored(tumble_table):
    tq = TableQuery(tumble_table)
    stored = tq.points[0].parameters
    state = tq.grid.state_at(tq.grid.coordinates(0))
    assert stored is not None and stored.approach.start_delay_s > 60.0  # later than 2π/|ω| = 52 s: the case at stake
    result = tq.query(state, budget_s=100.0)
    assert result.source is QuerySource.INTERPOLATED and result.report.feasible
    assert result.plan.approach.start_delay_s == stored.approach.start_delay_s
