"""The look-up table file's schema (version 1): one HDF5 file, plain h5py, no pickles (docs/table.md, Store).

Root attributes
    ``schema_version`` (int, :data:`SCHEMA_VERSION`), ``lutgen_version``, ``config_text`` (the grid
    config's text), ``scenario_text``, ``model_hash`` (:func:`lut.table.model_identity.model_hash` of
    robot URDF + target + scenario), ``created_utc`` (ISO 8601), ``grid_kind``; ``scenario_path`` when
    the writer gave one (``lutgen build`` writes it relative to the table's folder, so a table and its
    configs can move together); ``reused_from`` when a ``lutgen build --reuse`` wrote it (JSON, per reused table
    its path relative to the table's folder, ``created_utc`` and the points taken from it:
    :mod:`lut.table.provenance`).
Group ``grid/``
    one 1-D float64 dataset per axis (its values); attribute ``axis_names`` (ordered list of str).
Group ``points/`` — arrays over the flat point index ``0 … n_points-1``
    ``status`` int8 (:data:`STATUS_CODES`: 0 pending, 1 feasible, 2 infeasible, 3 failed; the mapping
    is also stored as JSON in the attribute ``points/status_codes``), ``failure_reason`` (variable-
    length UTF-8), ``solve_time_s`` float64, ``iterations`` int64 — always present — and one dataset
    per further record key.

Records → datasets. :func:`lut.table.table_writer.write_table` takes ``records: {point: dict[str, value]}``,
the flat records of :mod:`lut.table.records` (the same the build journal holds). ``"point"`` is the
index and ``"status"`` the status name; every other key becomes the dataset ``points/<key>`` — a ``"/"``
in a key makes a sub-group, e.g. ``"costs/min_distance_m"`` → ``points/costs/min_distance_m``. A
dataset's per-point shape is the shape of the value in the first record (by point index) that has the
key, so a record value of shape ``s`` gives a dataset of shape ``(n_points, *s)``; every record holding
the key must give the same shape. Its type: float64 if any record holds a float for the key, else int64
for ints and bools, variable-length UTF-8 for ``str`` (mixing ``str`` with numbers is an error). Points
without the key (pending, failed, …) hold the missing value: NaN (float), -1 (int), ``""`` (str); the
attribute ``points/missing_values`` says so. NUL characters in strings (which HDF5 strings cannot hold)
are replaced by U+FFFD.

The table is written atomically (temp file in the same folder, fsync, ``os.replace``): the file at
``path`` is always either the previous table or the complete new one.
"""

from __future__ import annotations

from lut.table.point_result import STATUS_CODES
from planner.errors import LutgenError

SCHEMA_VERSION = 1
STATUS_NAMES = {code: name for name, code in STATUS_CODES.items()}
REQUIRED_ATTRS = ("schema_version", "lutgen_version", "config_text", "scenario_text", "model_hash", "created_utc",
                  "grid_kind")
TEXT_ATTRS = ("lutgen_version", "config_text", "scenario_text", "model_hash", "created_utc", "grid_kind")
OPTIONAL_TEXT_ATTRS = ("scenario_path", "reused_from")
BASE_FIELDS = ("status", "failure_reason", "solve_time_s", "iterations")
TEXT_FIELDS = frozenset({"failure_reason"})  # every other per-point dataset holds numbers
MISSING_FLOAT = float("nan")
MISSING_INT = -1
MISSING_STR = ""

__all__ = ["BASE_FIELDS", "MISSING_FLOAT", "MISSING_INT", "MISSING_STR", "OPTIONAL_TEXT_ATTRS", "REQUIRED_ATTRS",
           "SCHEMA_VERSION", "STATUS_CODES", "STATUS_NAMES", "TEXT_ATTRS", "TEXT_FIELDS", "TableError"]


class TableError(LutgenError):
    """A look-up table (or build journal) is missing, corrupt, of another schema, or built for another model."""
