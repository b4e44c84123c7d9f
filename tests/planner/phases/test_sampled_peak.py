"""peak_magnitude (planner/phases/sampled_peak.py): a smooth curve's peak between its samples, against closed forms.

The references are the curves' own maxima (a sine's amplitude, a polynomial's vertex); the degenerate samplings
(a peak on a sample, at an end, a repeated instant, a flat or straight curve, too few samples) are tested on purpose.
"""

from __future__ import annotations

import numpy as np
import pytest

from planner.phases.sampled_peak import peak_magnitude

H_S = 0.1875  # the stabilization's dense spacing: 45 s, 60 via points, 4 instants each


@pytest.mark.parametrize("offset_s", np.linspace(0.0, H_S, 7))
def test_a_sines_peak_between_samples_is_found_where_the_largest_sample_misses_it(offset_s):
    # a torque-like peak: 10 N·m, curvature 12 N·m/s² at the top (ω² A = 12)
    omega = np.sqrt(1.2)
    t = np.arange(offset_s, 6.0, H_S)
    f = 10.0 * np.sin(omega * t)
    found = peak_magnitude(t, f)
    # a cubic through 4 samples errs by at most h⁴·max|f''''|/24 (6e-4 N·m here), mostly upwards: the safe side
    assert -1e-4 <= found - 10.0 <= H_S**4 * 10.0 * omega**4 / 24
    # h²/8·|f''| = 0.053 N·m is what the largest sample can miss by; at most offsets it misses by more than 1e-3
    assert 10.0 - np.abs(f).max() <= H_S**2 / 8 * 12.0 + 1e-12


def test_the_largest_sample_alone_misses_the_peak_by_the_curvature_bound():
    t = np.pi / 2 / np.sqrt(1.2) + (np.arange(-7, 7) + 0.5) * H_S  # the peak halfway between two samples
    f = 10.0 * np.sin(np.sqrt(1.2) * t)
    assert 10.0 - np.abs(f).max() > 0.04  # what the check before the cubic accepted
    assert -1e-4 <= peak_magnitude(t, f) - 10.0 <= H_S**4 * 10.0 * 1.2**2 / 24


def test_negative_peaks_and_several_curves_count_by_magnitude():
    t = np.linspace(0.0, 4.0, 23)
    curves = np.column_stack([np.sin(t), -3.0 * np.exp(-((t - 1.37) ** 2)), 0.5 * t])
    assert peak_magnitude(t, curves) == pytest.approx(3.0, abs=5e-3)  # the Gaussian's trough, between samples


def test_degenerate_samplings():
    t = np.linspace(0.0, 2.0, 9)
    # a parabola's vertex exactly on a sample: the sample, not more
    assert peak_magnitude(t, 5.0 - (t - 1.0) ** 2) == pytest.approx(5.0, abs=1e-12)
    # rising to the last sample: the end value (nothing beyond the sampled interval)
    assert peak_magnitude(t, 2.0 * t + 1.0) == pytest.approx(5.0, abs=1e-12)
    # flat: every sample a maximum, nothing above it
    assert peak_magnitude(t, np.full_like(t, 7.0)) == pytest.approx(7.0, abs=1e-12)
    # a via point that is also a dense instant (1e-12 s apart, the same value): no spurious curvature
    doubled = np.sort(np.concatenate([t, [1.0 + 1e-12]]))
    values = 5.0 - (doubled - 1.0) ** 2
    assert peak_magnitude(doubled, values) == pytest.approx(5.0, abs=1e-9)
    # too few samples for a cubic: the largest sample
    assert peak_magnitude([0.0, 1.0, 2.0], [1.0, 3.0, 2.0]) == 3.0
    assert peak_magnitude([0.0], [[1.0, -2.0, 0.5]]) == 2.0
