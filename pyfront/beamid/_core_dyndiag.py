"""Calls into the extension for the diagnosis of fits with time histories
(``fortran/api/beamid_api_dyndiag.f90``): the mixed static + release
problems of :mod:`beamid._core_estimation` (its :class:`Problem`), by the
calling convention of :func:`beamid._core._call` (fits by
:func:`beamid._core_estimation._fit_call`). Result arrays are read by the
column names the Fortran exports (``_core_estimation.CSTATS`` and friends).
"""
from __future__ import annotations

import numpy as np

from . import _ext
from ._core import _call
from ._core_estimation import (CSTATS, DSTATS, MSTATS, PSTATS, START_NAMES, Columns,
                               Problem, _mixed_values, _msg, _pad, _row_t)

_api = _ext.beamid_api_dyndiag


def time_structure(t: np.ndarray, normalized: np.ndarray) -> np.ndarray:
    """Structure in time of one series of normalized residuals: [runs,
    expected runs, runs z, runs p, lag-1 autocorrelation, its z, its p,
    amplitude slope (1/s), its z, its p] (NaN where undefined)."""
    return np.array(_api.api_time_structure(np.ascontiguousarray(t, dtype=float),
                                            np.ascontiguousarray(normalized, dtype=float)))


def problem_diagnose(prob: Problem, params0: np.ndarray, free: np.ndarray,
                     prior_idx: np.ndarray, prior_mean: np.ndarray, prior_sigma: np.ndarray,
                     blocks: list[np.ndarray], alpha: float, nrefit: int,
                     ambiguity_delta: float, collinear: float, nominal: np.ndarray,
                     with_mesh: bool = False, max_iter: int = 50) -> dict:
    """Score tests, refits, ranking, unseen candidates and the mesh test of
    any mix of static and release experiments (1-based indices; static
    experiments alone: the static diagnosis, every block tested as given);
    the refits also start from ``nominal``."""
    starts = np.cumsum([1] + [len(b) for b in blocks]).astype(np.int32)
    flat = (np.concatenate([np.asarray(b, np.int32) for b in blocks]).astype(np.int32)
            if blocks and sum(len(b) for b in blocks) else np.zeros(0, np.int32))
    (cstats, pstats, refit_params, ranking, cosine, dstats, refit_start, sep_t, mstats,
     mesh_params, kept, notes) = _call(
        _api.api_problem_diagnose, prob.nbeams, np.asarray(params0, float),
        np.asarray(nominal, float), np.asarray(free, np.int32), _pad(prior_idx, np.int32),
        _pad(prior_mean, float), _pad(prior_sigma, float), prob.exp_kind, _mixed_values(prob),
        prob.row_exp, _row_t(prob), prob.row_q, prob.row_value, prob.row_sigma,
        float(prob.tol), int(max_iter), starts, _pad(flat, np.int32), float(alpha),
        int(nrefit), float(ambiguity_delta), float(collinear), int(bool(with_mesh)))
    nc = len(blocks)
    lines = _msg(notes).rstrip().split("\n")
    lines += [""] * (nc - len(lines))
    return {"cstats": Columns(np.array(cstats).reshape(len(CSTATS), nc), CSTATS),
            "pstats": Columns(np.array(pstats).reshape(len(PSTATS), -1)[:, :-1], PSTATS),
            "refit_params": np.array(refit_params).reshape(-1, nc),
            "ranking": np.array(ranking, dtype=int) - 1,
            "cosine": np.array(cosine).reshape(nc, nc),
            "dstats": Columns(np.array(dstats), DSTATS),
            "starts": starts - 1, "refit_start": [START_NAMES.get(int(k)) for k in refit_start],
            "sep_t": np.array(sep_t), "mstats": Columns(np.array(mstats), MSTATS),
            "mesh_params": np.array(mesh_params),
            "kept": np.array(kept, dtype=int)[:-1] == 1,
            "ambiguous": np.array(kept, dtype=int)[:-1] == 2,
            "notes": [line.strip() for line in lines[:nc]]}
