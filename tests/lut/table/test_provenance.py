"""The ``reused_from`` attribute read back: a table a --reuse build wrote names its sources; a damaged one is refused
in one line naming the attribute, like any other corrupt field."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from lut.table.provenance import ReusedSource, provenance_text, reused_sources
from lut.table.schema import TableError
from lut.table.store import Table
from lut.table.table_writer import write_table

SOURCES = (ReusedSource("../a.h5", "2026-12-05T05:00:00+00:00", (0, 2)),
           ReusedSource("b.h5", "2026-12-04T18:17:00+00:00", ()))


def _table(path: Path, reused_from: str | None) -> Path:
    records = {p: {"point": p, "status": "infeasible", "failure_reason": "x", "solve_time_s": 1.0, "iterations": 3}
               for p in range(3)}
    write_table(path, grid_axes=[("spin_rate_deg_s", [1.0, 2.0, 3.0])], grid_kind="flat_spin", config_text="c",
                scenario_text="s", model_hash="h", records=records, n_points=3, reused_from=reused_from)
    return path


def test_the_sources_written_are_the_sources_read_and_a_table_without_them_has_none(tmp_path):
    assert Table.open(_table(tmp_path / "t.h5", provenance_text(SOURCES))).reused_from == SOURCES
    assert Table.open(_table(tmp_path / "u.h5", None)).reused_from == ()
    with h5py.File(tmp_path / "u.h5", "r") as f:
        assert "reused_from" not in f.attrs


@pytest.mark.parametrize(("text", "why"), [
    ("not json", "not a list"),
    ('{"table": "a.h5"}', "not a list"),
    ('[{"table": "a.h5", "points": [0]}]', "not a list"),  # no created_utc
    ('[{"table": 3, "created_utc": "t", "points": [0]}]', "not a list"),
    ('[{"table": "a.h5", "created_utc": "t", "points": [3]}]', "not a list"),  # one past the last point
    ('[{"table": "a.h5", "created_utc": "t", "points": [-1]}]', "not a list"),
    ('[{"table": "a.h5", "created_utc": "t", "points": [true]}]', "not a list"),
    ('[{"table": "a.h5", "created_utc": "t", "points": [1.0]}]', "not a list"),
    ('[{"table": "a.h5", "created_utc": "t", "points": [1]}, {"table": "b.h5", "created_utc": "t", "points": [1]}]',
     "more than one table"),
])
def test_a_damaged_attribute_is_one_table_error_naming_it(tmp_path, text, why):
    with pytest.raises(TableError, match=f"reused_from .*{why}") as err:
        Table.open(_table(tmp_path / "t.h5", text))
    assert str(tmp_path / "t.h5") in str(err.value) and "\n" not in str(err.value)


def test_the_last_point_and_an_empty_list_are_accepted():
    text = json.dumps([{"table": "a.h5", "created_utc": "t", "points": [2, 0]}])
    assert reused_sources(Path("t.h5"), text, 3) == (ReusedSource("a.h5", "t", (2, 0)),)
    assert reused_sources(Path("t.h5"), "[]", 3) == ()


def test_an_attribute_that_is_not_text_is_refused(tmp_path):
    path = _table(tmp_path / "t.h5", None)
    with h5py.File(path, "a") as f:
        f.attrs["reused_from"] = 7
    with pytest.raises(TableError, match="reused_from must be text"):
        Table.open(path)
