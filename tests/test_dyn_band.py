"""The band LU kernels of the integrators (dband_lu, zband_lu and their solves,
the algorithm of LAPACK's dgbtf2/dgbtrs written out) against dense solves,
including matrices that need row interchanges, and their error exits."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

import beamid
from beamid import _core_dynamics as cd


def _band(n, kl, ku, rng, weak_diagonal):
    a = rng.standard_normal((n, n))
    i, j = np.indices((n, n))
    a[(i - j > kl) | (j - i > ku)] = 0.0
    if weak_diagonal:
        a[i == j] *= 1e-3          # partial pivoting must swap rows
    else:
        a[i == j] += 2.0 * (kl + ku + 1)
    return a


@pytest.mark.parametrize("n,kl,ku", [(1, 0, 0), (5, 1, 2), (33, 7, 7), (40, 3, 7), (12, 11, 11)])
@pytest.mark.parametrize("weak", [False, True])
def test_band_lu_matches_dense(n, kl, ku, weak):
    rng = np.random.default_rng(n * 100 + kl * 10 + ku + weak)
    a = _band(n, kl, ku, rng, weak)
    b = _band(n, kl, ku, rng, False) * 0.3
    r, s = rng.standard_normal(n), rng.standard_normal(n)
    x, z = cd.band_solve(kl, ku, a, b, r, s)
    cond = np.linalg.cond(a)
    assert np.linalg.norm(a @ x - r) <= 1e-13 * cond * np.linalg.norm(r) + 1e-14
    assert_allclose(x, np.linalg.solve(a, r), rtol=1e-9 * max(1.0, cond / 1e3), atol=1e-12)
    assert_allclose(z, np.linalg.solve(a + 1j * b, r + 1j * s), rtol=1e-9, atol=1e-10)


def test_singular_band_is_reported():
    a = np.diag([1.0, 2.0, 0.0, 4.0])
    with pytest.raises(beamid.ConvergenceError, match="singular"):
        cd.band_solve(1, 1, a, np.zeros((4, 4)), np.ones(4), np.zeros(4))


@pytest.mark.parametrize("kl,ku", [(-1, 0), (0, 4), (4, 0)])
def test_bad_band_widths(kl, ku):
    with pytest.raises(beamid.InputError):
        cd.band_solve(kl, ku, np.eye(4), np.zeros((4, 4)), np.ones(4), np.zeros(4))


@pytest.mark.parametrize("n,kl,ku", [(30, 0, 3), (30, 3, 0), (300, 7, 7), (8, 7, 7)])
def test_band_lu_edge_widths(n, kl, ku):
    # one-sided bands, a long chain and a dense matrix stored as a band
    # (the modal systems); a weak diagonal, so that rows are swapped, only on
    # two-sided bands (on a one-sided band it makes the element growth, not
    # the kernels, decide the residual)
    rng = np.random.default_rng(7 * n + kl)
    a = _band(n, kl, ku, rng, kl > 0 and ku > 0)
    b = _band(n, kl, ku, rng, False) * 0.3
    r, s = rng.standard_normal(n), rng.standard_normal(n)
    x, z = cd.band_solve(kl, ku, a, b, r, s)
    cond = np.linalg.cond(a)
    assert np.linalg.norm(a @ x - r) <= 1e-13 * cond * np.linalg.norm(r) + 1e-14
    zc = a + 1j * b
    assert np.linalg.norm(zc @ z - (r + 1j * s)) <= (
        1e-13 * np.linalg.cond(zc) * np.linalg.norm(r + 1j * s) + 1e-14)


def test_singular_complex_band_is_reported():
    # A = [[0, 1], [1, 0]] is regular, A + iB = [[i, 1], [1, -i]] is not: the
    # complex factorization meets a zero pivot in column 2
    a = np.array([[0.0, 1.0], [1.0, 0.0]])
    b = np.array([[1.0, 0.0], [0.0, -1.0]])
    with pytest.raises(beamid.ConvergenceError, match="zero pivot 2"):
        cd.band_solve(1, 1, a, b, np.ones(2), np.zeros(2))


def _sym_band(n, k, rng, shift):
    a = rng.standard_normal((n, n))
    a = a + a.T
    i, j = np.indices((n, n))
    a[np.abs(i - j) > k] = 0.0
    a[i == j] += shift
    return a


@pytest.mark.parametrize("k", [7, 3, 0])
@pytest.mark.parametrize("n", [1, 5, 8, 9, 14, 15, 33, 100])
def test_symmetric_band_kernels_match_dense(n, k):
    # The Radau iteration matrices lam^2 M + lam C + K are factored as L D L^T
    # without pivoting (real: positive definite; complex: positive definite
    # imaginary part). Half-bandwidth 7, the rigid chain's, has constant
    # trip-count paths: n below, at and above 7 and 2 x 7 cover their edges.
    if k >= n:
        k = n - 1
    rng = np.random.default_rng(1000 * n + k)
    a = _sym_band(n, k, rng, 4.0 * (2 * k + 1) + 12.0)   # diagonally dominant: SPD
    b = _sym_band(n, k, rng, 4.0 * (2 * k + 1) + 12.0) * 0.5   # SPD imaginary part
    r, s = rng.standard_normal(n), rng.standard_normal(n)
    x, z, ax, az = cd.ldlt_solve(k, a, b, r, s)
    assert_allclose(x, np.linalg.solve(a, r), rtol=1e-12, atol=1e-14)
    assert_allclose(z, np.linalg.solve(a + 1j * b, r + 1j * s), rtol=1e-12, atol=1e-14)
    assert_allclose(ax, a @ r, rtol=1e-13, atol=1e-13)
    assert_allclose(az, (a + 1j * b) @ (r + 1j * s), rtol=1e-13, atol=1e-13)


def test_symmetric_band_kernels_refuse_bad_pivots():
    a = np.diag([1.0, -2.0, 3.0])
    with pytest.raises(beamid.InputError, match="pivot"):
        cd.ldlt_solve(1, a, np.eye(3), np.ones(3), np.zeros(3))
    with pytest.raises(beamid.InputError, match="n, k"):
        cd.ldlt_solve(3, np.eye(3), np.eye(3), np.ones(3), np.zeros(3))
