"""Corrupt tables fed to ``lutgen inspect`` and ``lutgen query``: one line, exit 1, no traceback, no hang,
and the file's bytes as they were.

Byte-level damage (truncation, zeroed ranges, random bytes) hits the HDF5 structure; dataset-level damage
(missing, mistyped, misshapen, non-finite datasets and attributes) is made with h5py on a valid table. The
table is the golden CI table (zeroed bytes 4000–12000 of it hung libhdf5 at 100 % CPU; what a given
damage does depends on the file's layout, so the hang itself is also tested with a read that sleeps) or a
table of the same grid written from the stand-in solver's records.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
import pytest

from lut.query.table_checks import parameter_shapes
from lut.table.store import Table
from planner.config.scenario import load_scenario
from tests.support.cli import ON_GRID_STATE, ROOT, assert_one_line_error, lutgen, lutgen_in_process, write_fake_table

GOLDEN = ROOT / "tests" / "data" / "ci_golden.h5"
LIMIT_S = 10.0  # the most a corrupt table may cost a command (the bound)


@dataclass(frozen=True)
class Damage:
    id: str
    apply: Callable[[Path], None]
    words: tuple[str, ...] = ()


def _bytes(edit: Callable[[bytearray], bytes | bytearray]) -> Callable[[Path], None]:
    def apply(path: Path) -> None:
        path.write_bytes(bytes(edit(bytearray(path.read_bytes()))))
    return apply


def _zero(start: int, stop: int) -> Callable[[Path], None]:
    def edit(data: bytearray) -> bytearray:
        data[start:stop] = bytes(len(data[start:stop]))
        return data
    return _bytes(edit)


def _random(start: int, stop: int | None, seed: int) -> Callable[[Path], None]:
    def edit(data: bytearray) -> bytearray:
        end = len(data) if stop is None else stop
        data[start:end] = np.random.default_rng(seed).integers(0, 256, end - start, dtype=np.uint8).tobytes()
        return data
    return _bytes(edit)


def _h5(edit: Callable[[h5py.File], None]) -> Callable[[Path], None]:
    def apply(path: Path) -> None:
        with h5py.File(path, "r+") as f:
            edit(f)
    return apply


def _replace(name: str, data: object) -> Callable[[h5py.File], None]:
    def edit(f: h5py.File) -> None:
        del f[name]
        f[name] = data
    return edit


def _nan_at_feasible_point(f: h5py.File) -> None:
    data = f["points/approach_params"][()]
    data[0, 3] = np.nan
    f["points/approach_params"][...] = data


HANG = Damage("zeroed-4000-12000", _zero(4000, 12000))  # libhdf5 spun forever (issue 24)
BYTE_DAMAGE = [
    Damage("truncated-half", _bytes(lambda d: d[: len(d) // 2])),
    Damage("truncated-to-superblock", _bytes(lambda d: d[:96])),
    Damage("empty-file", _bytes(lambda d: b"")),
    HANG,
    Damage("zeroed-superblock", _zero(0, 512)),
    Damage("zeroed-1000-3000", _zero(1000, 3000)),
    Damage("zeroed-tail", _zero(16000, 10**9)),
    Damage("random-file", _random(0, None, 1)),
    Damage("random-2000-6000", _random(2000, 6000, 2)),
    Damage("random-20000-20400", _random(20000, 20400, 3)),
]
DATASET_DAMAGE = [
    Damage("missing-status", _h5(lambda f: f.__delitem__("points/status")), ("points/status",)),
    Damage("missing-approach-params", _h5(lambda f: f.__delitem__("points/approach_params")),
           ("points/approach_params",)),
    Damage("missing-grid-axis", _h5(lambda f: f.__delitem__("grid/spin_rate_deg_s")), ("grid/spin_rate_deg_s",)),
    Damage("text-approach-params", _h5(_replace("points/approach_params", np.array(["x"] * 4, dtype=object))),
           ("points/approach_params",)),
    Damage("float-status", _h5(_replace("points/status", np.ones(4))), ("points/status",)),
    Damage("text-solve-time", _h5(_replace("points/solve_time_s", np.array(["1"] * 4, dtype=object))),
           ("points/solve_time_s",)),
    Damage("short-approach-params", _h5(_replace("points/approach_params", np.zeros((4, 6)))),
           ("points/approach_params", "shape")),
    Damage("int-q-tracking", _h5(_replace("points/q_tracking", np.zeros((4, 3, 7), dtype=np.int64))),
           ("points/q_tracking", "floats")),
    Damage("nan-approach-params", _h5(_nan_at_feasible_point), ("points/approach_params", "not finite")),
    Damage("wrong-row-count", _h5(_replace("points/iterations", np.zeros(3, dtype=np.int64))),
           ("points/iterations",)),
    Damage("numeric-model-hash", _h5(lambda f: f.attrs.__setitem__("model_hash", np.arange(3))), ("model_hash",)),
    Damage("numeric-config-text", _h5(lambda f: f.attrs.__setitem__("config_text", 7)), ("config_text",)),
    Damage("nan-grid-axis", _h5(_replace("grid/spin_phase_deg", np.array([0.0, np.nan]))), ("grid/spin_phase_deg",)),
    Damage("huge-shape-claim", _h5(lambda f: f["points"].create_dataset("big", shape=(4, 10**9), dtype="f8")),
           ("points/big",)),
]
QUERY_ONLY = frozenset({"missing-approach-params", "short-approach-params", "int-q-tracking",
                        "nan-approach-params"})  # inspect does not read the parameters


@pytest.fixture(scope="module")
def fake_table(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("hostile") / "fake.h5"
    write_fake_table(path)
    return path


def _damaged(source: Path, damage: Damage, tmp_path: Path) -> Path:
    path = tmp_path / f"{damage.id}.h5"
    shutil.copy(source, path)
    damage.apply(path)
    return path


def _assert_refused_quickly(path: Path, command: tuple, words: tuple[str, ...], subprocess: bool = False) -> None:
    """Refused in one line, exit 1, within :data:`LIMIT_S`, the file untouched (in this process unless
    ``subprocess``: the tracebacks a subprocess would print are caught either way)."""
    before = path.read_bytes()
    t0 = time.perf_counter()
    proc = lutgen(*command, timeout_s=60) if subprocess else lutgen_in_process(*command)
    elapsed = time.perf_counter() - t0
    assert_one_line_error(proc, *words)
    assert elapsed < LIMIT_S, f"{command}: {elapsed:.1f} s"
    assert path.read_bytes() == before


@pytest.mark.parametrize("damage", BYTE_DAMAGE, ids=[d.id for d in BYTE_DAMAGE])
def test_inspect_refuses_damaged_bytes_of_the_golden_table(damage, tmp_path):
    path = _damaged(GOLDEN, damage, tmp_path)
    _assert_refused_quickly(path, ("inspect", path), (str(path), *damage.words))


@pytest.mark.parametrize("damage", [d for d in BYTE_DAMAGE if d.id in ("zeroed-4000-12000", "random-2000-6000",
                                                                          "truncated-half")],
                         ids=lambda d: d.id)
def test_query_refuses_damaged_bytes(damage, fake_table, tmp_path):
    path = _damaged(fake_table, damage, tmp_path)
    _assert_refused_quickly(path, ("query", path, *ON_GRID_STATE), (str(path),))


@pytest.mark.parametrize("command", ["inspect", "query"])
def test_the_libhdf5_hang_is_one_line_from_the_installed_command(command, tmp_path):
    """The reproducer of issue 24 (zeroed bytes 4000–12000 of the golden table), as the operator meets it."""
    path = _damaged(GOLDEN, HANG, tmp_path)
    args = (command, path, *(ON_GRID_STATE if command == "query" else ()))
    _assert_refused_quickly(path, args, (str(path),), subprocess=True)


def test_a_read_that_hangs_or_crashes_is_ended_by_the_probe():
    """The mechanism behind the refusals above, whatever libhdf5 does with a given damage."""
    import os
    import signal

    from lut.table.bounded_read import ProbeOutcome, probe_read

    t0 = time.perf_counter()
    assert probe_read(lambda: time.sleep(3600), timeout_s=1.0).outcome is ProbeOutcome.TIMED_OUT
    assert time.perf_counter() - t0 < 5.0
    crashed = probe_read(lambda: os.kill(os.getpid(), signal.SIGSEGV), timeout_s=10.0)
    assert crashed.outcome is ProbeOutcome.CRASHED and str(int(signal.SIGSEGV)) in crashed.detail
    refused = probe_read(lambda: 1 / 0, timeout_s=10.0)
    assert refused.outcome is ProbeOutcome.REFUSED and "division by zero" in refused.detail
    assert probe_read(lambda: None, timeout_s=10.0).outcome is ProbeOutcome.OK


@pytest.mark.parametrize("damage", [d for d in DATASET_DAMAGE if d.id not in QUERY_ONLY], ids=lambda d: d.id)
def test_inspect_refuses_damaged_datasets(damage, fake_table, tmp_path):
    path = _damaged(fake_table, damage, tmp_path)
    _assert_refused_quickly(path, ("inspect", path), damage.words)


@pytest.mark.parametrize("damage", DATASET_DAMAGE, ids=lambda d: d.id)
def test_query_refuses_damaged_datasets(damage, fake_table, tmp_path):
    path = _damaged(fake_table, damage, tmp_path)
    _assert_refused_quickly(path, ("query", path, *ON_GRID_STATE), damage.words)


def test_parameter_shapes_are_those_the_planner_writes():
    """The shapes a query demands are the shapes of a real build's records (the golden table's)."""
    table = Table.open(GOLDEN)
    scenario = load_scenario(ROOT / "configs" / "scenarios" / "scenario_II.toml")
    for key, shape in parameter_shapes(scenario).items():
        assert table.field(key).shape[1:] == shape, key
