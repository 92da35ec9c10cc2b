"""The residual structure tests of compare (Fortran residual_structure)
against an independent reference, and their behaviour on known patterns."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import stats

from beamid import _core_estimation as ce


def reference(level, group, normalized):
    """Runs test on signs ordered by level within groups (first-appearance
    order), one-sided for few runs; least-squares trend of residuals on level."""
    order = []
    for g in dict.fromkeys(group):
        idx = [i for i in range(len(group)) if group[i] == g]
        order += sorted(idx, key=lambda i: level[i])
    signs = [1 if normalized[i] > 0 else 0 for i in order if normalized[i] != 0]
    n1, n2 = sum(signs), len(signs) - sum(signs)
    n = n1 + n2
    runs = 1 + sum(a != b for a, b in zip(signs, signs[1:]))
    mean = 2 * n1 * n2 / n + 1
    var = 2 * n1 * n2 * (2 * n1 * n2 - n) / (n * n * (n - 1))
    z = (runs - mean) / math.sqrt(var)
    p = stats.norm.cdf(z)                  # one-sided: few runs
    x = np.asarray(level, float) - np.mean(level)
    slope = float(x @ normalized / (x @ x))
    tz = slope * math.sqrt(float(x @ x))
    return [runs, mean, z, p, slope, tz, 2 * stats.norm.sf(abs(tz))]


@pytest.mark.parametrize("seed", range(5))
def test_structure_matches_reference(seed):
    rng = np.random.default_rng(seed)
    n = 24
    level = rng.choice([1.0, 2.0, 3.5, 5.0, 8.0], size=n)
    group = rng.integers(0, 3, size=n)
    normalized = rng.normal(size=n)
    got = ce.residual_structure(level, group, normalized)
    assert_allclose(got, reference(level, group, normalized), rtol=1e-9, atol=1e-12)


def test_a_trend_is_detected_and_noise_is_not():
    level = np.linspace(1.0, 8.0, 16)
    group = np.zeros(16, dtype=int)
    trend = ce.residual_structure(level, group, 0.6 * (level - 4.5))
    assert trend[3] < 1e-3 and trend[6] < 1e-3      # few runs, significant slope
    alternating = ce.residual_structure(level, group, np.where(np.arange(16) % 2, 1.0, -1.0))
    assert alternating[0] == 16 and alternating[3] > 0.99 and alternating[6] > 0.5


def test_undefined_cases_are_nan():
    one_sign = ce.residual_structure(np.array([1.0, 2.0, 3.0]), np.zeros(3, dtype=int),
                                     np.array([1.0, 2.0, 0.5]))
    assert all(math.isnan(v) for v in one_sign[:4]) and not math.isnan(one_sign[4])
    flat = ce.residual_structure(np.ones(4), np.zeros(4, dtype=int),
                                 np.array([1.0, -1.0, 1.0, -1.0]))
    assert all(math.isnan(v) for v in flat[4:])
