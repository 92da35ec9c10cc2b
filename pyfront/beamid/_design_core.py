"""The only module that calls the extension for experiment design and Monte
Carlo summaries (``fortran/api/beamid_api_design.f90``, module
``beamid_design``)."""
from __future__ import annotations

import numpy as np

from . import _ext
from .errors import raise_for_status

_api = _ext.beamid_api_design


def information_covariance(info: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, int]:
    """(cov, sigmas, D-criterion det(cov)^(1/(2n)), rank) of an information matrix."""
    info = np.asfortranarray(info, dtype=float)
    cov, sig, dcrit, rank, code, message = _api.api_information_covariance(info)
    raise_for_status(int(code), message)
    return np.array(cov), np.array(sig), float(dcrit), int(rank)


def information_update(info: np.ndarray, rows: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """info + sum of g g^T / sigma^2 over the columns g of rows (n_free x m)."""
    rows = np.asfortranarray(rows, dtype=float)
    return np.array(_api.api_information_update(np.asfortranarray(info, dtype=float), rows,
                                                np.asarray(sigma, float)))


def rank_candidates(info: np.ndarray, rows: np.ndarray, sigma: np.ndarray,
                    target: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(criterion now, criterion after each candidate, order best first, 0-based).
    rows is n_free x n_candidates; target is 1-based (0: D-criterion)."""
    info = np.asfortranarray(info, dtype=float)
    rows = np.asfortranarray(rows, dtype=float)
    base, crit, order, code, message = _api.api_rank_candidates(
        info, rows, np.asarray(sigma, float), int(target))
    raise_for_status(int(code), message)
    return float(base), np.array(crit), np.array(order, dtype=int) - 1


def mc_summary(est: np.ndarray, sig: np.ndarray, truth: np.ndarray,
               use: np.ndarray) -> np.ndarray:
    """Rows: coverage 1, 2, 3 sigma, bias, spread, rms sigma, ratio, z mean,
    z std, count; one column per parameter."""
    return np.array(_api.api_mc_summary(
        np.asfortranarray(est, dtype=float), np.asfortranarray(sig, dtype=float),
        np.asarray(truth, float), np.asarray(use, np.int32)))


def chi2_sf_many(x: np.ndarray, k: np.ndarray) -> np.ndarray:
    """P(chi2(k) > x) elementwise."""
    return np.array(_api.api_chi2_sf_many(np.asarray(x, float), np.asarray(k, np.int32)))
