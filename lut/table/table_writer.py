"""Writing a look-up table: flat point records → one HDF5 file, atomically (temp file, fsync, rename).

The layout, and how a record's keys become datasets, is :mod:`lut.table.schema`'s (docs/table.md, Store).
"""

from __future__ import annotations

import json
import os
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from lut.table.durable import fsync_dir, fsync_file
from lut.table.schema import MISSING_FLOAT, MISSING_INT, MISSING_STR, SCHEMA_VERSION, STATUS_CODES, TableError

_STR_DTYPE = h5py.string_dtype("utf-8")
FieldSpec = tuple[str, tuple[int, ...]]  # ("float" | "int" | "str", per-point shape)


def lutgen_version() -> str:
    """The installed lutgen's version (``unknown`` in a source tree never installed)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("lutgen")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree that was never installed
        return "unknown"


def _check_name(name: str, what: str) -> None:
    parts = name.split("/")
    if not name or any(p in ("", ".", "..") for p in parts):
        raise TableError(f"{what} {name!r} is not a valid table name (empty part, '.', '..' or stray '/')")


def _clean_str(value: str, where: str) -> str:
    try:
        value.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise TableError(f"{where}: string is not valid UTF-8: {exc}") from None
    return value.replace("\x00", "\ufffd")


def _kind_of(value: Any, where: str) -> FieldSpec:
    """("float" | "int" | "str", per-point shape) of one record value."""
    if isinstance(value, str):
        return "str", ()
    if isinstance(value, bool | int | np.bool_ | np.integer):
        return "int", ()
    if isinstance(value, float | np.floating):
        return "float", ()
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "biu":
            return "int", value.shape
        if value.dtype.kind == "f":
            return "float", value.shape
    detail = f" (dtype {value.dtype})" if isinstance(value, np.ndarray) else ""
    raise TableError(f"{where}: cannot store a value of type {type(value).__name__}{detail}")


def _point_arrays(records: dict[int, dict[str, Any]], n_points: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Status codes ``(n_points,)`` and one filled array per field, from the records; raises TableError before any
    file is touched."""
    status, specs = _field_specs(records, n_points)
    keys = sorted(specs)
    for key in keys:  # a key cannot be both a dataset and the group of another key
        if any(other.startswith(key + "/") for other in keys):
            raise TableError(f"record key {key!r} collides with another field of the table")
    return status, _filled_arrays(records, specs, n_points)


def _field_specs(records: dict[int, dict[str, Any]], n_points: int) -> tuple[np.ndarray, dict[str, FieldSpec]]:
    """Status codes ``(n_points,)`` and every field's kind and per-point shape, each record checked."""
    status = np.full(n_points, STATUS_CODES["pending"], dtype=np.int8)
    specs: dict[str, FieldSpec] = {"failure_reason": ("str", ()), "solve_time_s": ("float", ()),
                                   "iterations": ("int", ())}
    for p in sorted(records):
        if isinstance(p, bool) or not isinstance(p, int | np.integer) or not 0 <= p < n_points:
            raise TableError(f"record key {p!r} is not a point index in 0..{n_points - 1}")
        rec = records[p]
        if "point" in rec and int(rec["point"]) != int(p):
            raise TableError(f"the record stored for point {p} says point {rec['point']}")
        name = rec.get("status")
        if name not in STATUS_CODES:
            raise TableError(f"point {p}: status must be one of {', '.join(STATUS_CODES)}, got {name!r}")
        status[p] = STATUS_CODES[name]
        for key, value in rec.items():
            if key in ("point", "status"):
                continue
            if not isinstance(key, str):
                raise TableError(f"point {p}: record key {key!r} is not a string")
            _check_name(key, "record key")
            _merge_spec(specs, key, _kind_of(value, f"point {p}: {key}"), f"point {p}: {key}")
    return status, specs


def _merge_spec(specs: dict[str, FieldSpec], key: str, spec: FieldSpec, where: str) -> None:
    """Add one value's kind and shape to ``specs[key]``: shapes must agree, a float makes the field float."""
    if key not in specs:
        specs[key] = spec
        return
    (kind, shape), (old_kind, old_shape) = spec, specs[key]
    if shape != old_shape:
        raise TableError(f"{where}: shape {shape} differs from {old_shape}, set by an earlier point")
    if "str" in (kind, old_kind) and kind != old_kind:
        raise TableError(f"{where}: a {kind} value where other points hold a {old_kind}")
    if kind == "float":
        specs[key] = ("float", shape)


def _filled_arrays(records: dict[int, dict[str, Any]], specs: dict[str, FieldSpec],
                   n_points: int) -> dict[str, np.ndarray]:
    """One array ``(n_points, *shape)`` per field: the records' values, the missing value elsewhere."""
    arrays: dict[str, np.ndarray] = {}
    for key, (kind, shape) in specs.items():
        if kind == "str":
            arrays[key] = np.full(n_points, MISSING_STR, dtype=object)
        elif kind == "int":
            arrays[key] = np.full((n_points, *shape), MISSING_INT, dtype=np.int64)
        else:
            arrays[key] = np.full((n_points, *shape), MISSING_FLOAT, dtype=np.float64)
    for p in sorted(records):
        for key, value in records[p].items():
            if key in ("point", "status"):
                continue
            where = f"point {p}: {key}"
            if specs[key][0] == "str":
                arrays[key][p] = _clean_str(value, where)
                continue
            try:
                arrays[key][p] = value
            except (OverflowError, ValueError, TypeError) as exc:
                raise TableError(f"{where}: {exc}") from None
    return arrays


def write_table(path: Path, *, grid_axes: list[tuple[str, np.ndarray]], grid_kind: str, config_text: str,
                scenario_text: str, model_hash: str, records: dict[int, dict[str, Any]], n_points: int,
                scenario_path: str | None = None, reused_from: str | None = None) -> None:
    """Write the table atomically: ``<path>.tmp`` beside ``path`` (``t.h5`` → ``t.h5.tmp``), fsync, rename.

    ``records`` maps point index → flat record (:mod:`lut.table.schema`); points without a record are
    pending. Bad input (unknown status, a value that cannot be stored, inconsistent shapes) raises
    :class:`TableError` and leaves ``path`` as it was; no temp file is left behind either way.
    """
    path = Path(path)
    if n_points < 0:
        raise TableError(f"{path}: n_points must be >= 0, got {n_points}")
    axes = _checked_axes(grid_axes)
    status, arrays = _point_arrays(records, n_points)
    attrs = {"schema_version": np.int64(SCHEMA_VERSION), "lutgen_version": lutgen_version(),
             "config_text": config_text, "scenario_text": scenario_text, "model_hash": model_hash,
             "created_utc": datetime.now(UTC).isoformat(timespec="seconds"), "grid_kind": grid_kind}
    if scenario_path is not None:
        attrs["scenario_path"] = str(scenario_path)
    if reused_from is not None:
        attrs["reused_from"] = reused_from
    tmp = path.with_name(path.name + ".tmp")
    try:
        _write_h5(tmp, attrs, axes, status, arrays)
        fsync_file(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    fsync_dir(path.parent)


def _checked_axes(grid_axes: list[tuple[str, np.ndarray]]) -> list[tuple[str, np.ndarray]]:
    """The grid axes as (name, float64 values ``(count,)``), names checked: valid, no '/', no repeats."""
    axes: list[tuple[str, np.ndarray]] = []
    for name, values in grid_axes:
        _check_name(name, "grid axis")
        if "/" in name:
            raise TableError(f"grid axis name {name!r} must not contain '/'")
        axes.append((name, np.asarray(values, dtype=np.float64).reshape(-1)))
    if len({name for name, _ in axes}) != len(axes):
        raise TableError(f"grid axis names repeat: {[name for name, _ in axes]}")
    return axes


def _write_h5(tmp: Path, attrs: dict[str, Any], axes: list[tuple[str, np.ndarray]], status: np.ndarray,
              arrays: dict[str, np.ndarray]) -> None:
    """The whole HDF5 file at ``tmp``: root attributes, ``grid/`` and ``points/`` (:mod:`lut.table.schema`)."""
    with h5py.File(tmp, "w") as f:
        for name, value in attrs.items():
            f.attrs[name] = value
        grid = f.create_group("grid")
        grid.attrs["axis_names"] = [name for name, _ in axes]
        for name, values in axes:
            grid.create_dataset(name, data=values, track_times=False)
        pts = f.create_group("points")
        pts.attrs["status_codes"] = json.dumps(STATUS_CODES)
        pts.attrs["missing_values"] = "float: NaN, int: -1, str: empty string"
        pts.create_dataset("status", data=status, track_times=False)
        for key in sorted(arrays):
            data = arrays[key]
            if data.dtype == object:
                pts.create_dataset(key, data=data, dtype=_STR_DTYPE, track_times=False)
            else:
                pts.create_dataset(key, data=data, track_times=False)
        f.flush()
