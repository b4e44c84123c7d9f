"""Reading a look-up table: the HDF5 file checked and loaded into memory, one point's record at a time.

Any problem is one :class:`~lut.table.schema.TableError` naming the file; a file that would hang or crash
libhdf5 is refused in seconds (:mod:`lut.table.bounded_read`). The layout: :mod:`lut.table.schema`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from lut.table.bounded_read import ProbeOutcome, probe_read
from lut.table.provenance import ReusedSource, reused_sources
from lut.table.schema import (
    BASE_FIELDS,
    OPTIONAL_TEXT_ATTRS,
    REQUIRED_ATTRS,
    SCHEMA_VERSION,
    STATUS_CODES,
    STATUS_NAMES,
    TEXT_ATTRS,
    TEXT_FIELDS,
    TableError,
)

NUMERIC_KINDS = "biuf"
# reading a table: a few seconds, plus time for its size; beyond that libhdf5 is taken to hang (s, bytes/s)
READ_TIMEOUT_BASE_S = 3.0
READ_RATE_BYTES_PER_S = 20e6
# a dataset's values cannot need more memory than this many times the file, plus slack (variable-length
# strings are stored once; uncompressed arrays never exceed the file): a larger claim is a corrupt header
MAX_EXPANSION = 4
MAX_EXPANSION_SLACK_BYTES = 1 << 20


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
    for name in (*TEXT_ATTRS, *(name for name in OPTIONAL_TEXT_ATTRS if name in attrs)):
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
    ``status`` (int8 codes, :data:`STATUS_CODES`), ``n_points``, ``model_hash``, ``path``, ``reused_from`` (the
    tables a ``--reuse`` build took plans from, :mod:`lut.table.provenance`; empty for any other table).
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
        self.reused_from: tuple[ReusedSource, ...] = reused_sources(path, attrs.get("reused_from"), self.n_points)

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

    def scenario_file(self) -> Path:
        """The scenario file the table names (stored relative to the table's folder), checked to be there."""
        stored = self.attrs.get("scenario_path")
        if not stored:
            raise TableError(f"{self.path}: the table does not name its scenario; pass --scenario")
        path = self.path.absolute().parent / stored
        if not path.is_file():
            raise TableError(f"{self.path}: its scenario {stored} (relative to the table) is not there; "
                             "pass --scenario")
        return path

    def check_model(self, expected_hash: str, what: str) -> None:
        """Raise :class:`TableError` unless the table was built for the model hashed as ``expected_hash``."""
        if self.model_hash != expected_hash:
            raise TableError(f"table {self.path} was built for another robot/target/scenario than {what} "
                             f"(hash {self.model_hash[:12]}… vs {expected_hash[:12]}…)")
