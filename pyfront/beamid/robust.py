"""Does a dynamic fit end at the best fit? (issue 30)

Two checks that :func:`beamid.fit` makes on fits with
:class:`beamid.Release` experiments, without running the whole diagnosis:

* **the mesh check**: when a fit ends far above its degrees of freedom
  (chi-square p-value below :data:`FAR_P`) or stalls, the predictions at the
  estimates are computed again with every release at twice its elements per
  beam (one plain run, Fortran ``beamid_dyn_diagnosis::mesh_check``). When
  they move by more than :data:`MESH_LIKELY` sigma the discretization is the
  likely cause and the result names the elements per beam that would do
  (the ``mesh`` candidate's estimate, assuming the h^4 convergence of the
  cubic elements); :attr:`beamid.FitResult.mesh_check` holds the numbers.
* **several starts**: more fits from starts drawn around the given one (each
  free parameter times a uniform factor in ``[1 - spread, 1 + spread]``,
  start ``k`` from ``SeedSequence(seed, spawn_key=(k,))``), run on the
  runners of :func:`beamid.consistency` (this process, local processes or a
  Dask cluster; the same starts on any runner). The best end point is the
  result, the given start's unless another start went lower by more than
  :func:`same_chi2` (:attr:`beamid.FitResult.start_won` names its start, ``start`` is
  its starting model and ``log`` its path); every start's end is in
  :attr:`beamid.FitResult.starts`. A fit counts as converged only at a
  point that no other start lowered by more than :func:`same_chi2`; a start
  that ended higher is a local minimum, and the note says how much lower
  another start went.

``fit(..., starts=None)`` (the default) runs :data:`AUTO_STARTS` more starts
when a fit with releases ends far above its degrees of freedom or stalls and
the mesh check does not name the mesh; ``starts=0`` never, ``starts=k``
always ``k`` more.

A third aid is for long records: ``fit(..., grow=None)`` fits a release
record longer than :data:`GROW_ABOVE` seconds window by window (the end
halved until the next halving falls below :data:`GROW_FIRST`, then doubled up
to the whole record, each window from the last one's estimates), so the
phase of the response is caught before the whole record is fitted
(:func:`grown_fit`; ``result.path`` lists the windows). The windows before
the last are fitted at the rough tolerance :data:`GROW_RTOL`; the last, the
whole record, at the releases' own.

A fourth is the friction homotopy: ``fit(..., homotopy=None)`` fits a
model with joint friction on releases with the sign law (the
dissertation's, Eq. 101-102) first on the smooth law mu N v / sqrt(v^2 +
vs^2) at the regularization velocities :data:`HOMOTOPY_VELOCITIES`
(largest first), each from the last one's estimates, and then on the sign
law, so the pattern of stick and slip settles before Gauss-Newton sees the
kinks of its switches (:func:`homotopy_fit`; ``result.path`` lists the
stages). ``None`` (default) runs it when the plain fit ends far above its
degrees of freedom or stalls and the mesh is not the likely cause (the
path's end is kept when it goes lower than the plain fit by more than
:func:`same_chi2`, ``result.start_won`` then says "friction homotopy");
True always (the path is the fit); False never.

This module builds on :func:`beamid.estimation.fit` (each start, window and
mesh refit is a plain fit) and registers :func:`checked_fit` with it when
imported (``import beamid`` does), so estimation does not import it.
"""
from __future__ import annotations

import math
import time
import warnings
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from . import _core_estimation as _ce
from . import estimation as _est
from .dynamics import DEFAULT_RTOL
from .consistency import SERIAL_BELOW, _chunks, _dask_client, _local_workers, _mp_context
from .dyn_diagnosis import refine_mesh
from .errors import BeamidError
from .estimation import START_SEED, START_SPREAD, build_problem, fit as _fit
from .loads import Release, timed
from .measurements import Measurements

#: A fit ends "far above its degrees of freedom" when the chi-square's
#: p-value (data and a priori rows) is below this.
FAR_P = 1.0e-3
#: The mesh is named the likely cause when doubling it moves a prediction
#: at the estimates by more than this many sigma.
MESH_LIKELY = 1.0
#: More starts run by ``starts=None`` when a fit ends far above its degrees
#: of freedom or stalls (and the mesh is not the likely cause).
AUTO_STARTS = 4
#: Default spread of the starts: each free parameter times U(1 - s, 1 + s).
SPREAD = START_SPREAD
#: Default seed of the starts.
SEED = START_SEED

#: the states of a start
BEST, SAME, LOCAL, FAILED = "best", "same minimum", "local minimum", "failed"


def same_chi2(chi2: float) -> float:
    """Two end points whose chi-squares differ by less than this are the
    same minimum: 0.05 (five times the fit's noise floor, 0.01, within
    which a release's chi-square is not smooth) or 1e-5 of the chi-square
    on long records, whichever is larger."""
    return max(0.05, 1.0e-5 * abs(chi2))


@dataclass(frozen=True)
class MeshCheck:
    """The mesh check of a fit with releases (see the module docstring)."""

    elements_per_beam: int      #: the fit's (largest release's)
    recommended: int            #: elements per beam for 0.3 sigma
    max_change: float           #: largest |prediction change| / sigma at 2x
    at: tuple[str, float, str]  #: (experiment, t, quantity) of that change
    refit_chi2: float           #: chi-square of the refit at 2x (nan: no refit)
    drop: float                 #: chi-square drop of that refit (nan: no refit)
    likely_cause: bool          #: see mesh_check
    message: str


class StartEnd(NamedTuple):
    """Where one start of a fit ended."""

    index: int            #: 0 the given start, k >= 1 random start k
    label: str            #: "given start" or "random start k"
    start: dict           #: the free parameters' starting values
    estimates: dict       #: their end values (empty when the fit failed)
    chi2: float           #: data and a priori rows (nan when failed)
    stop: str             #: the fit's stop ("converged", "stalled", ...) or "error"
    iterations: int
    state: str            #: "best", "same minimum", "local minimum" or "failed"
    above_best: float     #: chi-square above the best start's (nan when failed)
    message: str = ""


def needs_check(fit: Any) -> bool:
    """A fit with releases (records in time: the core family is timed) that
    ended far above its degrees of freedom (p-value below FAR_P) or stalled."""
    if not any(timed(x) for x in fit.experiments.values()):
        return False
    if fit.stop == "stalled":
        return True
    total = fit.chi2 + fit.chi2_prior
    return fit.dof > 0 and _ce.chi2_sf(total, fit.dof) < FAR_P


def mesh_check(fit: Any, *, prior: Any = None, options: dict | None = None) -> MeshCheck | None:
    """The mesh check of ``fit`` (None without releases).

    The predictions at the estimates with every release at twice its
    elements per beam (Fortran ``mesh_check``): when none moves by more than
    MESH_LIKELY sigma the mesh is not the cause. Otherwise the fit is
    repeated at twice the elements per beam from its estimates (one fit, not
    the diagnosis); the mesh is the likely cause when that lowers the
    chi-square significantly (p < FAR_P at one degree of freedom) and by at
    least half its excess over the degrees of freedom. ``prior`` and
    ``options``: as given to the fit (``prior`` default: the fit's)."""
    prob = build_problem(fit.model, fit.experiments, fit.data)
    pred = np.array([r.model for r in fit.residuals], float)
    out = _ce.mesh_check(prob, fit.model.vector(), pred)
    if out["done"] == 0:
        return None
    row = out["row"]
    at = (fit.data.experiment[row], float(fit.data.t[row]), fit.data.quantity[row])
    nepb, rec, change = out["nepb"], out["recommended"], out["max_change"]
    where = f"{at[2]} at t = {at[1]:g} s of {at[0]!r}"
    if change <= MESH_LIKELY:
        return MeshCheck(nepb, rec, change, at, math.nan, math.nan, False,
                         f"the mesh is not the cause: at {2 * nepb} elements per beam no "
                         f"prediction moves by more than {change:.3g} sigma ({where})")
    total = fit.chi2 + fit.chi2_prior
    try:
        refit = _fit(fit.model, refine_mesh(fit.experiments), fit.data, free=fit.free,
                     prior=prior if prior is not None else (fit.prior or None), starts=0,
                     mesh=False, homotopy=False, **dict(options or {}))
        chi2 = refit.chi2 + refit.chi2_prior
    except BeamidError:
        chi2 = out["chi2"]      # the refined model at the fit's estimates
    drop = total - chi2
    likely = drop > 0.0 and _ce.chi2_sf(drop, 1) < FAR_P and drop >= 0.5 * (total - fit.dof)
    if likely:
        msg = (f"the mesh is the likely cause: at {2 * nepb} elements per beam the refit "
               f"reaches chi2 {chi2:.4g} ({drop:.4g} lower) and the predictions at these "
               f"estimates move by up to {change:.3g} sigma ({where}); refit with "
               f"elements_per_beam={rec} (discretization error below 0.3 sigma)")
    else:
        gain = (f"lowers the chi-square by {drop:.3g} only" if drop > 0.0 else
                f"does not lower the chi-square (chi2 {chi2:.4g})")
        msg = (f"the mesh is not the likely cause: at {2 * nepb} elements per beam the "
               f"predictions move by up to {change:.3g} sigma ({where}) but the refit there "
               f"{gain}")
    return MeshCheck(nepb, rec, change, at, float(chi2), float(drop), likely, msg)


# ------------------------------------------------------------------ several starts

@dataclass(frozen=True)
class _StartSpec:
    """Everything a worker needs to run starts (picklable)."""

    model: Any
    experiments: dict
    data: Any
    free: tuple[str, ...]      # the parameters the starts perturb (the fit's free)
    fit_free: tuple[str, ...]  # free as given to fit (a carried prior adds its own)
    prior: Any
    options: dict
    spread: float
    seed: int
    scale: dict          # per free parameter: the size a zero start is perturbed by


def start_generator(seed: int, k: int) -> np.random.Generator:
    """The generator of random start ``k``: ``SeedSequence(seed, spawn_key=(k,))``."""
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(k),)))


def random_start(spec: _StartSpec, k: int):
    """Random start ``k`` (k >= 1): each free parameter of the given start
    times U(1 - spread, 1 + spread); one that starts at 0 gets
    U(0, spread) times its scale (the first fit's |estimate| or sigma)."""
    rng = start_generator(spec.seed, k)
    u = rng.uniform(-1.0, 1.0, len(spec.free))
    values = {}
    for name, uk in zip(spec.free, u):
        x0 = float(spec.model[name])
        if x0 != 0.0:
            x = x0 * (1.0 + spec.spread * uk)
        else:
            x = spec.scale[name] * spec.spread * abs(uk)
        if name == "axial_coupling":
            x = min(x, 1.0)
        values[name] = x
    return spec.model.replace(**values)


def _run_start(spec: _StartSpec, k: int) -> tuple[int, Any, str]:
    """(k, FitResult or None, error message) of random start k."""
    start = random_start(spec, k)
    try:
        res = _fit(start, spec.experiments, spec.data, free=spec.fit_free, prior=spec.prior,
                   starts=0, mesh=False, homotopy=False, **spec.options)
    except BeamidError as exc:
        return k, None, (str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    return k, replace(res, nominal=spec.model), ""


def _run_starts(spec: _StartSpec, ks: Sequence[int]) -> list[tuple[int, Any, str]]:
    return [_run_start(spec, k) for k in ks]


def _execute(spec: _StartSpec, nstarts: int, client: Any, workers: int | None,
             first_seconds: float) -> tuple[list, str]:
    """Run random starts 1..nstarts on the consistency runners."""
    ks = list(range(1, nstarts + 1))
    if client is not None:
        client, owned = _dask_client(client)
        try:
            nworkers = max(1, len(client.scheduler_info().get("workers", {})))
            shared = client.scatter(spec, broadcast=True)
            futures = [client.submit(_run_starts, shared, [ks[i] for i in c], pure=False)
                       for c in _chunks(nstarts, nworkers)]
            return [r for f in futures for r in f.result()], f"Dask, {nworkers} workers"
        finally:
            if owned:
                client.close()
    nworkers = min(_local_workers(workers), nstarts)
    if workers is None and first_seconds * nstarts < SERIAL_BELOW:
        nworkers = 1
    if nworkers <= 1:
        return _run_starts(spec, ks), "serial"
    try:
        with ProcessPoolExecutor(max_workers=nworkers, mp_context=_mp_context()) as pool:
            futures = [pool.submit(_run_starts, spec, [ks[i] for i in c])
                       for c in _chunks(nstarts, nworkers)]
            out = [r for f in as_completed(futures) for r in f.result()]
    except BrokenProcessPool:
        # typically a script without the `if __name__ == "__main__":` guard
        warnings.warn("beamid.fit: the local worker processes for the starts failed to start; "
                      "running them in this process instead. In a script, call it under "
                      "`if __name__ == \"__main__\":` or pass workers=1", RuntimeWarning,
                      stacklevel=4)
        return _run_starts(spec, ks), "serial (local processes failed to start)"
    return out, f"{nworkers} local processes"


def several_starts(first: Any, nstarts: int, *, spread: float = SPREAD, seed: int = SEED,
                   workers: int | None = 1, client: Any = None, options: dict | None = None,
                   first_seconds: float = 0.0, why: str = "", free: Any = None,
                   prior: Any = None) -> Any:
    """``first`` (the fit from the given start) against ``nstarts`` more
    starts: the best end point, with every start's end in ``starts``.
    ``free`` and ``prior``: as given to :func:`beamid.fit` (default: the
    first fit's)."""
    fit_free = first.free if free is None else ((free,) if isinstance(free, str) else
                                                tuple(free))
    free = first.free
    scale = {}
    for n in free:
        e, s = abs(first.estimates[n]), first.sigmas[n]
        scale[n] = e if e > 0.0 else (s if math.isfinite(s) and s > 0.0 else 1.0)
    given = first.nominal if first.nominal is not None else first.start
    spec = _StartSpec(given, dict(first.experiments), first.data, free, fit_free,
                      first.prior or None if prior is None else prior, dict(options or {}), float(spread), int(seed),
                      scale)
    results, runner = _execute(spec, int(nstarts), client, workers, first_seconds)
    results.sort(key=lambda r: r[0])
    if [r[0] for r in results] != list(range(1, int(nstarts) + 1)):
        raise BeamidError("internal error: starts missing from the runner's results")
    fits = [(0, first, "")] + results
    done = [(k, f) for k, f, _ in fits if f is not None]
    kbest, best = min(done, key=lambda kf: kf[1].chi2 + kf[1].chi2_prior)
    cbest = best.chi2 + best.chi2_prior
    tol = same_chi2(cbest)
    if first.chi2 + first.chi2_prior - cbest < tol:
        # the given start's end is the same minimum: it stays the result (a
        # start that went lower within the noise floor is no better)
        kbest, best = 0, first
    ends = []
    for k, f, err in fits:
        label = "given start" if k == 0 else f"random start {k}"
        if f is None:
            ends.append(StartEnd(k, label, {n: float(random_start(spec, k)[n]) for n in free},
                                 {}, math.nan, "error", -1, FAILED, math.nan, err))
            continue
        c = f.chi2 + f.chi2_prior
        state = BEST if k == kbest else (SAME if c - cbest < tol else LOCAL)
        ends.append(StartEnd(k, label, {n: float(f.start[n]) for n in free},
                             dict(f.estimates), float(c), f.stop, f.iterations, state,
                             float(c - cbest), f.note))
    local = [e for e in ends if e.state == LOCAL]
    failed = [e for e in ends if e.state == FAILED]
    same = [e for e in ends if e.state == SAME]
    text = (f"{nstarts + 1} starts ({why + '; ' if why else ''}spread {spread:g}, seed {seed}, "
            f"{runner}): {ends[kbest].label} won (chi2 {cbest:.4g})")
    if kbest != 0:
        c0 = first.chi2 + first.chi2_prior
        if c0 - cbest >= tol:
            text += (f"; the given start's fit ended at chi2 {c0:.4g}, {c0 - cbest:.3g} higher: "
                     "it was a local minimum")
    text += f"; {len(same)} more reached the same minimum (within {tol:.2g})"
    lo, hi = (min(e.above_best for e in local), max(e.above_best for e in local)) if local \
        else (0.0, 0.0)
    if len(local) == 1:
        text += f"; 1 ended in a local minimum, {lo:.3g} higher"
    elif local:
        text += f"; {len(local)} ended in local minima, {lo:.3g} to {hi:.3g} higher"

    if failed:
        text += f"; {len(failed)} failed"
    note = best.note + ("; " if best.note else "") + text
    label = ends[kbest].label
    return replace(best, starts=tuple(ends), start_won=label, note=note,
                   nominal=given, mesh_check=first.mesh_check,
                   warnings=best.warnings + ((text,) if kbest != 0 and
                                             first.chi2 + first.chi2_prior - cbest >= tol
                                             else ()))


# ------------------------------------------------------------------ growing the record

#: The first window of a grown record (s): the record's end halved until the
#: next halving would fall below this (about half a period of the PACE arm,
#: where Table 16's half cycle converges in a few iterations).
GROW_FIRST = 1.0
#: ``grow=None`` grows records longer than this (s).
GROW_ABOVE = 4.0


#: The integration tolerance of a grown record's windows before the last
#: (the Fortran engine's ROUGH_RTOL, beamid_dynamic_experiments: the rough
#: model's minimum is within a few hundredths of a sigma of the accurate
#: one, at about a tenth of a run's cost). A window only has to catch the
#: phase for the next; the last window, the whole record, is fitted at the
#: releases' own tolerance and gives the estimates and covariance.
GROW_RTOL = 1.0e-6


def window_experiments(experiments: Any) -> dict:
    """The experiments of a window before the last: every implicit
    release integrated at GROW_RTOL unless its own tolerance is looser."""
    def loose(x: Any) -> Any:
        if not isinstance(x, Release) or x.integrator != "implicit":
            return x
        own = DEFAULT_RTOL if x.rtol is None else float(x.rtol)
        return replace(x, rtol=GROW_RTOL) if own < GROW_RTOL else x
    return {n: loose(x) for n, x in dict(experiments).items()}


def release_end(experiments: Any, data: Any) -> float:
    """The last measured time of a release (0 without releases)."""
    rel = {n for n, x in dict(experiments).items() if timed(x)}
    times = [float(t) for e, t in zip(data.experiment, data.t) if e in rel]
    return max(times, default=0.0)


def grow_windows(end: float, first: float = GROW_FIRST) -> list[float]:
    """The windows of a grown record ending at ``end``: end / 2^m, ..., end / 2,
    end, the first the shortest at or above ``first`` (just [end] when end
    is shorter than twice ``first``)."""
    windows = [float(end)]
    while windows[0] / 2.0 >= first:
        windows.insert(0, windows[0] / 2.0)
    return windows


def record_up_to(experiments: Any, data: Any, end: float) -> Any:
    """The data rows of the releases measured at t <= end, and every static row."""
    rel = {n for n, x in dict(experiments).items() if timed(x)}
    rows = [r for r in data.rows() if r[0] not in rel or r[1] <= end * (1.0 + 1e-12)]
    return Measurements.from_rows(rows, source=f"{data.source} (t <= {end:g} s)")


def should_grow(grow: bool | None, experiments: Any, data: Any) -> bool:
    """grow=True: always (when a release is measured past 2 GROW_FIRST);
    None: when its record is longer than GROW_ABOVE; False: never."""
    if grow is False:
        return False
    end = release_end(experiments, data)
    return end >= 2.0 * GROW_FIRST and (grow is True or end > GROW_ABOVE)


def grown_fit(model: Any, experiments: Any, data: Any, free: Any, prior: Any,
              options: dict, first: float = GROW_FIRST) -> tuple[Any, tuple[str, ...]]:
    """Fit the record's early part, then extend it (each window twice the
    last, from the last window's estimates) up to the whole record.
    Returns the fit of the whole record (its start: the last window's
    estimates) and the path, one line per window."""
    windows = grow_windows(release_end(experiments, data), first)
    path = []
    current = model
    res = None
    last = len(windows) - 1
    early = window_experiments(experiments)
    for k, end in enumerate(windows):
        part = data if k == last else record_up_to(experiments, data, end)
        res = _fit(current, experiments if k == last else early, part, free=free, prior=prior,
                   starts=0, mesh=False, grow=False, homotopy=False, **options)
        path.append(f"t <= {end:g} s: {len(part)} rows, {res.iterations} iterations, "
                    f"{res.stop}, chi2 {res.chi2:.6g} for {res.dof} dof")
        current = res.model
    return res, tuple(path)


# ------------------------------------------------------------------ friction homotopy

#: The smooth law's regularization velocities (m/s) of the friction
#: homotopy, largest first; the last stage is the sign law. 1e-2 m/s moves
#: the PACE tip by ~1.5e-3 m over a period (docs/dynamics.md): coarse
#: enough that the switch pattern is smooth in the parameters; 1e-3 m/s is
#: within a few sigma of the sign law on the tests' records.
HOMOTOPY_VELOCITIES = (1.0e-2, 1.0e-3)

#: the label of the homotopy's end point among the starts
HOMOTOPY = "friction homotopy"


def _sign_law(x: Any) -> bool:
    return isinstance(x, Release) and (x.friction is None or x.friction == "sign")


def homotopy_applies(model: Any, experiments: Any, free: Any) -> bool:
    """A release on the sign law, and joint friction in the model (a
    friction coefficient that is not zero or is free)."""
    if not any(_sign_law(x) for x in dict(experiments).values()):
        return False
    names = (free,) if isinstance(free, str) else tuple(free)
    return any(n.startswith("mu_") and (model[n] != 0.0 or n in names)
               for n in model.names())


def smooth_friction(experiments: Any, velocity: float) -> dict:
    """The experiments with every release on the sign law moved to the
    smooth law at regularization velocity ``velocity`` (m/s)."""
    return {n: replace(x, friction="smooth", friction_velocity=float(velocity))
            if _sign_law(x) else x for n, x in dict(experiments).items()}


def homotopy_fit(model: Any, experiments: Any, data: Any, free: Any, prior: Any,
                 options: dict, grow: bool | None = False,
                 velocities: Sequence[float] = HOMOTOPY_VELOCITIES
                 ) -> tuple[Any, tuple[str, ...]]:
    """Fit on the smooth friction law at each of ``velocities`` (largest
    first), each stage from the last one's estimates, then on the
    experiments' own (sign) law. A stage that cannot be fitted ends the
    smooth part (the sign-law fit starts from the last stage that could).
    Returns the sign-law fit (its start: the last smooth stage's
    estimates) and the path, one line per stage."""
    path = []
    current = model
    for vs in velocities:
        try:
            res = _fit(current, smooth_friction(experiments, vs), data, free=free, prior=prior,
                       starts=0, mesh=False, grow=grow, homotopy=False, **options)
        except BeamidError as exc:
            path.append(f"smooth law, vs = {vs:g} m/s: not fitted "
                        f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})")
            break
        path.append(f"smooth law, vs = {vs:g} m/s: {res.iterations} iterations, {res.stop}, "
                    f"chi2 {res.chi2:.6g} for {res.dof} dof")
        current = res.model
    res = _fit(current, experiments, data, free=free, prior=prior, starts=0, mesh=False,
               grow=grow, homotopy=False, **options)
    path.append(f"sign law: {res.iterations} iterations, {res.stop}, "
                f"chi2 {res.chi2:.6g} for {res.dof} dof")
    return res, tuple(path)


def _with_homotopy(result: Any, model: Any, experiments: Any, data: Any, free: Any,
                   prior: Any, options: dict, grow: bool | None) -> Any:
    """``result`` (a plain fit that ended far or stalled) against the
    friction homotopy from the same start: the homotopy's end when it went
    lower by more than same_chi2 (warned), else ``result`` with a note."""
    try:
        alt, path = homotopy_fit(model, experiments, data, free, prior, options, grow=grow)
    except BeamidError as exc:
        text = (f"the friction homotopy from the same start failed "
                f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})")
        return replace(result, note=result.note + ("; " if result.note else "") + text)
    c0, c1 = result.chi2 + result.chi2_prior, alt.chi2 + alt.chi2_prior
    if c0 - c1 >= same_chi2(c1):
        text = (f"the friction homotopy went lower than the plain fit (chi2 {c1:.6g} against "
                f"{c0:.6g}): the plain fit ended in a local minimum")
        return replace(alt, nominal=model, path=path, start_won=HOMOTOPY,
                       note=alt.note + ("; " if alt.note else "") + text,
                       warnings=alt.warnings + (text,))
    text = (f"the friction homotopy from the same start ended at chi2 {c1:.6g} "
            f"(the plain fit's {c0:.6g})")
    return replace(result, note=result.note + ("; " if result.note else "") + text)


# ------------------------------------------------------------------ fit's own end

def checked_fit(plain: Callable[[], Any], model: Any, experiments: Any, data: Any, free: Any,
                prior: Any, options: dict, *, starts: int | None, spread: float, seed: int,
                workers: int | None, client: Any, mesh: bool, grow: bool | None,
                homotopy: bool | None = False) -> Any:
    """What :func:`beamid.fit` does with its checked arguments: the plain fit
    (``plain()``), the grown record or the friction homotopy, then the mesh
    check, the homotopy after a far fit and the several starts (the module
    docstring)."""
    t0 = time.perf_counter()
    applies = homotopy is not False and homotopy_applies(model, experiments, free)
    if homotopy and applies:
        result, path = homotopy_fit(model, experiments, data, free, prior, options, grow=grow)
        result = replace(result, nominal=model, path=path, start_won=HOMOTOPY)
    elif should_grow(grow, experiments, data):
        result, path = grown_fit(model, experiments, data, free, prior, options)
        result = replace(result, nominal=model, path=path)
    else:
        result = plain()
    seconds = time.perf_counter() - t0
    far = needs_check(result)
    if mesh and far:
        check = mesh_check(result, prior=prior, options=options)
        if check is not None:
            result = replace(result, mesh_check=check,
                             warnings=result.warnings + (check.message,) if check.likely_cause
                             else result.warnings)
    likely = result.mesh_check is not None and result.mesh_check.likely_cause
    if far and homotopy is None and applies and not likely:
        check = result.mesh_check
        result = replace(_with_homotopy(result, model, experiments, data, free, prior,
                                        options, grow), mesh_check=check)
        far = needs_check(result)
    nstarts = starts
    if starts is None:
        nstarts = AUTO_STARTS if far and not likely else 0
    if nstarts:
        why = ("ended far above its degrees of freedom" if result.stop != "stalled" else
               "stalled") if starts is None else "asked for"
        result = several_starts(
            result, int(nstarts), spread=float(spread), seed=int(seed), workers=workers,
            client=client, first_seconds=seconds, why=why, options=options, free=free,
            prior=prior)
    return result


_est._ROBUST.update(fit=checked_fit)
