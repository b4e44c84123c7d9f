"""Validation of the target model's inputs: inertia, vectors and times, with the field that failed."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.errors import FieldValueError, LutgenError

# Relative asymmetry of an inertia matrix that is still rounding noise (e.g. from a CAD export).
INERTIA_SYMMETRY_TOL = 1e-9
CONFIG_SOURCE = "target"  # what a mass-property error names as its source

FieldError = Callable[[str, str, Any], LutgenError]  # (field, problem, value) -> the error to raise


def frozen_copy(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Private read-only float copy, so a frozen dataclass really is immutable."""
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def validate_inertia(inertia_body: ArrayLike, field: str = "inertia_body_kg_m2") -> NDArray[np.float64]:
    """Check a 3×3 inertia [kg·m²] is finite, symmetric and positive definite; return it symmetrised."""
    try:
        inertia = np.asarray(inertia_body, dtype=float)
    except (TypeError, ValueError) as exc:
        raise FieldValueError(CONFIG_SOURCE, field, f"must be a 3x3 numeric matrix ({exc})", inertia_body) from None
    if inertia.shape != (3, 3):
        raise FieldValueError(CONFIG_SOURCE, field, f"must have shape (3, 3), got {inertia.shape}", inertia.shape)
    if not np.all(np.isfinite(inertia)):
        raise FieldValueError(CONFIG_SOURCE, field, "must be finite (got NaN or inf)", inertia)
    scale = float(np.max(np.abs(inertia)))
    if np.max(np.abs(inertia - inertia.T)) > INERTIA_SYMMETRY_TOL * max(scale, np.finfo(float).tiny):
        raise FieldValueError(CONFIG_SOURCE, field, "must be symmetric", inertia)
    inertia = 0.5 * (inertia + inertia.T)
    eigvals = np.linalg.eigvalsh(inertia)
    if eigvals[0] <= 0.0:
        raise FieldValueError(
            CONFIG_SOURCE, field, f"must be positive definite, got eigenvalues {np.array2string(eigvals)}", eigvals
        )
    return inertia


def validate_vector(value: ArrayLike, size: int, field: str, error: FieldError) -> NDArray[np.float64]:
    """Finite ``(size,)`` float vector, else ``error(field, problem, value)``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise error(field, f"must be a numeric vector of length {size} ({exc})", value) from None
    if v.shape != (size,):
        raise error(field, f"must have shape ({size},), got {v.shape}", value)
    if not np.all(np.isfinite(v)):
        raise error(field, f"must be finite, got {np.array2string(v)}", value)
    return v


def body_field_error(field: str, problem: str, value: Any) -> LutgenError:
    """A :class:`FieldValueError` of the target's mass properties (``target: field: problem``)."""
    return FieldValueError(CONFIG_SOURCE, field, problem, value)


def validate_times(times_s: ArrayLike, t_end_s: float) -> NDArray[np.float64]:
    """Times [s] as a 1-D array inside ``[0, t_end_s]``; scalars become length-1 arrays."""
    times = np.atleast_1d(np.asarray(times_s, dtype=float))
    if times.ndim != 1:
        raise ValueError(f"times_s must be a scalar or a 1-D array, got shape {times.shape}")
    if not np.all(np.isfinite(times)):
        raise ValueError("times_s must be finite")
    if times.size and times.min() < 0.0:
        raise ValueError(f"times_s must be >= 0, got {times.min()!r}")
    if times.size and times.max() > t_end_s:
        raise ValueError(f"times_s must be <= t_end_s = {t_end_s!r}, got {times.max()!r}")
    return times
