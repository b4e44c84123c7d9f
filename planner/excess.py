"""How far something is past its limits, in units of those limits: one rule for an NLP's iterates and a verified plan.

An excess is counted relative to the magnitude of its limit, so that rad, m and N·m add up as "limits over" (2 N·m
over a 10 N·m torque limit is 0.2, 1 cm short of a 2 cm clearance 0.5); where the limit is ~0 (a rate that must be
zero, a momentum drift) the excess counts in its own unit. A NaN makes the total infinite: it is never the least.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

ZERO_LIMIT = 1e-9  # a limit this close to 0 measures its excess in its own units


def relative_excess_sum(excess: ArrayLike, limit: ArrayLike) -> float:
    """Σ ``excess`` / |``limit``| (the excess itself where |limit| ≤ :data:`ZERO_LIMIT`); ``inf`` if any is NaN or
    infinite. ``excess`` ≥ 0, same shape as ``limit``."""
    excess, scale = np.asarray(excess, dtype=float), np.abs(np.asarray(limit, dtype=float))
    total = float(np.sum(excess / np.where(scale > ZERO_LIMIT, scale, 1.0)))
    return total if np.isfinite(total) else np.inf
