"""Build tests with the fast stand-in solver: the point processes' environment, and two tables compared field by
field."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from lut.table.store import Table

ROOT = Path(__file__).resolve().parents[2]
FAKE_SOLVER = "tests.support.fake_solver:solve"
FAULT_VARIABLES = ("LUTGEN_FAKE_RAISE", "LUTGEN_FAKE_HANG", "LUTGEN_FAKE_CRASH", "LUTGEN_FAKE_SLEEP_S",
                   "LUTGEN_FAKE_INFEASIBLE")
# Per-point fields that hold wall-clock measurements: they differ between two runs of the same build by
# design, so only whether each point has a value (and that it is a duration, >= 0) must agree.
WALL_CLOCK_FIELDS = frozenset({"solve_time_s"})


def fake_solver_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """The point processes import :mod:`tests.support.fake_solver` from the repo root, with no fault injected,
    in new worker processes."""
    monkeypatch.setenv("PYTHONPATH", str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for var in FAULT_VARIABLES:
        monkeypatch.delenv(var, raising=False)
    fresh_workers()


def fresh_workers() -> None:
    """loky keeps its worker processes between builds, with the environment they started with; the
    fault-injection variables must reach the point processes, so every test starts new workers."""
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True, kill_workers=True)


def snapshot(path: Path) -> dict[str, np.ndarray]:
    """Every per-point field of the table (status, parameters, costs, margins, reasons…), whatever the records hold."""
    t = Table.open(path)
    return {key: t.field(key) for key in t.field_names}


def assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    """Same fields, and every field equal bit for bit (the build is deterministic: fixed warm-start tree, one
    solve per process), NaN (no value) where the other has NaN; wall-clock fields only agree on which points
    have a value."""
    assert sorted(a) == sorted(b), f"fields differ: {sorted(set(a) ^ set(b))}"
    assert {"status", "approach_params", "start_delay_s", "stabilization_params"} <= set(a)
    for key in sorted(a):
        if key in WALL_CLOCK_FIELDS:
            np.testing.assert_array_equal(np.isnan(a[key]), np.isnan(b[key]), err_msg=key)
            assert np.all(a[key][~np.isnan(a[key])] >= 0) and np.all(b[key][~np.isnan(b[key])] >= 0), key
            continue
        assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
