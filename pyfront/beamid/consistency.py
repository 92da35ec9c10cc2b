"""Monte Carlo consistency of a fit: do the reported sigmas hold?

The dissertation asks for it (Section 4.2.2, Chapter VI item 3: "repeat this
experiment with a distribution of estimates"). :func:`consistency` takes a
finished fit, takes its estimates as the truth, redraws the noise of the
fit's own data rows (their sigmas) around the model values at the estimates,
refits every replicate from the fit's starting point with the same free
parameters and a priori information, and summarizes: coverage of the truth
within 1, 2, 3 reported sigmas, bias, the ratio of reported sigma to the
empirical spread, and the chi-square of every replicate against its
chi-square(dof) distribution.

>>> import beamid
>>> truth = beamid.pace(axial_coupling=0.0)
>>> exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (3.0, 5.0, 6.5, 8.0)}
>>> data = beamid.simulate_measurements(truth, exps, ["y_tip"], sigma=1e-3)
>>> fit = beamid.fit(truth.replace(EI1=10.75, EI2=10.5), exps, data)
>>> mc = beamid.consistency(fit, replicates=20, seed=7, workers=1)
>>> mc.failed, mc.estimates["EI1"].shape
(0, (20,))

A replicate is the fit ``beamid.fit`` makes of its data (on
:class:`beamid.Measurements` built from the fit's own rows), so the same
function serves every experiment family that ``beamid.fit`` accepts. Without
releases a fit is one Gauss-Newton run (no record to grow, no homotopy, no
mesh check), and the replicates are fitted by the core in one call per
chunk of ``BATCH`` (``beamid_replicates``: each replicate's problem built
afresh and fitted exactly as ``beamid.fit`` would, the same numbers without
the per-fit checks and result assembly of the front); a replicate whose fit
did not end cleanly (an error, not converged, a flagged parameter) is refitted
through ``beamid.fit`` for its message. The summary statistics are computed
in Fortran (``beamid_design::mc_summary``).

Reproducibility: replicate ``k`` draws from its own generator
``numpy.random.default_rng(numpy.random.SeedSequence(seed, spawn_key=(k,)))``
(the k-th child of ``SeedSequence(seed).spawn``), first one standard normal
per data row, then one per a priori row. The replicates are therefore the
same whether they run in this process, on local processes or on a Dask
cluster, in any order and in any chunking.
"""
from __future__ import annotations

import math
import multiprocessing
import os
import re
import time
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from itertools import chain
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from . import _check
from .errors import BeamidError, InputError, OutputError, _write_all, _write_text
from . import _core, _core_estimation as _ce
from .estimation import (FLAG_TEXT, FitResult, _check_fit_args, _free_indices, _prior_arrays,
                         build_problem, fit as _fit, flag_is_problem)
from ._core_estimation import chi2_sf_many, mc_summary
from .loads import timed
from .fit_decks import read_fit_deck
from .plotting import agg_pyplot
from .progress import progress

#: Nominal coverage of +-k sigma for a normal estimate.
NOMINAL = {1: 0.6826894921370859, 2: 0.9544997361036416, 3: 0.9973002039367398}

#: Replicate states.
OK, FLAGGED, NOT_CONVERGED, ERROR = "ok", "flagged", "not converged", "error"

#: workers=None: replicates timed in this process before choosing a runner,
#: and the estimated remaining time (s) below which the run stays in this
#: process (starting the worker processes would cost more than it saves).
PROBE, SERIAL_BELOW = 4, 3.0

DASK_HINT = ("Dask is needed for client= / --scheduler: install it with "
             "`pip install beamid[dask]` (dask and distributed)")


@dataclass(frozen=True)
class _Spec:
    """Everything a worker needs to run replicates (picklable)."""

    start: Any
    experiments: dict
    data: Any
    free: tuple[str, ...]
    prior: dict
    options: dict
    truth_rows: np.ndarray     # model values of the data rows at the estimates
    truth: np.ndarray          # estimates of the free parameters
    seed: int


def replicate_generator(seed: int, k: int) -> np.random.Generator:
    """The generator of replicate ``k``: the k-th child of ``SeedSequence(seed)``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(k),)))


def _replicate_draws(spec: _Spec, k: int) -> tuple[np.ndarray, list[float]]:
    """Replicate ``k``'s row values and a priori means (in spec.prior's order)."""
    rng = replicate_generator(spec.seed, k)
    z = rng.standard_normal(len(spec.data) + len(spec.prior))
    values = spec.truth_rows + z[:len(spec.data)] * spec.data.sigma
    means = [float(spec.truth[spec.free.index(name)] + z[len(spec.data) + i] * sigma)
             for i, (name, (_, sigma)) in enumerate(spec.prior.items())]
    return values, means


def _replicate_inputs(spec: _Spec, k: int):
    values, means = _replicate_draws(spec, k)
    data = spec.data.with_values(values)
    prior = {name: (m, sigma) for m, (name, (_, sigma)) in zip(means, spec.prior.items())}
    return data, prior


def _run_one(spec: _Spec, k: int) -> dict:
    n = len(spec.free)
    rec = {"k": int(k), "status": ERROR, "message": "", "converged": False,
           "estimates": np.full(n, math.nan), "sigmas": np.full(n, math.nan),
           "chi2": math.nan, "chi2_prior": math.nan, "dof": -1, "iterations": -1,
           "flags": ("",) * n}
    try:
        data, prior = _replicate_inputs(spec, k)
        # a replicate is one fit (no mesh check, no more starts) unless asked
        res = _fit(spec.start, spec.experiments, data, free=spec.free, prior=prior,
                   **{"starts": 0, "mesh": False, **spec.options})
    except BeamidError as exc:
        rec["status"] = NOT_CONVERGED if not isinstance(exc, InputError) else ERROR
        rec["message"] = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        partial = getattr(exc, "partial", None)
        if isinstance(partial, dict) and "iterations" in partial:
            rec["iterations"] = int(partial["iterations"])
        return rec
    except Exception as exc:  # noqa: BLE001 - reported per replicate, never dropped
        rec["message"] = f"{type(exc).__name__}: {exc}"
        return rec
    rec.update(
        converged=bool(res.converged),
        estimates=np.array([res.estimates[nm] for nm in spec.free], float),
        sigmas=np.array([res.sigmas[nm] for nm in spec.free], float),
        chi2=float(res.chi2), chi2_prior=float(res.chi2_prior), dof=int(res.dof),
        iterations=int(res.iterations), flags=tuple(res.flags[nm] for nm in spec.free))
    if not res.converged:
        rec["status"] = NOT_CONVERGED
        rec["message"] = "; ".join(res.warnings) or "the fit stalled"
    elif any(flag_is_problem(f) for f in rec["flags"]):
        rec["status"] = FLAGGED
        rec["message"] = "; ".join(f"{nm}: {f}" for nm, f in zip(spec.free, rec["flags"])
                                   if flag_is_problem(f))
    else:
        rec["status"] = OK
    return rec


#: replicates per call of the core's batched fit (the progress bar moves between calls)
BATCH = 64


class _Batch:
    """The replicates of a fit without releases, fitted by the core a chunk
    at a time (``_core_estimation.fit_replicates``): the problem's arrays,
    free indices and a priori table built once, as ``beamid.fit`` builds
    them. Raises InputError (from those checks) when they refuse the fit's
    inputs: every replicate then goes through ``beamid.fit`` and records
    the error itself."""

    def __init__(self, spec: _Spec) -> None:
        opts = {"max_iter": 50, "tol": 0.0, **spec.options}
        _check_fit_args(spec.data, opts["tol"], opts["max_iter"])
        _check.choice("jacobian", opts.get("jacobian", "auto"), ("auto", "exact"))
        model = spec.start
        self.spec = spec
        self.prob = build_problem(model, spec.experiments, spec.data, opts["tol"])
        self.free, self.free_idx = _free_indices(model, spec.free)
        prior_map, self.ptable = _prior_arrays(model, self.free, spec.prior)
        if tuple(prior_map) != tuple(spec.prior):
            raise InputError("a priori names are not the free parameters' own")
        self.params0 = model.vector()
        self.nbeams = model.nbeams
        self.max_iter = int(opts["max_iter"])

    def _valid(self, params: np.ndarray) -> bool:
        """Whether the fitted vector makes a Model (the core's parameter
        check, as beamid.fit's result does; else the replicate is refitted
        through beamid.fit, which reports why)."""
        try:
            _core.check_params(self.nbeams, params)
        except BeamidError:
            return False
        return True

    def records(self, ks: Sequence[int]) -> list[dict]:
        spec, n = self.spec, len(self.free)
        draws = [_replicate_draws(spec, k) for k in ks]
        ys = np.array([v for v, _ in draws], float).T
        means = np.array([m for _, m in draws], float).reshape(len(ks), -1).T
        try:
            out = _ce.fit_replicates(self.prob, self.params0, self.free_idx, self.ptable, ys,
                                     means, self.max_iter)
        except BeamidError:
            # the batch refused (it should not, for arrays beamid.fit accepts): each
            # replicate through beamid.fit, which records what it says
            return [_run_one(spec, k) for k in ks]
        cols = self.free_idx - 1
        records = []
        for i, k in enumerate(ks):
            flags = tuple(FLAG_TEXT.get(int(f), "flagged") for f in out["flags"][:n, i])
            if (out["code"][i] != 0 or not out["converged"][i]
                    or any(flag_is_problem(f) for f in flags)
                    or not self._valid(out["params"][:, i])):
                # refitted through beamid.fit: the same fit, with its message
                records.append(_run_one(spec, k))
                continue
            records.append({
                "k": int(k), "status": OK, "message": "", "converged": True,
                "estimates": np.array(out["params"][cols, i], float),
                "sigmas": np.array(out["sigmas"][:n, i], float),
                "chi2": float(out["chi2"][i]), "chi2_prior": float(out["chi2_prior"][i]),
                "dof": int(out["dof"][i]), "iterations": int(out["iterations"][i]),
                "flags": flags})
        return records


def _batch(spec: _Spec) -> _Batch | None:
    """The batched runner for ``spec``, or None: records in time (a fit of a
    release may grow its record, run the homotopy or check its mesh) or inputs the
    fit's checks refuse go through ``beamid.fit`` one replicate at a time."""
    if any(timed(x) for x in spec.experiments.values()):
        return None
    try:
        return _Batch(spec)
    except Exception:  # noqa: BLE001 - beamid.fit then reports it, replicate by replicate
        return None


def _records(spec: _Spec, ks: Sequence[int], batch: _Batch | None):
    """The records of replicates ``ks`` in order, one at a time (for the
    progress bar), batched when ``batch`` is given."""
    ks = list(ks)
    if batch is None:
        for k in ks:
            yield _run_one(spec, k)
        return
    for a in range(0, len(ks), BATCH):
        yield from batch.records(ks[a:a + BATCH])


def _run_chunk(spec: _Spec, ks: Sequence[int]) -> list[dict]:
    """Worker entry point (module level, so spawn/forkserver and Dask can pickle it)."""
    return list(_records(spec, ks, _batch(spec)))


@dataclass(frozen=True)
class Consistency:
    """Result of :func:`consistency`.

    Arrays run over replicates ``0 .. replicates-1`` in order; a failed
    replicate keeps its row (NaN estimates, its status and message) and is
    counted in ``failed``; the statistics use the converged replicates
    (``used``), flagged ones included (they are counted in ``flagged``).
    """

    free: tuple[str, ...]
    truth: dict[str, float]              #: the fit's estimates
    reported: dict[str, float]           #: the fit's own sigmas
    seed: int
    estimates: dict[str, np.ndarray]
    sigmas: dict[str, np.ndarray]
    chi2: np.ndarray                     #: data chi-square per replicate
    chi2_prior: np.ndarray               #: a priori part per replicate
    chi2_p: np.ndarray                   #: P(chi2(dof) > chi2 + chi2_prior) per replicate
    dof: int                             #: expected distribution: chi-square(dof)
    iterations: np.ndarray
    status: tuple[str, ...]
    messages: tuple[str, ...]
    flags: tuple[tuple[str, ...], ...]
    coverage: dict[str, dict[int, float]]
    bias: dict[str, float]
    spread: dict[str, float]             #: empirical standard deviation of the estimates
    rms_sigma: dict[str, float]          #: root mean square of the reported sigmas
    spread_ratio: dict[str, float]       #: rms reported sigma / empirical spread
    z_mean: dict[str, float]             #: mean normalized error (est - truth) / sigma
    z_std: dict[str, float]
    runner: str = "serial"
    normalized: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def replicates(self) -> int:
        return len(self.status)

    @property
    def used(self) -> np.ndarray:
        """Mask of the replicates in the statistics (converged ones)."""
        return np.array([s in (OK, FLAGGED) for s in self.status])

    @property
    def failed(self) -> int:
        """Replicates whose refit did not converge or raised."""
        return sum(s in (NOT_CONVERGED, ERROR) for s in self.status)

    @property
    def flagged(self) -> int:
        """Converged replicates with a parameter flag (e.g. at a bound)."""
        return sum(s == FLAGGED for s in self.status)

    @property
    def failures(self) -> list[tuple[int, str, str]]:
        """(replicate, status, message) of every failed or flagged replicate."""
        return [(k, s, m) for k, (s, m) in enumerate(zip(self.status, self.messages))
                if s != OK]

    def tails(self, name: str, k: float = 2.0) -> tuple[float, float]:
        """Fractions of the used replicates with normalized error below -k and
        above +k (each 0.0228 for k = 2 when the errors are normal): a
        one-sided excess means the sigma is right in size but the errors are
        skewed (a parameter that enters the model nonlinearly)."""
        _check.choice("name", name, self.free)
        k = _check.real("k", k, above=0.0)
        z = self.normalized[name]
        z = z[np.isfinite(z)]
        if not z.size:
            return (math.nan, math.nan)
        return float(np.mean(z < -k)), float(np.mean(z > k))

    def coverage_error(self, name: str, k: int) -> float:
        """Monte Carlo standard error of ``coverage[name][k]`` at the nominal value."""
        _check.choice("name", name, self.free)
        if not _check.is_int(k) or k not in NOMINAL:
            _check.fail("k", k, "1, 2 or 3 (sigmas)")
        n = int(np.isfinite(self.normalized[name]).sum())
        return math.sqrt(NOMINAL[k] * (1.0 - NOMINAL[k]) / n) if n else math.nan

    def __str__(self) -> str:
        return self.table()

    def __repr__(self) -> str:
        return (f"<Consistency: {self.replicates} replicates (seed {self.seed}), "
                f"{int(self.used.sum())} converged, {self.flagged} flagged, {self.failed} "
                f"failed; free {', '.join(self.free)}; print() shows the table>")

    def table(self) -> str:
        """Coverage, bias and spread ratio per parameter, chi-square summary,
        failures."""
        n = self.replicates
        lines = [f"Monte Carlo consistency: {n} replicates (seed {self.seed}, {self.runner}); "
                 f"{int(self.used.sum())} converged, {self.flagged} of them flagged, "
                 f"{self.failed} failed"]
        head = (f"{'parameter':<12}{'truth':>11}{'fit sigma':>11}{'bias':>11}{'spread':>11}"
                f"{'rms sigma':>11}{'sigma/sprd':>11}{'z mean':>8}{'z std':>7}"
                f"{'<1s':>7}{'<2s':>7}{'<3s':>7}")
        lines += [head, "-" * len(head)]
        for nm in self.free:
            c = self.coverage[nm]
            lines.append(f"{nm:<12}{self.truth[nm]:>11.5g}{self.reported[nm]:>11.3g}"
                         f"{self.bias[nm]:>11.3g}{self.spread[nm]:>11.3g}"
                         f"{self.rms_sigma[nm]:>11.3g}{self.spread_ratio[nm]:>11.3f}"
                         f"{self.z_mean[nm]:>8.3f}{self.z_std[nm]:>7.3f}"
                         f"{c[1]:>7.3f}{c[2]:>7.3f}{c[3]:>7.3f}")
        lines.append(f"{'nominal':<89}{NOMINAL[1]:>7.3f}{NOMINAL[2]:>7.3f}{NOMINAL[3]:>7.3f}")
        if self.used.any():
            lines.append("beyond 2 sigma below / above (nominal 0.023 each): " + ", ".join(
                f"{nm} {self.tails(nm)[0]:.3f} / {self.tails(nm)[1]:.3f}" for nm in self.free))
        used = self.used
        if used.any() and self.dof > 0:
            tot = (self.chi2 + self.chi2_prior)[used]
            p = self.chi2_p[used]
            lines.append(f"chi2 (data + a priori): mean {tot.mean():.3g}, std {tot.std(ddof=1) if tot.size > 1 else math.nan:.3g}"
                         f" against chi2({self.dof}): mean {self.dof}, std "
                         f"{math.sqrt(2 * self.dof):.3g}; p < 0.05 in {np.mean(p < 0.05):.3f} "
                         f"of the replicates (expected 0.05)")
        elif self.dof <= 0:
            lines.append(f"chi2: dof = {self.dof}, no chi-square test (the data determine "
                         "the parameters exactly)")
        fails = self.failures
        if fails:
            groups: dict[str, list[tuple[int, str]]] = {}
            for k, s, m in fails:
                groups.setdefault(s, []).append((k, m))
            lines.append("not in the statistics (failed) or flagged:")
            for s, items in groups.items():
                k, m = items[0]
                lines.append(f"  {len(items)} x {s} (first: replicate {k}: {m})")
        return "\n".join(lines)

    def to_csv(self, path: str | os.PathLike) -> Path:
        """Every replicate: status, chi-square, p-value, iterations, and per
        parameter estimate, sigma, normalized error and flag (written to a
        temporary file and renamed, so no half-written file is left)."""
        path = _check.path("path", path)
        cols = ["replicate", "status", "iterations", "chi2", "chi2_prior", "dof", "chi2_p"]
        for nm in self.free:
            cols += [f"{nm}", f"sigma_{nm}", f"z_{nm}", f"flag_{nm}"]
        cols.append("message")
        lines = [f"# beamid.consistency: truth = the fit's estimates "
                 + ", ".join(f"{nm} = {self.truth[nm]:.17g}" for nm in self.free)
                 + f"; seed {self.seed}", ",".join(cols)]
        for k in range(self.replicates):
            row = [str(k), self.status[k], str(int(self.iterations[k])), f"{self.chi2[k]:.17g}",
                   f"{self.chi2_prior[k]:.17g}", str(self.dof), f"{self.chi2_p[k]:.17g}"]
            for j, nm in enumerate(self.free):
                row += [f"{self.estimates[nm][k]:.17g}", f"{self.sigmas[nm][k]:.17g}",
                        f"{self.normalized[nm][k]:.17g}", self.flags[k][j] or ""]
            row.append('"' + self.messages[k].replace('"', "'") + '"')
            lines.append(",".join(row))
        _write_text(path, "\n".join(lines) + "\n")
        return path

    def plot(self, path: str | os.PathLike | None = None, ax: Any = None):
        """Histograms of the normalized errors (est - truth) / sigma of every
        parameter against the N(0, 1) density, and of the chi-square against
        chi-square(dof). Writes a PNG when ``path`` is given; returns the figure."""
        path = _check.path("path", path, none=True)
        _check.axes("ax", ax)
        plt = agg_pyplot(path is not None, force=False)
        panels = len(self.free) + (1 if self.dof > 0 else 0)
        fig, axes = plt.subplots(1, panels, figsize=(3.6 * panels, 3.4), squeeze=False)
        grid = np.linspace(-4.0, 4.0, 201)
        gauss = np.exp(-0.5 * grid ** 2) / math.sqrt(2.0 * math.pi)
        for ax_, nm in zip(axes[0], self.free):
            z = self.normalized[nm]
            z = z[np.isfinite(z)]
            ax_.hist(np.clip(z, -4.5, 4.5), bins=np.linspace(-4.5, 4.5, 37), density=True,
                     alpha=0.6, label=f"{z.size} replicates")
            ax_.plot(grid, gauss, "k-", lw=1.0, label="N(0, 1)")
            c = self.coverage[nm]
            ax_.set_title(f"{nm}: sigma/spread {self.spread_ratio[nm]:.2f}, "
                          f"<1s {c[1]:.2f}", fontsize=9)
            ax_.set_xlabel(f"({nm} - truth) / sigma (-)")
            ax_.set_ylabel("probability density")
            ax_.legend(fontsize=7)
        if self.dof > 0:
            ax_ = axes[0][-1]
            tot = (self.chi2 + self.chi2_prior)[self.used]
            top = max(float(np.quantile(tot, 0.995)) if tot.size else 1.0, 3.0 * self.dof)
            ax_.hist(np.clip(tot, 0, top), bins=40, range=(0, top), density=True, alpha=0.6,
                     label="replicates")
            x = np.linspace(top / 400.0, top, 400)
            k = self.dof / 2.0
            pdf = np.exp((k - 1.0) * np.log(x) - x / 2.0 - k * math.log(2.0) - math.lgamma(k))
            ax_.plot(x, pdf, "k-", lw=1.0, label=f"chi2({self.dof})")
            ax_.set_title("chi-square of the replicates", fontsize=9)
            ax_.set_xlabel("chi2 (-)")
            ax_.set_ylabel("probability density")
            ax_.legend(fontsize=7)
        _save_figure(fig, path)
        return fig


def _save_figure(fig, path: str | os.PathLike | None) -> None:
    """Lay the figure out; at ``path`` (if given) save it as PNG all or none, then close it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    if path is not None:
        try:
            _write_all([(Path(path), lambda tmp: fig.savefig(tmp, dpi=110, format="png"))])
        finally:
            plt.close(fig)


def _output_prefix(deck_path, out, default: Path) -> Path:
    prefix = (Path(out) / Path(deck_path).stem) if out is not None else Path(default)
    try:
        prefix.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(exc.errno or 0, f"cannot write {prefix.parent}: "
                          f"{exc.strerror or exc}", str(prefix.parent)) from None
    return prefix


def _check_fit(fit: Any) -> None:
    """InputError unless ``fit`` is a FitResult (consistency and design)."""
    if not isinstance(fit, FitResult):
        raise InputError(f"fit must be a beamid.FitResult (beamid.fit), got "
                         f"{type(fit).__name__}")


def _deck_fit(deck: str | os.PathLike):
    """(deck, its fit) of an estimation deck: what ``beamid consistency`` and
    ``beamid design`` start from."""
    d = read_fit_deck(deck)
    return d, _fit(d.model, d.experiments, d.data, free=d.free, prior=d.prior,
                   max_iter=d.max_iter)


def _spec(fit: FitResult, seed: int, options: Mapping[str, Any] | None) -> _Spec:
    _check_fit(fit)
    seed = _check.count("seed", seed, min=0, max=2**128)
    options = _check.mapping("options", options, none=True)
    for key in options or {}:
        _check.choice("options: keyword", key, _FIT_OPTIONS)
    truth_rows = np.array([r.model for r in fit.residuals], float)
    if truth_rows.shape != (len(fit.data),) or not np.all(np.isfinite(truth_rows)):
        raise InputError("the fit has no finite model value for every data row; a "
                         "consistency check needs a fit that evaluated its model")
    truth = np.array([fit.estimates[n] for n in fit.free], float)
    return _Spec(start=fit.start, experiments=dict(fit.experiments), data=fit.data,
                 free=tuple(fit.free), prior=dict(fit.prior), options=dict(options or {}),
                 truth_rows=truth_rows, truth=truth, seed=seed)


def _chunks(n: int, parts: int) -> list[list[int]]:
    parts = max(1, min(n, parts))
    bounds = np.linspace(0, n, parts + 1).round().astype(int)
    return [list(range(a, b)) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


#: keywords of beamid.fit that ``options`` may pass to every refit
_FIT_OPTIONS = ("max_iter", "tol", "jacobian")


def _local_workers(workers: int | None) -> int:
    if workers is None:
        try:
            return max(1, len(os.sched_getaffinity(0)))
        except AttributeError:  # pragma: no cover - not Linux
            return max(1, os.cpu_count() or 1)
    return _check.count("workers", workers, min=1)


def _mp_context():
    """forkserver where available (spawn elsewhere). The fork server imports
    beamid once, so every worker forked from it starts with beamid loaded, and
    it stays up for later runs in the same session."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["beamid.consistency"])
        return ctx
    return multiprocessing.get_context("spawn")


def _dask_client(client: Any):
    """(client, owned): a Client as given, or one connected to an address string."""
    try:
        import distributed
    except ImportError:
        raise ImportError(DASK_HINT) from None
    if isinstance(client, str):
        if not re.fullmatch(_check._SCHEDULER, client):
            _check.fail("client", client, "a dask.distributed.Client or a scheduler address "
                        "such as 'tcp://host:8786'")
        try:
            return distributed.Client(client, timeout="30s"), True
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot connect to the Dask scheduler {client!r}: {exc}") from None
    if not isinstance(client, distributed.Client):
        raise InputError(f"client = {client!r}, expected a dask.distributed.Client or a "
                         "scheduler address such as 'tcp://host:8786'")
    return client, False


def _execute(spec: _Spec, replicates: int, client: Any, workers: int | None,
             show: bool | None) -> tuple[list[dict], str]:
    desc = "consistency"
    if client is not None:
        client, owned = _dask_client(client)
        try:
            from distributed import as_completed as dask_completed

            nworkers = max(1, len(client.scheduler_info().get("workers", {})))
            chunks = _chunks(replicates, 8 * nworkers)
            shared = client.scatter(spec, broadcast=True)
            futures = [client.submit(_run_chunk, shared, ks, pure=False) for ks in chunks]
            records = list(progress(chain.from_iterable(f.result() for f in dask_completed(futures)),
                                    total=replicates, desc=desc, enabled=show))
            return records, f"Dask, {nworkers} workers"
        finally:
            if owned:
                client.close()
    nworkers = min(_local_workers(workers), replicates)
    batch = _batch(spec) if nworkers <= 1 or workers is None else None
    probe: list[dict] = []
    if workers is None and nworkers > 1:
        # all cores only when the run pays for starting the processes (each
        # imports beamid, ~0.5 s): time a few replicates here first
        # (the median: the first call pays one-off start-up costs)
        times = []
        for k in range(min(PROBE, replicates)):
            t0 = time.perf_counter()
            probe.extend(_records(spec, [k], batch))
            times.append(time.perf_counter() - t0)
        if float(np.median(times)) * (replicates - len(probe)) < SERIAL_BELOW:
            nworkers = 1
    first = len(probe)

    def serial(runner: str) -> tuple[list[dict], str]:
        it = _records(spec, range(first, replicates), batch if batch is not None else
                      _batch(spec))
        return probe + list(progress(it, total=replicates - first, desc=desc,
                                     enabled=show)), runner

    if nworkers <= 1:
        return serial("serial")
    chunks = [[first + k for k in ks] for ks in _chunks(replicates - first, 8 * nworkers)]
    try:
        with ProcessPoolExecutor(max_workers=nworkers, mp_context=_mp_context()) as pool:
            futures = [pool.submit(_run_chunk, spec, ks) for ks in chunks]
            records = list(progress(chain.from_iterable(f.result() for f in as_completed(futures)),
                                    total=replicates - first, desc=desc, enabled=show))
    except BrokenProcessPool:
        # typically a script without the `if __name__ == "__main__":` guard
        # (the workers re-import the main module): say so and run here
        warnings.warn("beamid.consistency: the local worker processes failed to start; "
                      "running in this process instead. In a script, call it under "
                      "`if __name__ == \"__main__\":` (Python's multiprocessing rule) or pass "
                      "workers=1", RuntimeWarning, stacklevel=3)
        return serial("serial (local processes failed to start)")
    return probe + records, f"{nworkers} local processes"


def consistency(fit: FitResult, replicates: int = 200, seed: int = 7, client: Any = None,
                workers: int | None = None, *, options: Mapping[str, Any] | None = None,
                progress_bar: bool | None = None) -> Consistency:
    """Monte Carlo check of the sigmas a fit reports.

    Parameters
    ----------
    fit:
        A :class:`beamid.FitResult`. Its estimates are the truth of the
        replicates; its data rows (experiments, quantities, sigmas) the design.
    replicates:
        Number of noisy data sets (each refitted once).
    seed:
        Replicate ``k`` draws from ``SeedSequence(seed, spawn_key=(k,))``:
        the same seed gives the same replicates on any runner.
    client:
        ``None`` (local), a ``dask.distributed.Client`` or a scheduler
        address string (needs ``pip install beamid[dask]``).
    workers:
        Local processes; 1 runs in this process. Default: the cores this
        process may use, when the run is long enough to pay for starting
        them (a few replicates are timed here first; under about 3 s of
        estimated work the run stays in this process). Ignored with
        ``client``.
    options:
        Extra keyword arguments for every refit (``beamid.fit``), e.g.
        ``{"max_iter": 100}``.
    progress_bar:
        ``None``: a tqdm bar when stderr is a terminal.

    A priori information (Eq. 142-145) is a measurement too: its mean is
    redrawn around the truth with its sigma in every replicate. A replicate
    whose refit stalls or raises is kept, counted in ``failed`` and named in
    ``table()``; it does not enter the statistics.
    """
    spec = _spec(fit, seed, options)
    replicates = _check.count("replicates", replicates, min=2)
    # the per-replicate arrays of the result
    _check.memory(8 * (4 * len(spec.free) + 8) * replicates,
                  f"replicates = {replicates}: the results")
    workers = _check.count("workers", workers, min=1, none=True)
    if progress_bar is not None:
        _check.flag("progress_bar", progress_bar)
    records, runner = _execute(spec, replicates, client, workers, progress_bar)
    records.sort(key=lambda r: r["k"])
    if [r["k"] for r in records] != list(range(replicates)):
        raise BeamidError("internal error: replicates missing from the runner's results")
    return _summarize(fit, spec, records, runner)


def _summarize(fit: FitResult, spec: _Spec, records: list[dict], runner: str) -> Consistency:
    free = spec.free
    est = np.array([r["estimates"] for r in records], float).reshape(len(records), len(free))
    sig = np.array([r["sigmas"] for r in records], float).reshape(len(records), len(free))
    status = tuple(r["status"] for r in records)
    use = np.array([s in (OK, FLAGGED) for s in status])
    stats = mc_summary(est, sig, spec.truth, use)
    chi2 = np.array([r["chi2"] for r in records], float)
    chi2_prior = np.array([r["chi2_prior"] for r in records], float)
    dofs = np.array([r["dof"] for r in records], int)
    total = chi2 + np.nan_to_num(chi2_prior)
    pvals = np.full(len(records), math.nan)
    ok = use & np.isfinite(total) & (dofs > 0)
    if ok.any():
        pvals[ok] = chi2_sf_many(total[ok], dofs[ok])
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (est - spec.truth) / sig
    z[~use] = math.nan
    return Consistency(
        free=free, truth={n: float(v) for n, v in zip(free, spec.truth)},
        reported={n: float(fit.sigmas[n]) for n in free}, seed=spec.seed,
        estimates={n: est[:, j].copy() for j, n in enumerate(free)},
        sigmas={n: sig[:, j].copy() for j, n in enumerate(free)},
        chi2=chi2, chi2_prior=chi2_prior, chi2_p=pvals, dof=int(fit.dof),
        iterations=np.array([r["iterations"] for r in records], int), status=status,
        messages=tuple(r["message"] for r in records),
        flags=tuple(tuple(r["flags"]) for r in records),
        coverage={n: {1: float(stats[0, j]), 2: float(stats[1, j]), 3: float(stats[2, j])}
                  for j, n in enumerate(free)},
        # rows 3-8 of mc_summary, in this order
        **{key: {n: float(stats[i, j]) for j, n in enumerate(free)} for i, key in enumerate(
            ("bias", "spread", "rms_sigma", "spread_ratio", "z_mean", "z_std"), start=3)},
        runner=runner, normalized={n: z[:, j].copy() for j, n in enumerate(free)})


def run_consistency_deck(deck: str | os.PathLike, replicates: int = 200, seed: int = 7,
                         scheduler: str | None = None, out: str | os.PathLike | None = None,
                         workers: int | None = None, plots: bool = True
                         ) -> tuple[str, list[Path], Consistency]:
    """``beamid consistency DECK``: fit an estimation deck, run the Monte
    Carlo check and write ``<prefix>_consistency.csv`` (every replicate) and
    ``_consistency.png`` (normalized errors against N(0, 1)). The prefix is
    the deck's ``output`` or ``OUT/<deck name>``. Returns (table, files, result)."""
    d, base = _deck_fit(deck)
    mc = consistency(base, replicates=replicates, seed=seed, client=scheduler,
                     workers=workers, options={"max_iter": d.max_iter})
    prefix = _output_prefix(deck, out, d.output_prefix)
    files = [mc.to_csv(Path(f"{prefix}_consistency.csv"))]
    if plots:
        path = Path(f"{prefix}_consistency.png")
        mc.plot(path)
        files.append(path)
    return f"{base.summary()}\n\n{mc.table()}", files, mc
