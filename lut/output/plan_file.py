"""Reading a ``lutgen.plan/1`` document (docs/table.md, Plan file) back, for the plots and the 3D preview.

The writer is :mod:`lut.output.export`. A reader checks only what it uses: the schema tag, the phases and
the sample arrays (equal length, the documented widths), so that a broken file fails here with one
line naming the file and the field, not deep inside matplotlib. Optional fields (``samples.min_distance_m``,
``samples.closest_pair``, ``samples.closest_points_m``, ``target.shapes``) are checked when present.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.errors import LutgenError

SCHEMA = "lutgen.plan/1"  # the same tag lut.output.export writes (not imported: export pulls in the whole planner)
REPO_ROOT = Path(__file__).resolve().parents[2]  # lut/output/plan_file.py → the repository

# sample key -> columns per row (1 = a plain vector)
SAMPLE_WIDTHS: dict[str, int] = {
    "t": 1, "q": 0, "qd": 0, "base_position": 3, "base_wxyz": 4, "ee_position": 3, "ee_wxyz": 4,
    "grasp_position": 3, "grasp_wxyz": 4, "target_position": 3, "target_wxyz": 4, "grasp_wrench": 6,
}  # 0: any width, but q and qd must agree
OPTIONAL_SAMPLE_WIDTHS: dict[str, int] = {"min_distance_m": 1}
PHASE_NAMES = ("approach", "tracking", "stabilization")

Array = NDArray[np.float64]


class PlanFileError(LutgenError):
    """A plan JSON file is missing, not JSON, of another schema, or lacks a field the viewer needs."""


def load_plan(path: str | Path) -> dict[str, Any]:
    """Read and check a plan JSON file (``.json`` or gzip-compressed ``.json.gz``); raise :class:`PlanFileError`."""
    path = Path(path)
    if not path.is_file():
        raise PlanFileError(f"{path}: no such plan file")
    try:
        raw = path.read_bytes()
        if raw[:2] == b"\x1f\x8b":  # gzip magic: test data and archived plans are stored compressed
            raw = gzip.decompress(raw)
        doc = json.loads(raw.decode("utf-8"))
    except (OSError, EOFError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise PlanFileError(f"{path}: not a plan JSON file ({str(exc).splitlines()[0]})") from None
    check_plan(doc, str(path))
    return doc


def check_plan(doc: Any, source: str = "plan") -> None:
    """Raise :class:`PlanFileError` naming ``source`` and the field unless ``doc`` is a usable plan document."""
    if not isinstance(doc, dict):
        raise PlanFileError(f"{source}: not a plan document (expected a JSON object, got {type(doc).__name__})")
    if doc.get("schema") != SCHEMA:
        raise PlanFileError(f"{source}: schema: expected {SCHEMA!r}, got {doc.get('schema')!r}")
    phases = doc.get("phases")
    if not isinstance(phases, dict) or any(name not in phases for name in PHASE_NAMES):
        raise PlanFileError(f"{source}: phases: expected {', '.join(PHASE_NAMES)} as [t_start, t_end]")
    for name in PHASE_NAMES:
        span = phases[name]
        if not (isinstance(span, list) and len(span) == 2 and all(isinstance(v, int | float) for v in span)):
            raise PlanFileError(f"{source}: phases.{name}: expected [t_start, t_end] in s, got {span!r}")
    samples = doc.get("samples")
    if not isinstance(samples, dict):
        raise PlanFileError(f"{source}: samples: missing")
    n = None
    for key, width in {**SAMPLE_WIDTHS, **{k: w for k, w in OPTIONAL_SAMPLE_WIDTHS.items() if k in samples}}.items():
        if key not in samples:
            raise PlanFileError(f"{source}: samples.{key}: missing")
        try:
            arr = np.asarray(samples[key], dtype=float)
        except (TypeError, ValueError):
            raise PlanFileError(f"{source}: samples.{key}: not an array of numbers") from None
        ok_shape = arr.ndim == 1 if width == 1 else (arr.ndim == 2 and (width == 0 or arr.shape[1] == width))
        if not ok_shape or arr.shape[0] < 2:
            raise PlanFileError(f"{source}: samples.{key}: expected ≥ 2 rows of {width or 'n'} values, "
                                f"got shape {arr.shape}")
        if n is None:
            n = arr.shape[0]
        elif arr.shape[0] != n:
            raise PlanFileError(f"{source}: samples.{key}: {arr.shape[0]} rows, samples.t has {n}")
    if np.shape(samples["q"]) != np.shape(samples["qd"]):
        raise PlanFileError(f"{source}: samples.qd: shape {np.shape(samples['qd'])} differs from q's")
    if np.any(np.diff(np.asarray(samples["t"], dtype=float)) <= 0):
        raise PlanFileError(f"{source}: samples.t: must be strictly increasing")
    for key, shape in (("closest_pair", ()), ("closest_points_m", (2, 3))):
        if key in samples and np.shape(samples[key]) != (n, *shape):
            raise PlanFileError(f"{source}: samples.{key}: expected shape {(n, *shape)}, got {np.shape(samples[key])}")
    shapes = doc.get("target", {}).get("shapes") if isinstance(doc.get("target"), dict) else None
    if shapes is not None:
        _check_shapes(shapes, source)


def _check_shapes(shapes: Any, source: str) -> None:
    """``target.shapes``: boxes (``size_m`` [3] > 0) and capsules (``radius_m`` > 0, ``length_m`` ≥ 0)."""
    if not isinstance(shapes, list):
        raise PlanFileError(f"{source}: target.shapes: expected a list of shapes")
    for i, s in enumerate(shapes):
        where = f"{source}: target.shapes[{i}]"
        if not isinstance(s, dict) or s.get("kind") not in ("box", "capsule"):
            raise PlanFileError(f"{where}: expected an object with kind 'box' or 'capsule'")
        try:
            if s["kind"] == "box":
                ok = np.shape(s["size_m"]) == (3,) and min(float(v) for v in s["size_m"]) > 0
            else:
                ok = float(s["radius_m"]) > 0 and float(s["length_m"]) >= 0
            placed = np.shape(s.get("position_m", [0, 0, 0])) == (3,) and np.shape(s.get("wxyz", [1, 0, 0, 0])) == (4,)
            ok = ok and placed
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise PlanFileError(f"{where}: a {s['kind']} needs " + ("size_m [3] > 0" if s["kind"] == "box" else
                                "radius_m > 0 and length_m >= 0") + ", position_m [3] and wxyz [4]")


def sample_arrays(doc: dict[str, Any]) -> dict[str, Array]:
    """Every numeric sample array as float64 (``closest_pair``, a list of str, is left out)."""
    return {key: np.asarray(value, dtype=float) for key, value in doc["samples"].items() if key != "closest_pair"}


def phase_spans(doc: dict[str, Any]) -> dict[str, tuple[float, float]]:
    """``{phase name: (t_start, t_end)}`` in s since the observation, in maneuver order."""
    return {name: (float(doc["phases"][name][0]), float(doc["phases"][name][1])) for name in PHASE_NAMES}


def resolve_robot_urdf(doc: dict[str, Any]) -> Path | None:
    """The robot URDF the plan names: as given if absolute, else against the current dir, then the repo root."""
    given = doc.get("robot_urdf")
    if not isinstance(given, str) or not given:
        return None
    path = Path(given)
    candidates = [path] if path.is_absolute() else [Path.cwd() / path, REPO_ROOT / path]
    for candidate in candidates:
        if candidate.is_file():
            return candidate.resolve()
    return None


def plan_label(doc: dict[str, Any]) -> str:
    """Short name of the plan for titles: scenario name and status."""
    return f"{doc.get('scenario', 'plan')}, {doc.get('status', '?')}"
