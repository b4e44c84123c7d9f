"""The largest magnitude a smooth curve reaches between its samples: a local cubic through each sampled maximum.

The largest sample of a curve sampled every h misses its peak by up to h²/8·|f''|; a cubic through the four samples
around each sampled maximum finds it to O(h⁴·|f''''|) (README, the constants' measurements: ``DENSE_FACTOR``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

SAME_INSTANT_S = 1e-6  # samples closer than this are one instant (a via point that is also a dense instant)
REFINED_SHARE = 0.9  # only maxima within this share of the largest sample are refined: the others cannot win
FINE_STEPS = 64  # the cubic is maximised on this many sub-steps of the two intervals around the sample


def peak_magnitude(times_s: ArrayLike, values: ArrayLike) -> float:
    """max |f| of the smooth curves sampled as ``values`` (n,) or (n, m) (one curve per column) at the
    increasing instants ``times_s`` (n,) [s]: the largest sample, raised where a local cubic through the four
    samples around a sampled maximum rises above it. Units: those of ``values``."""
    t = np.asarray(times_s, dtype=float)
    v = np.asarray(values, dtype=float).reshape(len(t), -1)
    keep = np.concatenate([[True], np.diff(t) > SAME_INSTANT_S])
    t, v = t[keep], v[keep]
    peak = float(np.abs(v).max(initial=0.0))
    if len(t) < 4:
        return peak
    for curve in np.hstack([v, -v]).T:
        for i in _sampled_maxima(curve, REFINED_SHARE * peak):
            peak = max(peak, _cubic_peak(t, curve, i))
    return peak


def _sampled_maxima(curve: Array, floor: float) -> Array:
    """Indices of the interior samples at least as high as both neighbours and above ``floor``."""
    inner = np.arange(1, len(curve) - 1)
    high = (curve[inner] >= curve[inner - 1]) & (curve[inner] >= curve[inner + 1]) & (curve[inner] > floor)
    ends = [i for i in (0, len(curve) - 1) if curve[i] > floor]  # a maximum at an end rises inward only
    return np.concatenate([inner[high], np.array(ends, dtype=int)])


def _cubic_peak(t: Array, curve: Array, i: int) -> float:
    """The largest value on [t[i-1], t[i+1]] of the cubics through samples i-2…i+1 and i-1…i+2 (those that exist)."""
    lo, hi = t[max(i - 1, 0)], t[min(i + 1, len(t) - 1)]
    fine = np.linspace(lo, hi, 2 * FINE_STEPS + 1) - t[i]
    best = curve[i]
    for first in {min(max(f, 0), len(t) - 4) for f in (i - 2, i - 1)}:  # near an end both clip to one window
        window = slice(first, first + 4)
        coeffs = np.polyfit(t[window] - t[i], curve[window], 3)
        best = max(best, float(np.polyval(coeffs, fine).max()))
    return best
