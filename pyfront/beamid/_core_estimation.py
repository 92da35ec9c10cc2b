"""The only module that calls the extension for estimation, diagnosis, the
improve ladder, experiment design and Monte Carlo summaries.

An estimation problem (any mix of static and release experiments) crosses
the boundary as plain arrays (see ``fortran/api/beamid_api_estimation.f90``):
experiments as kinds and named specs (sparse triples: experiment, key of the
core's key table ``_core.spec_keys``, value), data rows as (experiment
index, t, quantity code, value, sigma), 1-based parameter indices. Result
arrays are read by the column names the Fortran exports (CSTATS and friends).

The calling convention is :func:`beamid._core._call` (the status is the
last two results; a bad one raises). Fits are the exception that
:func:`_fit_call` makes: a fit that fails still returns its last point,
attached to the exception as ``exc.partial``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from . import _ext
from ._core import (DeckHandle, Handle, _call, _text, quantity_labels, spec_column, spec_keys,
                    spec_triples_of)
from .errors import InputError, raise_for_status

_api = _ext.beamid_api_estimation
_deck_api = _ext.beamid_api_deck
_design = _ext.beamid_api_design   # beamid_design: information algebra, MC summaries

#: Observation kind codes of the Fortran core (beamid_observations' one table).
QUANTITY_NAMES = dict(enumerate(quantity_labels(), start=1))
QUANTITY_CODES = {v: k for k, v in QUANTITY_NAMES.items()}


@dataclass(frozen=True)
class Problem:
    """Arrays describing an estimation problem of any mix of static and
    release experiments (0-based nothing: the indices here are already
    1-based for Fortran)."""

    nbeams: int
    exp_kind: np.ndarray      # (nexp,) int32
    #: each experiment's spec by the core's key names (``_core.spec_keys``:
    #: fx, elements_per_beam, t0, ...); a key not given (or 0) takes its
    #: default in the core. It crosses as named triples (specs())
    exp_specs: tuple[Mapping[str, float], ...]
    row_exp: np.ndarray       # (nrow,) int32, 1-based
    row_q: np.ndarray         # (nrow,) int32
    row_value: np.ndarray     # (nrow,)
    row_sigma: np.ndarray     # (nrow,)
    row_t: np.ndarray         # (nrow,) times of the rows (0 for static experiments)
    tol: float = 0.0
    #: the observation list row_q indexes (kind code, beam, arc length s of
    #: each entry; None: row_q are kind codes)
    obs_kind: np.ndarray | None = None
    obs_beam: np.ndarray | None = None
    obs_s: np.ndarray | None = None
    #: the names of the observation list's entries (None: the kind names)
    obs_labels: tuple[str, ...] | None = None
    #: the release experiments' load histories, their own list beside the
    #: specs: a column [experiment (1-based), beamid_loads' 9 values]
    #: per history (10, nh) and the table rows (2, ntab) they refer to
    hist_spec: np.ndarray | None = None
    hist_tab: np.ndarray | None = None

    def __post_init__(self) -> None:
        # each spec a dict of its own (a caller's dict changed later does
        # not change the problem)
        object.__setattr__(self, "exp_specs", tuple(dict(s) for s in self.exp_specs))

    @property
    def exp_values(self) -> np.ndarray:
        """The specs in the legacy positional form, read-only and derived
        from :attr:`exp_specs`: (NEXPVAL, nexp), row spec_keys()[name].row for
        key ``name`` (0: not given)."""
        values = np.zeros((NEXPVAL, len(self.exp_specs)), order="F")
        for j, spec in enumerate(self.exp_specs):
            values[:, j] = spec_column(spec)
        values.setflags(write=False)
        return values

    def histories(self) -> tuple[np.ndarray, np.ndarray]:
        """The load histories as the binding takes them (none: empty)."""
        spec = np.zeros((10, 0), order="F") if self.hist_spec is None else self.hist_spec
        tab = np.zeros((2, 1), order="F") if self.hist_tab is None else self.hist_tab
        return np.asfortranarray(spec, float), np.asfortranarray(tab, float)

    def observations(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The observation list as the binding takes it."""
        if self.obs_kind is None:
            n = len(QUANTITY_NAMES)
            return (np.arange(1, n + 1, dtype=np.int32), np.zeros(n, np.int32), np.zeros(n))
        return (np.asarray(self.obs_kind, np.int32), np.asarray(self.obs_beam, np.int32),
                np.asarray(self.obs_s, float))

    def observation_names(self) -> tuple[str, ...]:
        """The names of the observation list's entries, in its order."""
        if self.obs_labels is not None:
            return tuple(self.obs_labels)
        if self.obs_kind is None:
            return tuple(QUANTITY_NAMES.values())
        return tuple(QUANTITY_NAMES[int(k)] + (f"@{int(b)}:{float(s):g}" if b > 0 else "")
                     for k, b, s in zip(self.obs_kind, self.obs_beam, self.obs_s))

    def specs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The experiments' specs as the binding takes them: sparse triples
        (1-based experiment, key number, value) by the core's key names."""
        return spec_triples_of(self.exp_specs)

    def rows(self) -> tuple:
        """The experiments, the rows and the tolerance in the order the fit,
        diagnose and ladder entries take them."""
        return (self.exp_kind, *self.specs(), self.row_exp, self.row_t, self.row_q,
                *self.observations(), self.row_value, self.row_sigma, float(self.tol),
                *self.histories())


#: the number of keys of an experiment's spec (the core's key table), the
#: rows of :attr:`Problem.exp_values`
NEXPVAL = len(spec_keys())


def problem_predict(prob: Problem, params: np.ndarray,
                    wrt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predictions and d/d params(wrt) of any mix of static and release
    experiments (beamid_inverse; wrt 1-based)."""
    wrt = np.asarray(wrt, dtype=np.int32)
    pred, jac = _call(_api.api_problem_predict,
                      prob.nbeams, np.asarray(params, float), prob.exp_kind, *prob.specs(),
                      prob.row_exp, prob.row_t, prob.row_q, *prob.observations(), wrt,
                      float(prob.tol), *prob.histories())
    return np.array(pred), np.array(jac).reshape(prob.row_exp.size, wrt.size)


def prior_table(rows) -> np.ndarray:
    """A priori information as the binding takes it: a column [1-based
    parameter index, mean, sigma] per parameter (``rows``: those triples)."""
    return np.asfortranarray(np.array(rows, float).T.reshape(3, -1))


def chi2_sf(x: float, k: int) -> float:
    """Chi-square survival function (Fortran)."""
    return float(_api.api_chi2_sf(float(x), int(k)))


def code_names(table: int) -> dict[int, str]:
    """A code table of the core by position from 0 (defined once, in Fortran):
    1 parameter flags, 2 how a fit ended, 3 refit starts, 4 candidate states,
    5-9 result columns, 10 load targets and 11 history kinds (beamid_loads,
    whose codes are the positions + 1)."""
    names, code = _api.api_code_names(int(table))
    raise_for_status(int(code), f"no code table {table}")
    return dict(enumerate(_text(names).strip().split(";")))


@dataclass(frozen=True)
class EffectRow:
    """One effect of the core's table (beamid_effects) for a chain of a
    given number of beams: ``kinds`` the families that can see it,
    ``ranks`` its place among each family's default candidates (by family
    name; 0: not a default), ``params`` its parameter indices (0-based)."""

    name: str
    description: str
    kinds: tuple[str, ...]
    ranks: dict
    null_value: float
    lower: float
    upper: float
    params: tuple[int, ...]


@functools.lru_cache(maxsize=None)
def effect_table(nbeams: int) -> dict[str, EffectRow]:
    """The effects table of the core for a chain of ``nbeams`` beams, by name
    in the core's order (api_effect_table; bounds of +-huge come back as
    +-inf)."""
    neffect, nindex = _api.api_effect_sizes(int(nbeams))
    text, ranks, values, starts, indices = _call(_api.api_effect_table, int(nbeams), neffect,
                                                 nindex)
    lines = _text(text).rstrip("\n").split("\n")
    families = lines[0].split("\t")
    big = np.finfo(float).max
    out = {}
    for e, line in enumerate(lines[1:]):
        name, description = line.split("\t")
        null, lower, upper = (float(v) if abs(v) < big else float(np.sign(v) * np.inf)
                              for v in values[:, e])
        out[name] = EffectRow(
            name, description, tuple(f for f, r in zip(families, ranks[:, e]) if r > 0),
            {f: int(r) for f, r in zip(families, ranks[:, e])}, null, lower, upper,
            tuple(int(i) - 1 for i in indices[starts[e] - 1:starts[e + 1] - 1]))
    return out


def default_effects(kind: str) -> tuple[str, ...]:
    """The default candidates of a family (``static`` or ``dynamic``), in
    their order (the core's table)."""
    rows = [r for r in effect_table(1).values() if r.ranks[kind] > 0]
    return tuple(r.name for r in sorted(rows, key=lambda r: r.ranks[kind]))


#: Parameter flags (FLAG_*), how a fit ended (STOP_*), the refit start kept
#: (START_*; 0: none) and candidate states (CAND_*), from the Fortran tables.
FLAG_NAMES = code_names(1)
STOP_NAMES = code_names(2)
START_NAMES = {k: (v or None) for k, v in code_names(3).items()}
CANDIDATE_STATES = code_names(4)


def _columns(table: int) -> dict[str, int]:
    """Column name -> 0-based row of a result array (api_code_names 5-8)."""
    return {name: k for k, name in code_names(table).items()}


#: the columns of a fit's stats, of a diagnosis' cstats, pstats, dstats, and
#: of the mesh test's mstats (dynamic diagnosis)
FIT_STATS = _columns(5)
CSTATS = _columns(6)
PSTATS = _columns(7)
DSTATS = _columns(8)
MSTATS = _columns(9)


class Columns:
    """Rows of a result array by their Fortran names: ``cols["chi2"]``."""

    def __init__(self, array: np.ndarray, names: dict[str, int]) -> None:
        self._a, self._names = np.asarray(array), names

    def __getitem__(self, name: str) -> np.ndarray:
        return self._a[self._names[name]]


def _fit_dict(out, n: int) -> dict:
    (params, sigmas, cov, corr, flags, pred, norm, stats, log_cost, log_lambda, log_step,
     log_params, info, code, message, note) = out
    st = Columns(stats, FIT_STATS)
    nlog = int(st["nlog"]) + 1
    return {
        "params": np.array(params), "sigmas": np.array(sigmas),
        "cov": np.array(cov).reshape(n, n), "corr": np.array(corr).reshape(n, n),
        "flags": np.array(flags, dtype=int), "predictions": np.array(pred),
        "normalized": np.array(norm), "chi2": float(st["chi2"]),
        "chi2_prior": float(st["chi2_prior"]), "cond": float(st["cond"]),
        "dof": int(st["dof"]), "rank": int(st["rank"]),
        "iterations": int(st["iterations"]), "converged": bool(st["converged"]),
        "log_cost": np.array(log_cost[:nlog]), "log_lambda": np.array(log_lambda[:nlog]),
        "log_step": np.array(log_step[:nlog]),
        "log_params": np.array(log_params).reshape(n, -1)[:, :nlog],
        "stop": STOP_NAMES.get(int(info[0]), "stalled"), "start": START_NAMES.get(int(info[1])),
        "note": _text(note).strip(), "code": int(code), "message": _text(message).strip(),
    }


def _fit_call(entry, n: int, refit: bool, *args) -> dict:
    """Call a fit entry point (results as api_fit_effect's, ``n`` free
    parameters) and return :func:`_fit_dict`; a bad status raises with the
    result in ``exc.partial`` (a refit none of whose starts converged says
    what each start gave: the Fortran message holds 256 characters, the
    notes all of it)."""
    result = _fit_dict(entry(*args), n)
    code, message = result["code"], result["message"]
    if code != 0:
        if code == 1 and result["note"] and refit:
            message = f"refit: no start converged: {result['note']}"
        try:
            raise_for_status(code, message)
        except Exception as exc:
            exc.partial = result  # type: ignore[attr-defined]
            raise
    return result


def fit(prob: Problem, params0: np.ndarray, free: np.ndarray, prior: np.ndarray,
        max_iter: int = 50, block: np.ndarray | None = None, nominal: np.ndarray | None = None,
        start_mask: int = 0, prior_cov: np.ndarray | None = None) -> dict:
    """Weighted Gauss-Newton/LM fit of any mix of experiment families
    (``block`` empty), or the refit of a fit at ``params0`` with the
    parameters ``block`` freed as well, from the first-order estimate, from
    ``nominal`` and by continuation (1-based indices; ``start_mask`` bits 1,
    2, 4 choose the first-order, nominal and continuation starts, 0 all);
    ``prior`` a :func:`prior_table`, with ``prior_cov`` a full covariance (a
    previous fit carried forward, Eq. 146-148).
    Returns a dict of arrays; a fit that stalls or whose parameter runs away
    comes back with ``stop`` and ``note`` saying so. Raises ConvergenceError
    (with the partial result in ``exc.partial``) when still moving at
    ``max_iter`` or when no refit start converged."""
    free = np.asarray(free, dtype=np.int32)
    block = np.zeros(0, np.int32) if block is None else np.asarray(block, np.int32)
    params0 = np.asarray(params0, float)
    nominal = params0 if nominal is None else np.asarray(nominal, float)
    cov = np.zeros(0) if prior_cov is None else np.ravel(prior_cov, order="F").astype(float)
    return _fit_call(_api.api_fit_effect, free.size + block.size, bool(block.size),
                     prob.nbeams, params0, free, block, nominal, prior, cov, *prob.rows(),
                     int(max_iter), int(start_mask))


def time_structure(t: np.ndarray, normalized: np.ndarray) -> np.ndarray:
    """Structure in time of one series of normalized residuals: [runs,
    expected runs, runs z, runs p, lag-1 autocorrelation, its z, its p,
    amplitude slope (1/s), its z, its p] (NaN where undefined)."""
    return np.array(_api.api_time_structure(np.ascontiguousarray(t, dtype=float),
                                            np.ascontiguousarray(normalized, dtype=float)))


def _blocks(blocks: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Candidate blocks as (starts, flat parameter list)."""
    starts = np.cumsum([1] + [len(b) for b in blocks]).astype(np.int32)
    flat = [np.asarray(b, np.int32) for b in blocks]
    return starts, (np.concatenate(flat) if flat else np.zeros(0)).astype(np.int32)


def _diag_dict(out, starts: np.ndarray) -> dict:
    """The dict of :func:`problem_diagnose` from the outputs of a diagnosis entry."""
    (cstats, pstats, refit_params, ranking, cosine, dstats, refit_start, sep_t, mstats,
     mesh_params, kept, notes) = out
    nc = starts.size - 1
    lines = _text(notes).rstrip().split("\n")
    lines += [""] * (nc - len(lines))
    return {"cstats": Columns(np.array(cstats).reshape(len(CSTATS), nc), CSTATS),
            "pstats": Columns(np.array(pstats).reshape(len(PSTATS), -1), PSTATS),
            "refit_params": np.array(refit_params).reshape(-1, nc) if nc else np.zeros((0, 0)),
            "ranking": np.array(ranking, dtype=int) - 1,
            "cosine": np.array(cosine).reshape(nc, nc),
            "dstats": Columns(np.array(dstats), DSTATS),
            "starts": starts - 1, "refit_start": [START_NAMES.get(int(k)) for k in refit_start],
            "sep_t": np.array(sep_t), "mstats": Columns(np.array(mstats), MSTATS),
            "mesh_params": np.array(mesh_params),
            "kept": np.array(kept, dtype=int) == 1,
            "ambiguous": np.array(kept, dtype=int) == 2,
            "notes": [line.strip() for line in lines[:nc]]}


def problem_diagnose(prob: Problem, params0: np.ndarray, free: np.ndarray, prior: np.ndarray,
                     blocks: list[np.ndarray], alpha: float, nrefit: int,
                     ambiguity_delta: float, collinear: float, nominal: np.ndarray,
                     with_mesh: bool = False, max_iter: int = 50) -> dict:
    """Score tests, refits, ranking, unseen candidates and the mesh test of
    any mix of static and release experiments (1-based indices; static
    experiments alone: the static diagnosis, every block tested as given);
    the refits also start from ``nominal``."""
    starts, flat = _blocks(blocks)
    return _diag_dict(_call(
        _api.api_problem_diagnose, prob.nbeams, np.asarray(params0, float),
        np.asarray(nominal, float), np.asarray(free, np.int32), prior, *prob.rows(),
        int(max_iter), starts, flat, float(alpha), int(nrefit),
        float(ambiguity_delta), float(collinear), int(bool(with_mesh))), starts)


class LadderHandle(Handle):
    """An improve ladder (Fortran beamid_ladder, the one beamid-batch runs)
    held in the extension under a handle that this object owns: started by
    :func:`ladder_start`, stepped by :func:`ladder_step`, its rungs returned
    by :func:`ladder_rungs`. Ladders of several handles (several threads'
    ``improve`` calls) are independent; :meth:`close` (or the end of a
    ``with`` block, or the collection of the object) releases the ladder."""

    def __init__(self, handle: int) -> None:
        super().__init__(handle, _api.api_ladder_close)

    def __repr__(self) -> str:
        return f"LadderHandle({self.id}, {'closed' if self.closed else 'open'})"


def ladders_open() -> int:
    """The number of ladders the extension holds (handles not yet closed)."""
    return int(_api.api_ladder_handles_open())


def ladder_start(prob: Problem, params0: np.ndarray, free: np.ndarray, prior: np.ndarray,
                 blocks: list[np.ndarray], with_mesh: bool, alpha: float, max_steps: int,
                 max_iter: int = 50, gross: bool = False, noise: bool = False) -> LadderHandle:
    """Start an improve ladder (Fortran beamid_ladder, the one beamid-batch
    runs) with the fit of ``params0[free]`` and return its handle:
    :func:`ladder_step` runs its rungs, :func:`ladder_rungs` returns them.
    ``gross``, ``noise``: the measurement chain's row candidates
    (beamid_ladder row_rung)."""
    starts, flat = _blocks(blocks)
    handle = _call(_api.api_ladder_open, prob.nbeams, np.asarray(params0, float),
                   np.asarray(free, np.int32), prior, *prob.rows(), int(max_iter), starts,
                   flat, int(bool(with_mesh)) | 2 * bool(gross) | 4 * bool(noise),
                   float(alpha), int(max_steps))
    return LadderHandle(handle)


def _entries(run: LadderHandle | DeckHandle) -> tuple:
    """The step, rung, fit, rows and diag entries of a run's ladder, its
    handle bound: a problem's (:func:`ladder_start`) or a deck's
    (:func:`deck_task_start`)."""
    if isinstance(run, LadderHandle):
        entries = (_api.api_ladder_handle_step, _api.api_ladder_handle_rung,
                   _api.api_ladder_handle_fit, _api.api_ladder_handle_rows,
                   _api.api_ladder_handle_diag)
    elif isinstance(run, DeckHandle):
        entries = (_deck_api.api_deck_handle_step, _deck_api.api_deck_handle_rung,
                   _deck_api.api_deck_handle_fit, _deck_api.api_deck_handle_rows,
                   _deck_api.api_deck_handle_diag)
    else:
        raise InputError(f"run: {run!r}, expected a LadderHandle (ladder_start) or a "
                         "DeckHandle (deck_task_start)")
    return tuple(functools.partial(entry, run._id()) for entry in entries)


def ladder_step(run: LadderHandle | DeckHandle) -> bool:
    """Diagnose the last fit of the ladder of ``run`` and, unless the ladder
    ends there, add the verdict's effect and refit (one rung); True once the
    ladder has ended. ``run``: the handle :func:`ladder_start` returned, or a
    deck's handle its ladder was started on (:func:`deck_task_start`)."""
    _nrung, done = _call(_entries(run)[0])
    return bool(done)


def ladder_rungs(nparams: int, blocks: list[np.ndarray],
                 run: LadderHandle | DeckHandle) -> list[dict]:
    """The rungs of the ladder of ``run`` ended by :func:`ladder_step`: per
    rung a dict with ``effect`` (None for the start, else the candidate's
    1-based number or effect name, or ``"mesh (N elements per beam)"``),
    ``fit`` (the dict of :func:`fit`), ``diag`` (of
    :func:`problem_diagnose`), ``free``, ``params`` (switched on),
    ``removed`` (set back), ``start`` and ``nominal`` (parameter vectors),
    ``elements_per_beam`` (of the releases, 0: as given) and
    ``refit_start``, returned from the run's handle."""
    starts, flat = _blocks(blocks)
    step, rung, fit_, rows_, diag = _entries(run)
    nrung, _done = _call(step)   # an ended ladder: no step, the count
    rungs = []
    for k in range(1, int(nrung) + 1):
        info, free_k, added, removed, start, nominal, effect = _call(rung, k, nparams)
        nfree = int(info[0])
        effect = _text(effect).strip()
        rungs.append({
            "effect": None if effect == "start" else effect,
            "fit": _fit_call(fit_, nfree, False, k, nparams, nfree, int(info[3]),
                             int(info[4])),
            "diag": _diag_dict(_call(diag, k, nparams, starts.size - 1, flat.size), starts),
            "free": np.array(free_k[:nfree]) - 1, "params": added[added > 0] - 1,
            "removed": removed[removed > 0] - 1, "start": np.array(start),
            "nominal": np.array(nominal), "elements_per_beam": int(info[1]),
            "refit_start": START_NAMES.get(int(info[2])),
            "rows": _ladder_rows(rows_, k, int(info[3]))})
    return rungs


def _ladder_rows(rows, k: int, nrow: int) -> dict | None:
    """The rows of rung ``k``'s fit as the measurement chain's treatments
    judged them (the keys :func:`fit_chain` adds), None for a plain fit;
    ``rows``: the rows entry of the run's handle (:func:`_entries`)."""
    weights, sigma_used, sigma_sd, flagged, has = _call(rows, k, nrow)
    if not has:
        return None
    return {"weights": np.array(weights), "sigma_used": np.array(sigma_used),
            "sigma_sd": np.array(sigma_sd), "flagged": np.array(flagged, dtype=bool)}


def residual_structure(level: np.ndarray, group: np.ndarray,
                       normalized: np.ndarray) -> np.ndarray:
    """Runs and trend tests of compare: [runs, expected runs, runs z, runs p,
    slope, trend z, trend p] (NaN where undefined)."""
    return np.array(_api.api_residual_structure(
        np.ascontiguousarray(level, dtype=float), np.ascontiguousarray(group, dtype=np.int32),
        np.ascontiguousarray(normalized, dtype=float)))


# ------------------------------------------- experiment design, Monte Carlo summaries

def information_covariance(info: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, int]:
    """(cov, sigmas, D-criterion det(cov)^(1/(2n)), rank) of an information matrix."""
    info = np.asfortranarray(info, dtype=float)
    cov, sig, dcrit, rank = _call(_design.api_information_covariance, info)
    return np.array(cov), np.array(sig), float(dcrit), int(rank)


def information_update(info: np.ndarray, rows: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """info + sum of g g^T / sigma^2 over the columns g of rows (n_free x m)."""
    rows = np.asfortranarray(rows, dtype=float)
    return np.array(_design.api_information_update(np.asfortranarray(info, dtype=float), rows,
                                                np.asarray(sigma, float)))


def rank_candidates(info: np.ndarray, rows: np.ndarray, sigma: np.ndarray,
                    target: int) -> tuple[float, np.ndarray, np.ndarray]:
    """(criterion now, criterion after each candidate, order best first, 0-based).
    rows is n_free x n_candidates; target is 1-based (0: D-criterion)."""
    info = np.asfortranarray(info, dtype=float)
    rows = np.asfortranarray(rows, dtype=float)
    base, crit, order = _call(_design.api_rank_candidates, info, rows, np.asarray(sigma, float),
                              int(target))
    return float(base), np.array(crit), np.array(order, dtype=int) - 1


def mc_summary(est: np.ndarray, sig: np.ndarray, truth: np.ndarray,
               use: np.ndarray) -> np.ndarray:
    """Rows: coverage 1, 2, 3 sigma, bias, spread, rms sigma, ratio, z mean,
    z std, count; one column per parameter."""
    return np.array(_design.api_mc_summary(
        np.asfortranarray(est, dtype=float), np.asfortranarray(sig, dtype=float),
        np.asarray(truth, float), np.asarray(use, np.int32)))


def chi2_sf_many(x: np.ndarray, k: np.ndarray) -> np.ndarray:
    """P(chi2(k) > x) elementwise."""
    return np.array(_design.api_chi2_sf_many(np.asarray(x, float), np.asarray(k, np.int32)))


# ------------------------------------------- estimation decks: the deck's fit runs once

def deck_task_start(deck: DeckHandle, task: str = "", stage: int = 0) -> None:
    """Start the ladder of an estimation deck run as ``task`` (default the
    deck's) as beamid-batch runs it: the fit (undiagnosed for fit and
    compare; of an identify deck the fit of ``stage``, 1-based, from the
    stages fitted by the calls before); :func:`ladder_step` diagnoses
    (diagnose: one rung, improve: a rung per call), :func:`ladder_rungs`
    reads it, :func:`deck_task_write` writes the deck's files.

    ``deck`` a :class:`beamid._core.DeckHandle`: the deck read once, its run
    held by the handle (pass the handle to :func:`ladder_step`,
    :func:`ladder_rungs` and :func:`deck_task_write`; hold ``handle.lock``
    from the start to the write). A path is refused: the run of a deck
    lives in its handle, never found again by path."""
    _call(_deck_api.api_deck_handle_start, _deck(deck)._id(), task, int(stage))


def _deck(deck) -> DeckHandle:
    """``deck`` if a DeckHandle; else InputError naming it."""
    if not isinstance(deck, DeckHandle):
        raise InputError(f"deck: {deck!r}, expected a beamid._core.DeckHandle (the run of a "
                         "deck is held by its handle, not found by path)")
    return deck


def deck_task_write(deck: DeckHandle, task: str = "", output: str = "") -> list[str]:
    """Write the files of the deck run (all or none, the bytes of
    beamid-batch) from the ladder :func:`deck_task_start` started on its
    handle, to the output prefix ``output`` (default the deck's, resolved
    against the deck's folder as the deck's own)."""
    return deck_task_write_report(deck, task, output)[1]


def deck_task_write_report(deck: DeckHandle, task: str = "", output: str = "",
                           fit_keys: str = "") -> tuple[str, list[str]]:
    """:func:`deck_task_write` and the summary line beamid-batch prints
    before the files: ``(summary, files)``. The handle writes the files of
    the task its run started (``task`` and ``fit_keys`` are not used: the
    handle holds the deck as read with its own)."""
    written, summary = _call(_deck_api.api_deck_handle_write, _deck(deck)._id(), output)
    return _text(summary), [line for line in _text(written).split("\n") if line]


def fit_chain(prob: Problem, params0: np.ndarray, free: np.ndarray, prior: np.ndarray,
              max_iter: int = 50, prior_cov: np.ndarray | None = None) -> dict:
    """:func:`fit` with the rows' treatment of the measurement chain (losses,
    burn-in, estimated sigmas: beamid_chain_fit); the dict gains per row
    ``weights``, ``sigma_used``, ``sigma_sd`` and ``flagged`` (gross errors)."""
    free = np.asarray(free, dtype=np.int32)
    cov = np.zeros(0) if prior_cov is None else np.ravel(prior_cov, order="F").astype(float)
    extra = {}

    def entry(*args):
        out = _api.api_fit_chain(*args)
        extra.update(weights=np.array(out[13]), sigma_used=np.array(out[14]),
                     sigma_sd=np.array(out[15]), flagged=np.array(out[16], dtype=bool))
        return out[:13] + out[17:]

    result = _fit_call(entry, free.size, False, prob.nbeams, np.asarray(params0, float), free,
                       prior, cov, *prob.rows(), int(max_iter))
    result.update(extra)
    return result


def mesh_check(prob: Problem, params: np.ndarray, pred: np.ndarray) -> dict:
    """The mesh check of a fit (beamid_dyn_diagnosis mesh_check): the data
    rows' predictions at ``params`` with every release at twice its elements
    per beam against the fit's ``pred``. Returns done (0 without releases),
    nepb, recommended, max_change (sigma units), row (0-based) and chi2 (of
    the refined model at params)."""
    out = _call(_api.api_mesh_check, prob.nbeams, np.asarray(params, float), prob.exp_kind,
                *prob.specs(), prob.row_exp, prob.row_t, prob.row_q, *prob.observations(),
                prob.row_value,
                prob.row_sigma, np.asarray(pred, float), float(prob.tol), *prob.histories())
    out = np.asarray(out, float)
    return {"done": int(out[0]), "nepb": int(out[1]), "recommended": int(out[2]),
            "max_change": float(out[3]), "row": int(out[4]) - 1, "chi2": float(out[5])}


def fit_replicates(prob: Problem, params0: np.ndarray, free: np.ndarray, prior: np.ndarray,
                   ys: np.ndarray, means: np.ndarray, max_iter: int = 50) -> dict:
    """Monte Carlo replicates of one fit in one call (beamid_replicates):
    the problem ``prob`` (its row values unused) fitted from ``params0`` on
    each column of ``ys`` (nrow x nrep, the rows' values) with a priori means
    ``means`` (nprior x nrep; ``prior`` a :func:`prior_table` giving the
    indices and sigmas). Each replicate is the fit :func:`fit` would make of
    its data. Returns arrays over the replicates (last axis): ``params``,
    ``sigmas``, ``flags``, the fit stats by name (``chi2``, ``chi2_prior``,
    ``dof``, ``iterations``, ``converged``, ...), ``stop`` (STOP_NAMES) and
    ``code`` (0: the fit ended; else its status code: the replicate is to be
    refitted through :func:`fit` for its message)."""
    ys = np.asfortranarray(ys, float)
    means = np.ravel(np.reshape(np.asarray(means, float), (prior.shape[1], ys.shape[1])),
                     order="F")
    (kind, kv_exp, kv_key, kv_value, row_exp, row_t, row_q, obs_kind, obs_beam, obs_s,
     _value, row_sigma, tol, hist_spec, hist_tab) = prob.rows()
    params, sigmas, flags, stats, stops, codes = _call(
        _api.api_fit_replicates, prob.nbeams, np.asarray(params0, float),
        np.asarray(free, np.int32), prior, kind, kv_exp, kv_key, kv_value, row_exp, row_t,
        row_q, obs_kind, obs_beam, obs_s, row_sigma, tol, hist_spec, hist_tab, int(max_iter),
        ys, means)
    st = Columns(np.asarray(stats), FIT_STATS)
    out = {name: np.array(st[name]) for name in FIT_STATS}
    out.update(params=np.array(params), sigmas=np.array(sigmas), flags=np.array(flags, int),
               stop=[STOP_NAMES.get(int(s), "stalled") for s in stops],
               code=np.array(codes, int))
    return out
