"""The build journal (crash-safe, checksummed) and the HDF5 look-up table (schema, atomic write, errors)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from importlib.metadata import version
from pathlib import Path

import h5py
import numpy as np
import pytest

from lut.table import table_writer
from lut.table.journal import Journal
from lut.table.journal_format import MAGIC
from lut.table.model_identity import model_hash
from lut.table.schema import SCHEMA_VERSION, STATUS_CODES, TableError
from lut.table.store import Table
from lut.table.table_writer import write_table

ROOT = Path(__file__).resolve().parents[3]
HEADER = {"model_hash": "0123abcd" * 8, "grid_text": "name = 'g'\n"}


def _bits_equal(a, b) -> bool:
    """Same dtype, shape and bytes (NaN payloads and signed zeros included)."""
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _assert_records_equal(got: dict, want: dict) -> None:
    assert list(got) == list(want)
    for key, value in want.items():
        if isinstance(value, np.ndarray | np.generic):
            assert type(got[key]) is type(value), key
            assert _bits_equal(got[key], value), key
        elif isinstance(value, float):
            assert type(got[key]) is float and _bits_equal(got[key], value), key
        else:
            assert type(got[key]) is type(value) and got[key] == value, key


def _record(point: int, status: str = "feasible") -> dict:
    rng = np.random.default_rng(point)
    params = rng.standard_normal(35)
    params[:4] = [np.nan, -0.0, np.inf, 5e-324]  # NaN, signed zero, inf, subnormal survive bit for bit
    return {
        "point": point, "status": status,
        "failure_reason": "" if status == "feasible" else f"Kollision Δ point {point}",
        "solve_time_s": float(rng.uniform(10, 90)), "iterations": int(rng.integers(5, 500)),
        "approach_params": params, "base_offset_m": rng.standard_normal(2), "start_delay_s": float(rng.uniform(0, 50)),
        "q_tracking": rng.standard_normal((3, 7)), "stabilization_params": rng.standard_normal(14),
        "free_axis_angle_rad": 0.1 * point, "costs/min_distance_m": float(rng.uniform(0, 1)),
        "costs/approach_energy_m2": float(rng.uniform(0, 1)), "margins/collision": float(rng.uniform(-1, 1)),
    }


# ---- journal ----------------------------------------------------------------------------------


def test_journal_round_trip_is_bit_identical(tmp_path):
    path = tmp_path / "t.h5.journal"
    odd = {"point": 7, "status": "failed", "failure_reason": "worker crashed (signal 9): ünïcødé ✓\nline 2",
           "flag": True, "count": -3, "big": 2**62, "np_scalar": np.float32(1.5), "np_int": np.int16(-7),
           "ints": np.arange(6, dtype=np.int32).reshape(2, 3), "mask": np.array([True, False]),
           "big_endian": np.arange(3, dtype=">f8"), "empty": np.zeros((0, 4)), "zero_d": np.array(2.5)}
    written = [_record(0), _record(1, "infeasible"), odd, _record(0, "failed")]  # point 0 twice: last one wins
    with Journal(path, HEADER) as j:
        for rec in written:
            j.append(rec)
        in_process = j.records()
    with Journal(path, HEADER) as j:
        reread = j.records()
        assert j.ignored_bytes == 0
    assert sorted(reread) == [0, 1, 7]
    for got in (in_process, reread):
        _assert_records_equal(got[0], written[3])
        _assert_records_equal(got[1], written[1])
        big = got[7].pop("big_endian")
        assert big.dtype == np.dtype("<f8") and np.array_equal(big, [0.0, 1.0, 2.0])  # stored little-endian
        _assert_records_equal(got[7], {k: v for k, v in odd.items() if k != "big_endian"})
    assert path.read_bytes().startswith(MAGIC)


def test_journal_keeps_each_points_first_record_and_knows_which_were_journaled_again(tmp_path):
    path = tmp_path / "t.h5.journal"
    first = [_record(0), _record(1, "infeasible"), _record(2)]
    again = [_record(1), _record(2, "failed"), _record(2, "infeasible")]  # point 2 three times
    with Journal(path, HEADER) as j:
        for rec in first:
            j.append(rec)
        assert j.journaled_again() == set()
        for rec in again:
            j.append(rec)
        in_process = (j.first_records(), j.journaled_again(), j.records())
    with Journal(path, HEADER) as j:  # the same after a reopen (a resumed build)
        reread = (j.first_records(), j.journaled_again(), j.records())
    for firsts, journaled_again, lasts in (in_process, reread):
        assert journaled_again == {1, 2}
        for p in range(3):
            _assert_records_equal(firsts[p], first[p])
        _assert_records_equal(lasts[1], again[0])
        _assert_records_equal(lasts[2], again[2])
        _assert_records_equal(lasts[0], first[0])


@pytest.mark.parametrize("damage", ["cut_3_bytes", "cut_to_frame_head", "garbage_tail", "flipped_byte"])
def test_journal_torn_last_frame_is_ignored_then_cut_before_appending(tmp_path, damage):
    path = tmp_path / "j"
    with Journal(path, HEADER) as j:
        j.append(_record(0))
        j.append(_record(1))
        size_two = path.stat().st_size
        j.append(_record(2))
    data = path.read_bytes()
    if damage == "cut_3_bytes":
        data = data[:-3]
    elif damage == "cut_to_frame_head":
        data = data[:size_two + 20]  # the last frame's length and half its checksum only
    elif damage == "garbage_tail":
        data = data + b"\x07garbage that is not a frame" * 3
    else:
        data = data[:-10] + bytes([data[-10] ^ 0x40]) + data[-9:]
    path.write_bytes(data)
    with Journal(path, HEADER) as j:
        recs = j.records()
        expected = [0, 1, 2] if damage == "garbage_tail" else [0, 1]
        assert sorted(recs) == expected
        for p in expected:
            _assert_records_equal(recs[p], _record(p))
        assert j.ignored_bytes > 0
        j.append(_record(3, "failed"))  # appending after the cut works
    with Journal(path, HEADER) as j:
        assert sorted(j.records()) == [*expected, 3]
        assert j.ignored_bytes == 0
        _assert_records_equal(j.records()[3], _record(3, "failed"))


def test_journal_for_another_config_is_refused(tmp_path):
    path = tmp_path / "j"
    with Journal(path, HEADER) as j:
        j.append(_record(0))
    with pytest.raises(TableError, match=r"was written for a different config \(hash [0-9a-f]{12}.*model_hash"):
        Journal(path, {**HEADER, "model_hash": "f" * 64})
    with Journal(path, HEADER) as j:  # untouched by the refused open
        assert sorted(j.records()) == [0]


def test_journal_rejects_bad_records_and_foreign_files(tmp_path):
    path = tmp_path / "j"
    with Journal(path, HEADER) as j:
        size = path.stat().st_size
        for bad in ({"status": "feasible"}, {"point": 1}, {"point": True, "status": "feasible"},
                    {"point": 1, "status": "feasible", "x": object()},
                    {"point": 1, "status": "feasible", "x": np.array(["a", "b"])},
                    {"point": 1, "status": "feasible", "x": [1.0, 2.0]}):
            with pytest.raises(TableError):
                j.append(bad)
        assert path.stat().st_size == size and j.records() == {}
    other = tmp_path / "not-a-journal"
    other.write_bytes(b"PK\x03\x04 something else")
    with pytest.raises(TableError, match="not a lutgen journal"):
        Journal(other, HEADER)


@pytest.mark.skipif(os.name != "posix", reason="flock is POSIX")
def test_journal_is_locked_against_a_second_writer(tmp_path):
    path = tmp_path / "j"
    with Journal(path, HEADER):
        with pytest.raises(TableError, match="in use by another build"):
            Journal(path, HEADER)
    Journal(path, HEADER).close()  # released on close


CRASH_RECORD = """
import numpy as np

def crash_record(point):
    rng = np.random.default_rng(point)
    n = int(rng.integers(1, 2000))  # up to 16 kB (the file stays small)
    return {"point": point, "status": "feasible", "values": rng.standard_normal(n), "n": n, "tag": f"p{point}"}
"""

CRASH_WRITER = CRASH_RECORD + """
import sys
from pathlib import Path
from lut.table.journal import Journal

journal = Journal(Path(sys.argv[1]), {"model_hash": "crash-test"})
point = len(journal.records())
print("ready", point, flush=True)
while True:
    journal.append(crash_record(point))
    point += 1
"""


@pytest.mark.skipif(os.name != "posix", reason="SIGKILL")
def test_journal_survives_sigkill_at_random_moments(tmp_path):
    namespace: dict = {}
    exec(CRASH_RECORD, namespace)
    crash_record = namespace["crash_record"]
    path = tmp_path / "crash.journal"
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    rng = np.random.default_rng(20240601)
    counts = [0]
    for _ in range(3):
        proc = subprocess.Popen([sys.executable, "-c", CRASH_WRITER, str(path)], stdout=subprocess.PIPE, env=env)
        try:
            ready = proc.stdout.readline().split()
            assert ready[0] == b"ready" and int(ready[1]) == counts[-1]  # the writer saw every earlier record
            proc.stdout.close()
            time.sleep(float(rng.uniform(0.15, 0.6)))
        finally:
            proc.kill()  # SIGKILL: no cleanup, possibly mid-write
            proc.wait()
        assert proc.returncode == -9
        with Journal(path, {"model_hash": "crash-test"}) as j:
            recs = j.records()
        assert sorted(recs) == list(range(len(recs)))  # no hole: records are appended in order
        for p, rec in recs.items():
            _assert_records_equal(rec, crash_record(p))  # intact and complete (checksummed)
        assert len(recs) >= counts[-1]
        counts.append(len(recs))
    assert counts[-1] > 0, counts


# ---- table --------------------------------------------------------------------------------------

AXES = [("spin_rate_deg_s", np.array([3.0, 3.5, 4.0])), ("spin_phase_deg", np.array([0.0, 15.0]))]
N = 6


def _records() -> dict[int, dict]:
    recs = {0: _record(0), 1: _record(1, "infeasible"), 4: _record(4)}
    recs[2] = {"point": 2, "status": "failed", "failure_reason": "timeout: exceeded --point-timeout 900 s",
               "solve_time_s": 900.5, "iterations": 0}
    recs[5] = {**_record(5), "margins/late_key": 0.25}  # first seen at the last point
    return recs  # point 3 pending


def _write(path: Path, records: dict | None = None, **kw) -> None:
    args = {"grid_axes": AXES, "grid_kind": "flat_spin", "config_text": "name = 'test'\n",
            "scenario_text": "[robot]\n", "model_hash": model_hash("<robot/>", "[target]", "[robot]\n"),
            "records": _records() if records is None else records, "n_points": N}
    write_table(path, **{**args, **kw})


def test_table_round_trip(tmp_path):
    path = tmp_path / "t.h5"
    recs = _records()
    _write(path, scenario_path="configs/scenarios/scenario_II.toml")
    assert not path.with_name("t.h5.tmp").exists()
    t = Table.open(path)
    assert t.n_points == N and t.axis_names == ["spin_rate_deg_s", "spin_phase_deg"]
    assert all(_bits_equal(got, want) for got, (_, want) in zip(t.axis_values, AXES, strict=True))
    assert t.attrs["schema_version"] == SCHEMA_VERSION == 1
    assert t.attrs["lutgen_version"] == version("lutgen")
    assert t.attrs["config_text"] == "name = 'test'\n" and t.attrs["scenario_text"] == "[robot]\n"
    assert t.attrs["grid_kind"] == "flat_spin" and t.attrs["scenario_path"] == "configs/scenarios/scenario_II.toml"
    assert t.model_hash == model_hash("<robot/>", "[target]", "[robot]\n") and len(t.model_hash) == 64
    assert t.attrs["created_utc"].endswith("+00:00")
    assert t.status.dtype == np.int8 and t.status.tolist() == [1, 2, 3, 0, 1, 1]
    assert t.counts() == {"pending": 1, "feasible": 3, "infeasible": 1, "failed": 1}
    # datasets: (n_points, *value shape), NaN / -1 / "" where a point has no value
    assert t.field("approach_params").shape == (N, 35) and t.field("q_tracking").shape == (N, 3, 7)
    assert t.field("base_offset_m").shape == (N, 2) and t.field("start_delay_s").shape == (N,)
    assert np.isnan(t.field("approach_params")[[2, 3]]).all()
    assert t.field("iterations").tolist() == [recs[0]["iterations"], recs[1]["iterations"], 0, -1,
                                              recs[4]["iterations"], recs[5]["iterations"]]
    assert t.field("failure_reason")[3] == "" and t.field("failure_reason")[1] == "Kollision Δ point 1"
    assert np.isnan(t.field("margins/late_key")[:5]).all() and t.field("margins/late_key")[5] == 0.25
    assert t.has_field("costs/min_distance_m") and not t.has_field("costs/nope")
    with pytest.raises(TableError, match="no field 'costs/nope'"):
        t.field("costs/nope")
    # every record comes back bit-identical (plus the missing values of keys other points have)
    for p, want in recs.items():
        got = t.record(p)
        _assert_records_equal({k: got[k] for k in want}, want)
    pending = t.record(3)
    assert pending["status"] == "pending" and pending["iterations"] == -1 and np.isnan(pending["start_delay_s"])
    # plain h5py sees the documented layout
    with h5py.File(path, "r") as f:
        assert isinstance(f["points/costs"], h5py.Group)
        assert f["points/costs/min_distance_m"].shape == (N,)
        assert f["points/status"].dtype == np.int8 and f["grid/spin_phase_deg"][()].tolist() == [0.0, 15.0]
        assert f["points/failure_reason"].asstr()[1] == "Kollision Δ point 1"


def test_write_table_never_leaves_a_half_written_table(tmp_path, monkeypatch):
    path = tmp_path / "t.h5"
    _write(path)
    before = path.read_bytes()
    # an unserialisable value: refused before the file is touched
    bad = {**_records(), 3: {"point": 3, "status": "feasible", "approach_params": object()}}
    with pytest.raises(TableError, match="point 3: approach_params: cannot store a value of type object"):
        _write(path, bad)
    assert path.read_bytes() == before and not path.with_name("t.h5.tmp").exists()

    # a failure after the HDF5 content is written, before the rename
    def fail(_path):
        raise OSError("disk on fire")

    monkeypatch.setattr(table_writer, "fsync_file", fail)
    with pytest.raises(OSError, match="disk on fire"):
        _write(path, {0: _record(0, "infeasible")})
    assert path.read_bytes() == before and not path.with_name("t.h5.tmp").exists()
    monkeypatch.undo()
    _write(path, {0: _record(0, "infeasible")})  # a successful write replaces the table
    assert Table.open(path).counts()["infeasible"] == 1 and not path.with_name("t.h5.tmp").exists()


@pytest.mark.parametrize("records, match", [
    ({0: {**_record(0), "approach_params": np.zeros(3)}, 1: _record(1)}, r"point 1: approach_params: shape \(35,\)"),
    ({0: {"point": 0, "status": "solved"}}, "status must be one of"),
    ({9: _record(9)}, "not a point index"),
    ({0: _record(1)}, "says point 1"),
    ({0: {**_record(0), "tag": "a"}, 1: {**_record(1), "tag": 2.0}}, "point 1: tag: a float value"),
    ({0: {**_record(0), "costs": 1.0}}, "'costs' collides"),
    ({0: {**_record(0), "x//y": 1.0}}, "not a valid table name"),
])
def test_write_table_rejects_inconsistent_records(tmp_path, records, match):
    with pytest.raises(TableError, match=match):
        _write(tmp_path / "t.h5", records)
    assert list(tmp_path.iterdir()) == []


def _mutate(path: Path, how) -> None:
    with h5py.File(path, "r+") as f:
        how(f)


@pytest.mark.parametrize("case, match", [
    ("missing", "no such table file"),
    ("truncated", "not a readable HDF5 table"),
    ("not_hdf5", "not a readable HDF5 table"),
    ("schema_7", "unknown schema version 7; this lutgen reads 1"),
    ("no_schema", "not a lutgen table"),
    ("missing_attribute", "missing root attribute.*model_hash"),
    ("missing_dataset", "missing dataset.*points/iterations"),
    ("missing_axis", "grid/spin_phase_deg"),
    ("bad_status", r"unknown code\(s\) \[9\]"),
    ("short_field", r"points/start_delay_s has shape \(4,\)"),
])
def test_open_refuses_bad_tables_in_one_line(tmp_path, case, match):
    path = tmp_path / "t.h5"
    if case != "missing":
        _write(path)
    if case == "truncated":
        data = path.read_bytes()
        path.write_bytes(data[:len(data) // 2])
    elif case == "not_hdf5":
        path.write_text("name = 'a grid config, not a table'\n")
    elif case == "schema_7":
        _mutate(path, lambda f: f.attrs.modify("schema_version", 7))
    elif case == "no_schema":
        _mutate(path, lambda f: f.attrs.__delitem__("schema_version"))
    elif case == "missing_attribute":
        _mutate(path, lambda f: f.attrs.__delitem__("model_hash"))
    elif case == "missing_dataset":
        _mutate(path, lambda f: f.__delitem__("points/iterations"))
    elif case == "missing_axis":
        _mutate(path, lambda f: f.__delitem__("grid/spin_phase_deg"))
    elif case == "bad_status":
        _mutate(path, lambda f: f["points/status"].__setitem__(2, 9))
    elif case == "short_field":
        def shorten(f):
            del f["points/start_delay_s"]
            f["points/start_delay_s"] = np.zeros(4)
        _mutate(path, shorten)
    with pytest.raises(TableError, match=match) as info:
        Table.open(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message


def test_check_model_names_both_hashes(tmp_path):
    path = tmp_path / "t.h5"
    _write(path)
    t = Table.open(path)
    t.check_model(model_hash("<robot/>", "[target]", "[robot]\n"), "scenario_II.toml")  # the same model: fine
    other = model_hash("<robot/>", "[target]", "[robot]\nmass = 2\n")
    with pytest.raises(TableError, match=r"built for another robot/target/scenario than scenario_II.toml "
                                         rf"\(hash {t.model_hash[:12]}… vs {other[:12]}…\)"):
        t.check_model(other, "scenario_II.toml")


def test_model_hash_separates_its_three_texts():
    assert model_hash("ab", "c", "") != model_hash("a", "bc", "")
    assert model_hash("a", "b", "c") == model_hash("a", "b", "c") and STATUS_CODES["failed"] == 3
