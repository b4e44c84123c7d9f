"""The observation error model: a small attitude rotation in the target body frame and a body-rate error, Gaussian.

The true state is drawn around the observed one: ``R_true = R_obs · Exp(δθ)`` with the rotation vector δθ
[rad] in the target body frame, and ``ω_true = ω_obs + δω`` [rad/s] in the body frame; ``[δθ; δω]`` is zero-mean
Gaussian with a 6×6 covariance (1-σ per axis: a diagonal one). Draws are standard normals ``z`` scaled by a
square root of the covariance and an error scale, so every scale of a sweep reuses the same ``z`` (common
random numbers: the success curve over scales is not blurred by fresh draws at each scale).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from planner.errors import LutgenError
from planner.model.rotation import quat_multiply
from planner.model.target_state import TargetState

Array = NDArray[np.float64]
PSD_TOL = 1e-12  # relative to the largest eigenvalue: a covariance eigenvalue above −this is taken as 0
SYMMETRY_TOL = 1e-9  # relative asymmetry of a covariance file accepted as rounding


class ErrorModelError(LutgenError):
    """A σ or a covariance that is not an error model: negative, not finite, not 6×6 symmetric PSD."""


@dataclass(frozen=True)
class ErrorModel:
    """Zero-mean Gaussian ``[δθ (rad, body frame); δω (rad/s, body frame)]`` with covariance ``covariance`` (6, 6)."""

    covariance: Array  # (6, 6) [rad², rad²/s, rad²/s²]

    @classmethod
    def from_sigmas(cls, attitude_sigma_rad: float, rate_sigma_rad_s: float) -> ErrorModel:
        """Independent axes: 1-σ ``attitude_sigma_rad`` [rad] per body axis, ``rate_sigma_rad_s`` [rad/s] per axis."""
        for name, value in (("attitude σ", attitude_sigma_rad), ("rate σ", rate_sigma_rad_s)):
            if not np.isfinite(value) or value < 0:
                raise ErrorModelError(f"{name}: must be a finite number >= 0, got {value}")
        return cls(np.diag([attitude_sigma_rad**2] * 3 + [rate_sigma_rad_s**2] * 3))

    @classmethod
    def from_matrix(cls, matrix: Array, source: str) -> ErrorModel:
        """A full covariance, checked: 6×6, finite, symmetric, positive semi-definite."""
        c = np.asarray(matrix, dtype=float)
        if c.shape != (6, 6) or not np.all(np.isfinite(c)):
            raise ErrorModelError(f"{source}: expected a finite 6×6 covariance, got shape {c.shape}")
        scale = max(float(np.abs(c).max()), 1e-300)
        if np.abs(c - c.T).max() > SYMMETRY_TOL * scale:
            raise ErrorModelError(f"{source}: the covariance is not symmetric")
        eig = np.linalg.eigvalsh((c + c.T) / 2)
        if eig.min() < -PSD_TOL * scale:
            raise ErrorModelError(f"{source}: the covariance is not positive semi-definite "
                                  f"(eigenvalue {eig.min():.3g})")
        return cls((c + c.T) / 2)

    @classmethod
    def from_file(cls, path: str | Path) -> ErrorModel:
        """A covariance from a text file: 6 rows of 6 numbers (whitespace or commas; ``#`` comments)."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ErrorModelError(f"{path}: cannot read the covariance file ({exc})") from None
        rows = [line.split("#")[0].replace(",", " ").split() for line in text.splitlines()]
        rows = [r for r in rows if r]
        try:
            matrix = np.array([[float(v) for v in r] for r in rows], dtype=float)
        except ValueError:
            raise ErrorModelError(f"{path}: expected 6 rows of 6 numbers") from None
        if matrix.ndim != 2:
            raise ErrorModelError(f"{path}: expected 6 rows of 6 numbers")
        return cls.from_matrix(matrix, str(path))

    def square_root(self) -> Array:
        """``L`` (6, 6) with ``L Lᵀ`` = the covariance: ``diag(σ)`` for a diagonal one (so ``δᵢ = σᵢ zᵢ``), else the
        Cholesky factor, else (singular) from the eigen-decomposition."""
        c = self.covariance
        if not np.any(c - np.diag(np.diag(c))):
            return np.diag(np.sqrt(np.diag(c)))
        try:
            return np.linalg.cholesky(c)
        except np.linalg.LinAlgError:
            eig, vec = np.linalg.eigh(c)
            return vec * np.sqrt(np.clip(eig, 0.0, None))

    def sigmas(self) -> Array:
        """The 1-σ of each component (6,): attitude [rad] ×3, body rate [rad/s] ×3."""
        return np.sqrt(np.diag(self.covariance))


def standard_draws(n: int, seed: int) -> Array:
    """``n`` draws (n, 6) of independent standard normals from ``seed``."""
    return np.random.default_rng(seed).standard_normal((n, 6))


def perturbed_states(observed: TargetState, model: ErrorModel, z: Array, scale: float) -> list[TargetState]:
    """True states ``observed`` ⊕ ``scale``·L·z, one per row of ``z`` (module docstring)."""
    deltas = scale * np.asarray(z, dtype=float) @ model.square_root().T
    states = []
    for d in deltas:
        if not np.any(d):
            states.append(observed)  # zero error: the observed state itself, bit for bit
            continue
        angle = float(np.linalg.norm(d[:3]))
        # q_obs ⊗ q(δθ): a body-frame rotation, and exactly q_obs at zero error
        q = np.asarray(observed.attitude_wxyz) if angle == 0.0 else quat_multiply(
            observed.attitude_wxyz, np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * d[:3] / angle]))
        states.append(TargetState(q / np.linalg.norm(q), np.asarray(observed.omega_body_rad_s) + d[3:]))
    return states
