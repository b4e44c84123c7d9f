"""The look-up table on disk: one HDF5 file, plain h5py, no pickles (DESIGN §6). Schema version 1.

Root attributes
    ``schema_version`` (int, :data:`SCHEMA_VERSION`), ``lutgen_version``, ``config_text`` (the grid
    config's text), ``scenario_text``, ``model_hash`` (:func:`model_hash` of robot URDF + target +
    scenario), ``created_utc`` (ISO 8601), ``grid_kind``; ``scenario_path`` when the writer gave one (``lutgen build``
    writes it relative to the table's folder, so a table and its configs can move together).
Group ``grid/``
    one 1-D float64 dataset per axis (its values); attribute ``axis_names`` (ordered list of str).
Group ``points/`` — arrays over the flat point index ``0 … n_points-1``
    ``status`` int8 (:data:`STATUS_CODES`: 0 pending, 1 feasible, 2 infeasible, 3 failed; the mapping
    is also stored as JSON in the attribute ``points/status_codes``), ``failure_reason`` (variable-
    length UTF-8), ``solve_time_s`` float64, ``iterations`` int64 — always present — and one dataset
    per further record key.

Records → datasets. :func:`write_table` takes ``records: {point: dict[str, value]}``, the flat records of
:mod:`lut.table.records` (the same the build journal holds). ``"point"`` is the index and ``"status"`` the
status name; every other key becomes the dataset ``points/<key>`` — a ``"/"`` in a key makes a
sub-group, e.g. ``"costs/min_distance_m"`` → ``points/costs/min_distance_m``. A dataset's per-point
shape is the shape of the value in the first record (by point index) that has the key, so a record
value of shape ``s`` gives a dataset of shape ``(n_points, *s)``; every record holding the key must
give the same shape. Its type: float64 if any record holds a float for the key, else int64 for ints
and bools, variable-length UTF-8 for ``str`` (mixing ``str`` with numbers is an error). Points without
the key (pending, failed, …) hold the missing value: NaN (float), -1 (int), ``""`` (str); the attribute
``points/missing_values`` says so. NUL characters in strings (which HDF5 strings cannot hold) are
replaced by U+FFFD.

The table is written atomically (temp file in the same folder, fsync, ``os.replace``): the file at
``path`` is always either the previous table or the complete new one.
"""

from __future__ import annotations

import hashlib
import json
import os
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from lut.table.bounded_read import ProbeOutcome, probe_read
from planner.errors import LutgenError

SCHEMA_VERSION = 1
STATUS_CODES = {"pending": 0, "feasible": 1, "infeasible": 2, "failed": 3}
STATUS_NAMES = {code: name for name, code in STATUS_CODES.items()}
REQUIRED_ATTRS = ("schema_version", "lutgen_version", "config_text", "scenario_text", "model_hash", "created_utc",
                  "grid_kind")
TEXT_ATTRS = ("lutgen_version", "config_text", "scenario_text", "model_hash", "created_utc", "grid_kind")
BASE_FIELDS = ("status", "failure_reason", "solve_time_s", "iterations")
TEXT_FIELDS = frozenset({"failure_reason"})  # every other per-point dataset holds numbers
NUMERIC_KINDS = "biuf"
# reading a table: a few seconds, plus time for its size; beyond that libhdf5 is taken to hang (s, bytes/s)
READ_TIMEOUT_BASE_S = 3.0
READ_RATE_BYTES_PER_S = 20e6
# a dataset's values cannot need more memory than this many times the file, plus slack (variable-length
# strings are stored once; uncompressed arrays never exceed the file): a larger claim is a corrupt header
MAX_EXPANSION = 4
MAX_EXPANSION_SLACK_BYTES = 1 << 20
MISSING_FLOAT = np.nan
MISSING_INT = -1
MISSING_STR = ""
_STR_DTYPE = h5py.string_dtype("utf-8")


class TableError(LutgenError):
    """A look-up table (or build journal) is missing, corrupt, of another schema, or built for another model."""


def model_hash(urdf_text: str, target_text: str, scenario_text: str) -> str:
    """Hex SHA-256 identifying robot + target + scenario; each text is length-prefixed, so it is unambiguous."""
    h = hashlib.sha256()
    for text in (urdf_text, target_text, scenario_text):
        data = text.encode("utf-8")
        h.update(f"{len(data)}:".encode("ascii"))
        h.update(data)
    return h.hexdigest()


def lutgen_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("lutgen")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree that was never installed
        return "unknown"


# ---- writing ------------------------------------------------------------------------------------


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


def _kind_of(value: Any, where: str) -> tuple[str, tuple[int, ...]]:
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
    """Status codes and one filled array per field, from the records; raises TableError before any file is touched."""
    status = np.full(n_points, STATUS_CODES["pending"], dtype=np.int8)
    specs: dict[str, tuple[str, tuple[int, ...]]] = {
        "failure_reason": ("str", ()), "solve_time_s": ("float", ()), "iterations": ("int", ())}
    points = sorted(records)
    for p in points:
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
            where = f"point {p}: {key}"
            if not isinstance(key, str):
                raise TableError(f"point {p}: record key {key!r} is not a string")
            _check_name(key, "record key")
            kind, shape = _kind_of(value, where)
            if key not in specs:
                specs[key] = (kind, shape)
                continue
            old_kind, old_shape = specs[key]
            if shape != old_shape:
                raise TableError(f"{where}: shape {shape} differs from {old_shape}, set by an earlier point")
            if "str" in (kind, old_kind) and kind != old_kind:
                raise TableError(f"{where}: a {kind} value where other points hold a {old_kind}")
            if kind == "float":
                specs[key] = ("float", shape)
    keys = sorted(specs)
    for key in keys:  # a key cannot be both a dataset and the group of another key
        if any(other.startswith(key + "/") for other in keys):
            raise TableError(f"record key {key!r} collides with another field of the table")
    arrays: dict[str, np.ndarray] = {}
    for key, (kind, shape) in specs.items():
        if kind == "str":
            arrays[key] = np.full(n_points, MISSING_STR, dtype=object)
        elif kind == "int":
            arrays[key] = np.full((n_points, *shape), MISSING_INT, dtype=np.int64)
        else:
            arrays[key] = np.full((n_points, *shape), MISSING_FLOAT, dtype=np.float64)
    for p in points:
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
    return status, arrays


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # pragma: no cover - e.g. Windows
        return
    try:
        os.fsync(fd)
    except OSError:  # pragma: no cover
        pass
    finally:
        os.close(fd)


def write_table(path: Path, *, grid_axes: list[tuple[str, np.ndarray]], grid_kind: str, config_text: str,
                scenario_text: str, model_hash: str, records: dict[int, dict[str, Any]], n_points: int,
                scenario_path: str | None = None) -> None:
    """Write the table atomically: ``<path>.tmp`` beside ``path`` (``t.h5`` → ``t.h5.tmp``), fsync, rename.

    ``records`` maps point index → flat record (module docstring); points without a record are
    pending. Bad input (unknown status, a value that cannot be stored, inconsistent shapes) raises
    :class:`TableError` and leaves ``path`` as it was; no temp file is left behind either way.
    """
    path = Path(path)
    if n_points < 0:
        raise TableError(f"{path}: n_points must be >= 0, got {n_points}")
    axes: list[tuple[str, np.ndarray]] = []
    for name, values in grid_axes:
        _check_name(name, "grid axis")
        if "/" in name:
            raise TableError(f"grid axis name {name!r} must not contain '/'")
        axes.append((name, np.asarray(values, dtype=np.float64).reshape(-1)))
    if len({name for name, _ in axes}) != len(axes):
        raise TableError(f"grid axis names repeat: {[name for name, _ in axes]}")
    status, arrays = _point_arrays(records, n_points)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["schema_version"] = np.int64(SCHEMA_VERSION)
            f.attrs["lutgen_version"] = lutgen_version()
            f.attrs["config_text"] = config_text
            f.attrs["scenario_text"] = scenario_text
            f.attrs["model_hash"] = model_hash
            f.attrs["created_utc"] = datetime.now(UTC).isoformat(timespec="seconds")
            f.attrs["grid_kind"] = grid_kind
            if scenario_path is not None:
                f.attrs["scenario_path"] = str(scenario_path)
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
        _fsync_file(tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    _fsync_dir(path.parent)


# ---- reading ------------------------------------------------------------------------------------


def _plain(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        return [_plain(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def read_timeout_s(size_bytes: int) -> float:
    """Time limit (s) of reading a table of ``size_bytes``: a few seconds, more for a large file."""
    return READ_TIMEOUT_BASE_S + size_bytes / READ_RATE_BYTES_PER_S


def _root_attributes(path: Path, f: h5py.File) -> dict[str, Any]:
    """The root attributes as Python values, after checking the schema version and the text attributes."""
    if "schema_version" not in f.attrs:
        raise TableError(f"{path}: not a lutgen table (no schema_version attribute)")
    try:
        version = int(f.attrs["schema_version"])
    except (TypeError, ValueError):
        raise TableError(f"{path}: schema_version is not an integer: {f.attrs['schema_version']!r}") from None
    if version != SCHEMA_VERSION:
        raise TableError(f"{path}: unknown schema version {version}; this lutgen reads {SCHEMA_VERSION}")
    missing = [name for name in REQUIRED_ATTRS if name not in f.attrs]
    if missing:
        raise TableError(f"{path}: missing root attribute(s) {', '.join(missing)}")
    attrs = {name: _plain(f.attrs[name]) for name in f.attrs}
    for name in (*TEXT_ATTRS, *(["scenario_path"] if "scenario_path" in attrs else [])):
        if not isinstance(attrs[name], str):
            raise TableError(f"{path}: root attribute {name} must be text, got {type(attrs[name]).__name__}")
    return attrs


def _dataset(path: Path, name: str, ds: h5py.Dataset, max_bytes: int) -> np.ndarray:
    """The values of one dataset (strings as an object array), after checking its size is plausible."""
    nbytes = ds.size * ds.dtype.itemsize
    if nbytes > max_bytes:
        raise TableError(f"{path}: {name} claims shape {ds.shape} ({nbytes} bytes), impossible in a file of "
                         f"{path.stat().st_size} bytes: corrupt")
    if h5py.check_string_dtype(ds.dtype) is not None:
        return np.asarray(ds.asstr()[()], dtype=object)
    if ds.dtype.kind not in NUMERIC_KINDS:
        raise TableError(f"{name}: must hold numbers or text, got dtype {ds.dtype}")
    return np.asarray(ds[()])


def _grid_axes(path: Path, grid: h5py.Group, max_bytes: int) -> tuple[list[str], list[np.ndarray]]:
    """Axis names and their values (finite, float64) from the ``grid/`` group."""
    if "axis_names" not in grid.attrs:
        raise TableError(f"{path}: missing attribute grid/axis_names")
    axis_names = [str(n) for n in np.atleast_1d(_plain(grid.attrs["axis_names"]))]
    axis_values = []
    for name in axis_names:
        ds = grid.get(name)
        if not isinstance(ds, h5py.Dataset) or ds.ndim != 1 or ds.size == 0:
            raise TableError(f"{path}: missing or malformed dataset grid/{name}")
        values = _dataset(path, f"grid/{name}", ds, max_bytes)
        if values.dtype.kind not in "iuf" or not np.all(np.isfinite(values.astype(np.float64))):
            raise TableError(f"{path}: grid/{name} must hold finite numbers")
        axis_values.append(values.astype(np.float64))
    return axis_names, axis_values


def _check_point_fields(path: Path, fields: dict[str, np.ndarray]) -> None:
    """Base datasets present; every dataset one row per point; text only where text belongs; known codes."""
    missing = [name for name in BASE_FIELDS if name not in fields]
    if missing:
        raise TableError(f"{path}: missing dataset(s) {', '.join('points/' + m for m in missing)}")
    status = fields["status"]
    if status.ndim != 1 or status.dtype.kind not in "iu":
        raise TableError(f"{path}: points/status must be a 1-D integer dataset, got {status.dtype} {status.shape}")
    n = status.shape[0]
    for name, data in fields.items():
        if data.ndim == 0 or data.shape[0] != n:
            raise TableError(f"{path}: points/{name} has shape {data.shape}, expected ({n}, …)")
        if (data.dtype == object) != (name in TEXT_FIELDS):
            want = "text" if name in TEXT_FIELDS else "numbers"
            raise TableError(f"{path}: points/{name} must hold {want}, got dtype {data.dtype}")
    for name, kinds in (("solve_time_s", "f"), ("iterations", "iu")):
        if fields[name].dtype.kind not in kinds:
            raise TableError(f"{path}: points/{name} has dtype {fields[name].dtype}")
    bad = np.setdiff1d(np.unique(status), list(STATUS_NAMES))
    if bad.size:
        raise TableError(f"{path}: points/status holds unknown code(s) {bad.tolist()}")


class Table:
    """A look-up table read fully into memory (the file is closed again when :meth:`open` returns).

    ``attrs`` (root attributes as Python values), ``axis_names``, ``axis_values`` (float64 arrays),
    ``status`` (int8 codes, :data:`STATUS_CODES`), ``n_points``, ``model_hash``, ``path``.
    """

    def __init__(self, path: Path, attrs: dict[str, Any], axis_names: list[str], axis_values: list[np.ndarray],
                 fields: dict[str, np.ndarray]) -> None:
        self.path = path
        self.attrs = attrs
        self.axis_names = axis_names
        self.axis_values = axis_values
        self._fields = fields
        self.status: np.ndarray = fields["status"]
        self.n_points = int(self.status.shape[0])
        self.model_hash = str(attrs["model_hash"])

    @classmethod
    def open(cls, path: str | Path) -> Table:
        """Read and validate ``path``; any problem raises a one-line :class:`TableError` naming the file.

        The file is read first in a child process with a time limit (:mod:`lut.table.bounded_read`): a corrupt
        file that would hang or crash libhdf5 is refused within :func:`read_timeout_s`.
        """
        path = Path(path)
        if not path.exists():
            raise TableError(f"{path}: no such table file")
        if not path.is_file():
            raise TableError(f"{path}: not a file")
        timeout_s = read_timeout_s(path.stat().st_size)
        probe = probe_read(lambda: cls._load(path), timeout_s)
        if probe.outcome is ProbeOutcome.TIMED_OUT:
            raise TableError(f"{path}: corrupt table: reading it did not finish within {timeout_s:.0f} s "
                             "(libhdf5 hangs on damaged metadata)")
        if probe.outcome is ProbeOutcome.CRASHED:
            raise TableError(f"{path}: corrupt table: reading it crashed libhdf5 ({probe.detail})")
        if probe.outcome is ProbeOutcome.REFUSED:
            raise TableError(probe.detail)
        return cls._load(path)

    @classmethod
    def _load(cls, path: Path) -> Table:
        try:
            f = h5py.File(path, "r")
        except OSError as exc:
            raise TableError(f"{path}: not a readable HDF5 table (truncated or corrupt?): {_first_line(exc)}") from None
        try:
            with f:
                return cls._read(path, f)
        except (OSError, KeyError, ValueError, TypeError, RuntimeError, MemoryError) as exc:
            raise TableError(f"{path}: corrupt table: {_first_line(exc)}") from None

    @classmethod
    def _read(cls, path: Path, f: h5py.File) -> Table:
        attrs = _root_attributes(path, f)
        for group in ("grid", "points"):
            if not isinstance(f.get(group), h5py.Group):
                raise TableError(f"{path}: missing group {group}/")
        max_bytes = MAX_EXPANSION * path.stat().st_size + MAX_EXPANSION_SLACK_BYTES
        axis_names, axis_values = _grid_axes(path, f["grid"], max_bytes)
        fields: dict[str, np.ndarray] = {}

        def collect(name: str, obj: Any) -> None:
            if isinstance(obj, h5py.Dataset):
                fields[name] = _dataset(path, f"points/{name}", obj, max_bytes)

        f["points"].visititems(collect)
        _check_point_fields(path, fields)
        fields["status"] = fields["status"].astype(np.int8)
        return cls(path, attrs, axis_names, axis_values, fields)

    # ---- access -------------------------------------------------------------------------------

    @property
    def field_names(self) -> list[str]:
        """Every per-point field, e.g. ``approach_params``, ``costs/min_distance_m`` (sorted)."""
        return sorted(self._fields)

    def has_field(self, key: str) -> bool:
        return key in self._fields

    def field(self, key: str) -> np.ndarray:
        """A copy of the per-point array ``points/<key>``, shape ``(n_points, …)`` (str fields: object arrays)."""
        if key not in self._fields:
            raise TableError(f"{self.path}: no field {key!r} (fields: {', '.join(self.field_names)})")
        return self._fields[key].copy()

    def record(self, point: int) -> dict[str, Any]:
        """Every field of one point: ``point``, ``status`` (name), scalars as Python values, arrays as copies.

        Fields the point has no value for hold the missing value (NaN, -1, ``""``).
        """
        if not 0 <= point < self.n_points:
            raise TableError(f"{self.path}: point {point} is outside 0..{self.n_points - 1}")
        rec: dict[str, Any] = {"point": int(point), "status": STATUS_NAMES[int(self.status[point])]}
        for key in self.field_names:
            if key == "status":
                continue
            value = self._fields[key][point]
            rec[key] = value.copy() if isinstance(value, np.ndarray) else _plain(value)
        return rec

    def counts(self) -> dict[str, int]:
        """Number of points per status name (all four names, zeros included)."""
        return {name: int(np.count_nonzero(self.status == code)) for name, code in STATUS_CODES.items()}

    def check_model(self, expected_hash: str, what: str) -> None:
        """Raise :class:`TableError` unless the table was built for the model hashed as ``expected_hash``."""
        if self.model_hash != expected_hash:
            raise TableError(f"table {self.path} was built for another robot/target/scenario than {what} "
                             f"(hash {self.model_hash[:12]}… vs {expected_hash[:12]}…)")
