"""Parameter estimation from static measurements (Section 3.2, Eq. 36-56, 142-145).

>>> import beamid
>>> truth = beamid.pace(axial_coupling=0.0)
>>> exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (3.0, 5.0, 6.5, 8.0)}
>>> data = beamid.simulate_measurements(truth, exps, ["y_tip"], sigma=1e-3)
>>> fit = beamid.fit(truth.replace(EI1=10.75, EI2=10.5), exps, data, free=("EI1", "EI2"))
>>> round(fit.estimates["EI1"], 3), round(fit.estimates["EI2"], 3)
(11.413, 11.275)

The numerics (Gauss-Newton with a Levenberg-Marquardt safeguard, bounds, a
priori pseudo-measurements, SVD covariance) run in Fortran
(``beamid_estimation``); this module builds the problem and names the results.
"""
from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Mapping, NamedTuple, Sequence

import numpy as np

from . import _check, _core_estimation as _ce
from . import observations
from . import load_histories as _lh
from .dynamics import _warn_chirp
from .errors import BeamidError, InputError
from .loads import LOAD_RELEASE, Modal, RadialWire, Release, TipLoad, family, timed
from . import modal as _modal
from .measurements import Measurements, QUANTITIES
from .model import Model
from .chain import ChainSpec, RowTreatment, check_sigma_given, parse_nuisance, parse_rows
from .static import ALIASES as _static_aliases
from .static import OUTPUTS as _static_outputs
from .static import measurement_value, solve_static

#: Meaning of the per-parameter flags returned by the Fortran core (its table).
FLAG_TEXT = dict(_ce.FLAG_NAMES)
#: the flag of a determined estimate whose sigma exceeds 20 % of its value
#: (FLAG_WEAK, its threshold WEAK_RELATIVE_SIGMA in beamid_estimation.f90, the
#: one place it is set); not a problem of the fit
WEAK = "weak"


def flag_is_problem(flag: str) -> bool:
    """A flag that says the fit cannot be trusted for that parameter (not
    "ok", not "weak": a weak estimate is determined, only poorly)."""
    return flag not in ("ok", WEAK)

Experiments = Mapping[str, "TipLoad | RadialWire | Release"]

#: Defaults of fit's several starts (beamid.robust): the spread (each free
#: parameter times U(1 - s, 1 + s)) and the seed; at most MAX_STARTS more.
START_SPREAD = 0.4
START_SEED = 30
MAX_STARTS = 1000
#: The checks fit makes on its own end (issue 30: the mesh check, several
#: starts, growing a long record). beamid.robust builds on this module's fit
#: and fills this in when it is imported (the package imports it), so this
#: module does not import it: ``fit`` (plain fit -> checked FitResult).
_ROBUST: dict[str, Callable[..., Any]] = {}


class Residual(NamedTuple):
    """One data row after a fit."""

    experiment: str
    t: float
    quantity: str
    measured: float
    model: float
    sigma: float
    normalized: float  # (measured - model) / sigma


class IterationLog(NamedTuple):
    """One accepted Gauss-Newton/LM iteration (iteration 0 is the start)."""

    iteration: int
    cost: float          # chi-square including a priori rows
    damping: float       # Levenberg-Marquardt lambda (0: pure Gauss-Newton step)
    relative_step: float
    params: dict[str, float]


@dataclass(frozen=True)
class FitResult:
    """Result of :func:`fit`.

    ``estimates`` and ``sigmas`` are dicts by parameter name; ``cov`` and
    ``corr`` are arrays in the order of ``free``. A parameter the data do not
    determine has an infinite sigma and a flag in ``flags``; ``warnings``
    says so in words. A fit that stalled or whose parameter ran away has
    ``converged`` False, ``stop`` "stalled" or "runaway" and ``note`` saying
    which parameters are at a bound, running away or collinear.
    """

    model: Model
    start: Model
    experiments: dict[str, TipLoad | RadialWire]
    data: Measurements
    free: tuple[str, ...]
    prior: dict[str, tuple[float, float]]
    estimates: dict[str, float]
    sigmas: dict[str, float]
    cov: np.ndarray
    corr: np.ndarray
    chi2: float
    chi2_prior: float
    dof: int
    iterations: int
    converged: bool
    cond: float
    rank: int
    flags: dict[str, str]
    residuals: list[Residual]
    log: list[IterationLog] = field(repr=False)
    warnings: tuple[str, ...] = ()
    #: how the iteration ended: "converged", "stalled" (no step lowers the cost
    #: though the iterate is no minimum) or "runaway" (a parameter ran away,
    #: held where found, the others fitted); see ``note`` and ``flags``
    stop: str = "converged"
    #: what happened when the fit did not converge (or how a refit started)
    note: str = ""
    #: the model the user started from (refits of :func:`beamid.add_effect`
    #: and :func:`beamid.improve` also start from it); None: ``start``
    nominal: Model | None = field(default=None, repr=False)
    #: for a refit with an effect added: the start it kept ("first-order
    #: estimate", "nominal model" or "continuation")
    refit_start: str | None = None
    #: the measurement chain's nuisance parameters fitted with the physics
    #: (``nuisance=`` of :func:`fit`; beamid.chain): estimates and sigmas by
    #: name (``t0[exp]``, ``bias[exp:quantity]``, ``scale[exp:quantity]``);
    #: ``cov`` above is the physics block of ``full_cov`` (free parameters,
    #: then these), so the physics sigmas account for them
    nuisance: dict[str, float] = field(default_factory=dict)
    nuisance_sigmas: dict[str, float] = field(default_factory=dict)
    full_cov: np.ndarray | None = field(default=None, repr=False)
    chain: "ChainSpec | None" = field(default=None, repr=False)
    #: the rows' treatment (``loss``, ``burn_in``, ``estimate_sigma`` of
    #: :func:`fit`): the loss; per row the last IRLS weight (0: burn-in),
    #: whether it was fitted, and the rows flagged as gross errors
    #: (standardized residual beyond 3.5: not in chi2 and dof)
    loss: str = "linear"
    weights: np.ndarray | None = field(default=None, repr=False)
    fitted_rows: np.ndarray | None = field(default=None, repr=False)
    gross_errors: tuple[int, ...] = ()
    #: the sigmas estimated from the residuals, by channel "experiment:quantity":
    #: (sigma, its standard deviation)
    sigma_estimates: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: the rows' treatment asked for (beamid.chain.RowTreatment; None: plain)
    treatment: "RowTreatment | None" = field(default=None, repr=False)
    #: the mesh check (fits with releases that ended far above their degrees
    #: of freedom or stalled; beamid.robust.MeshCheck), None when not made
    mesh_check: "Any" = field(default=None, repr=False)
    #: where every start ended (beamid.robust.StartEnd; empty: one start)
    starts: tuple = field(default=(), repr=False)
    #: the start whose end point this is ("given start" or "random start k")
    start_won: str = "given start"
    #: the fits that led here when the record was grown (one line per window)
    path: tuple[str, ...] = field(default=(), repr=False)

    @property
    def chi2_per_dof(self) -> float:
        """Chi-square (data and a priori rows) per degree of freedom."""
        return (self.chi2 + self.chi2_prior) / self.dof if self.dof > 0 else math.nan

    @property
    def normalized(self) -> np.ndarray:
        """Normalized residuals (measured - model) / sigma, in row order."""
        return np.array([r.normalized for r in self.residuals])

    def summary(self) -> str:
        """A printable table of the estimates."""
        lines = [f"{'parameter':<16}{'estimate':>14}{'sigma':>12}  flag"]
        for name in self.free:
            lines.append(f"{name:<16}{self.estimates[name]:>14.6g}{self.sigmas[name]:>12.3g}  "
                         f"{self.flags[name]}")
        for name, (v, sd) in self.sigma_estimates.items():
            lines.append(f"sigma of {name} estimated from the residuals: {v:.4g} +- {sd:.2g}")
        if self.gross_errors:
            lines.append(f"gross errors (|normalized residual| > 3.5, not in chi2): rows "
                         + ", ".join(str(i) for i in self.gross_errors))
        if self.nuisance:
            lines.append("measurement chain:")
            for name, v in self.nuisance.items():
                lines.append(f"{name:<16}{v:>14.6g}{self.nuisance_sigmas[name]:>12.3g}")
        lines.append(f"chi2 = {self.chi2:.4g} (+ a priori {self.chi2_prior:.3g}), dof = "
                     f"{self.dof}, chi2/dof = {self.chi2_per_dof:.3g}, "
                     f"{self.iterations} iterations, condition number {self.cond:.3g}")
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        est = ", ".join(f"{n} = {self.estimates[n]:.6g} +- {self.sigmas[n]:.3g} "
                        f"({self.flags[n]})" for n in self.free[:6])
        more = f", ... ({len(self.free)} free)" if len(self.free) > 6 else ""
        return (f"<FitResult {self.stop} after {self.iterations} iterations: {est}{more}; "
                f"chi2 {self.chi2:.4g} for {self.dof} dof>")


# ----------------------------------------------------------------- building blocks

def _check_experiments(experiments: Experiments) -> dict[str, TipLoad | RadialWire]:
    if not isinstance(experiments, Mapping) or not experiments:
        raise InputError("experiments must be a non-empty dict {name: load}, e.g. "
                         "{'F3': beamid.TipForce(fy=3.0)}")
    out = {}
    for name, load in experiments.items():
        # an experiment is what the core has a family for (beamid.loads.family)
        if family(load) is None:
            raise InputError(f"experiment {name!r}: load = {load!r}, expected TipForce, "
                             "TipMoment, RadialWire, Release or Modal")
        out[str(name)] = load
    return out


def build_problem(model: Model, experiments: Experiments, data: Measurements,
                  tol: float = 0.0, chain: ChainSpec | None = None,
                  rows: RowTreatment | None = None) -> _ce.Problem:
    """Arrays for the Fortran core; checks that every row can be predicted.
    ``chain``: the nuisance parameters of the measurement chain (their
    values follow the model's in the parameter vector, ChainSpec.order)."""
    exps = _check_experiments(experiments)
    if not isinstance(data, Measurements):
        raise InputError(f"data must be beamid.Measurements (read_measurements), got "
                         f"{type(data).__name__}")
    data.check_experiments(exps)
    names = list(exps)
    kinds = np.zeros(len(names), np.int32)
    specs: list[dict[str, float]] = []
    for j, name in enumerate(names):
        kinds[j], spec = exps[name].spec()
        specs.append(dict(spec))
    # the problem's observation list: each distinct name once, in the core's
    # order of kinds and loci (observations.ordered), parsed by the core; the
    # measurement chain's channel masks number its entries
    labels = {q: i for i, q in enumerate(observations.ordered(data.quantity), start=1)}
    obs = [observations.parse(q) for q in labels]
    _check_stations(model, data, dict(zip(labels, obs)))
    if chain:
        chain.encode(names, specs, labels)
    if rows:
        rows.encode(names, specs, labels)
    hist_spec, hist_tab = _histories(model, names, exps)
    return _ce.Problem(
        nbeams=model.nbeams, exp_kind=kinds, exp_specs=tuple(specs),
        row_exp=np.array([names.index(e) + 1 for e in data.experiment], np.int32),
        row_q=np.array([labels[q] for q in data.quantity], np.int32),
        row_value=np.array(data.value, float), row_sigma=np.array(data.sigma, float),
        row_t=np.array(data.t, float), tol=float(tol),
        obs_kind=np.array([observations.binding_code(o) for o in obs], np.int32),
        obs_beam=np.array([o.beam for o in obs], np.int32),
        obs_s=np.array([o.s for o in obs], float), obs_labels=tuple(labels),
        hist_spec=hist_spec, hist_tab=hist_tab)


def _histories(model: Model, names: list[str], exps) -> tuple:
    """The load histories of the release experiments as the core's own list
    (a column [experiment, beamid_loads' layout] each; None, None without
    any); a chirp above the mesh's highest frequency is warned of."""
    cols, tabs = [], []
    for j, name in enumerate(names):
        x = exps[name]
        if not (isinstance(x, Release) and x.loads):
            continue
        _warn_chirp(model, x.elements_per_beam, list(x.loads))
        spec, tab = _lh.columns(list(x.loads))
        offset = sum(t.shape[1] for t in tabs)
        spec = np.array(spec)
        spec[7, spec[8] > 0] += offset
        cols += [np.concatenate([[j + 1.0], spec[:, k]]) for k in range(spec.shape[1])]
        tabs.append(tab)
    if not cols:
        return None, None
    return (np.asfortranarray(np.array(cols).T), np.asfortranarray(np.concatenate(tabs, axis=1)))


def _check_stations(model: Model, data: Measurements, parsed: dict) -> None:
    """InputError naming the row for a station on a beam the model does not
    have or beyond its beam's length (0 <= s <= L_b)."""
    for i, q in enumerate(data.quantity):
        o = parsed[q]
        if observations.kinds()[o.kind].locus != "station":
            continue
        where = data._where(i)
        if not 1 <= o.beam <= model.nbeams:
            raise InputError(f"{where}: field quantity = {q!r}: beam {o.beam} does not exist, "
                             f"expected 1..{model.nbeams}")
        length = float(model[f"L{o.beam}"])
        if o.s > length * (1.0 + 1e-12):
            raise InputError(f"{where}: field quantity = {q!r}: station s = {o.s:g} is beyond "
                             f"beam {o.beam}, expected 0 <= s <= {length:g} (L{o.beam})")


def _free_indices(model: Model, free: Iterable[str]) -> tuple[tuple[str, ...], np.ndarray]:
    names = _check.names("free", free)
    if not names:
        raise InputError("free is empty: name the parameters to estimate, e.g. "
                         "free=('EI1', 'EI2')")
    canonical = tuple(model.names()[model.index(n)] for n in names)
    for n in canonical:
        if canonical.count(n) > 1:
            raise InputError(f"free names parameter {n!r} twice")
    return canonical, np.array([model.index(n) + 1 for n in canonical], np.int32)


def _prior_arrays(model: Model, free: tuple[str, ...],
                  prior: Mapping[str, tuple[float, float]] | None):
    out, rows = {}, []
    for name, spec in (_check.mapping("prior", prior, none=True) or {}).items():
        canonical = model.names()[model.index(name)]
        if canonical not in free:
            raise InputError(f"prior names {name!r}, which is not free (free: "
                             f"{', '.join(free)})")
        try:
            m, s = (float(v) for v in spec)
        except (TypeError, ValueError):
            raise InputError(f"prior[{name!r}] = {spec!r}, expected (mean, sigma)") from None
        if not (math.isfinite(m) and math.isfinite(s) and s > 0.0):
            raise InputError(f"prior[{name!r}] = ({m:g}, {s:g}), expected a finite mean and "
                             "sigma > 0")
        rows.append((model.index(canonical) + 1, m, s))
        out[canonical] = (m, s)
    return out, _ce.prior_table(rows)


def _named(model: Model, text: str) -> str:
    """Fortran notes name parameters by 1-based index ("parameter 7",
    "parameters 2 and 5"): put the names in."""
    names = model.names()

    def name(k: str) -> str:
        i = int(k) - 1
        return names[i] if 0 <= i < len(names) else f"parameter {k}"

    def one(match: re.Match) -> str:
        if match.group(2):
            return f"{name(match.group(1))} and {name(match.group(2))}"
        return name(match.group(1))

    return re.sub(r"\bparameters? (\d+)(?: and (\d+))?", one, text)


def _warnings(free: tuple[str, ...], flags: np.ndarray, corr: np.ndarray, cond: float,
              rank: int, stop: str = "converged", note: str = "") -> tuple[str, ...]:
    out = []
    if stop in ("runaway", "stalled"):
        out.append(f"not converged ({stop}): {note}")
    if stop == "runaway":
        pass    # the held parameter's column is left out of rank and condition
    elif rank < len(free):
        out.append(f"the free parameters are not identifiable from these data (rank {rank} "
                   f"of {len(free)}); undetermined parameters have infinite sigma")
    elif cond > 1e6:
        out.append(f"ill-conditioned problem (condition number {cond:.3g})")
    for i, name in enumerate(free):
        if flag_is_problem(FLAG_TEXT.get(int(flags[i]), "flagged")):
            out.append(f"{name}: {FLAG_TEXT.get(int(flags[i]), 'flagged')}")
    for i in range(len(free)):
        for j in range(i + 1, len(free)):
            c = corr[i, j]
            if np.isfinite(c) and abs(c) > 0.99:
                out.append(f"{free[i]} and {free[j]} are correlated {c:+.4f}: the data "
                           "determine a combination of them, not each")
    return tuple(out)


def _check_fit_args(data, tol, max_iter) -> None:
    """Argument checks of fit (InputError naming the argument)."""
    if not isinstance(data, Measurements):
        raise InputError(f"data = {type(data).__name__}, expected beamid.Measurements "
                         "(beamid.read_measurements)")
    _check.real("tol", tol, min=0.0, expected="0 (default) or a positive tolerance")
    _check.count("max_iter", max_iter, min=1)


def fit(model: Model, experiments: Experiments, data: Measurements,
        free: Sequence[str] = ("EI1", "EI2"),
        prior: "Mapping[str, tuple[float, float]] | FitResult | None" = None, *,
        max_iter: int = 50, tol: float = 0.0, jacobian: str = "auto",
        nuisance: Mapping | None = None, loss: str = "linear",
        burn_in: "float | Mapping[str, float] | None" = None,
        estimate_sigma: "bool | Sequence | None" = None,
        starts: int | None = None, start_spread: float = START_SPREAD,
        start_seed: int = START_SEED, workers: int | None = 1, client: Any = None,
        mesh: bool = True, grow: bool | None = None,
        homotopy: bool | None = None) -> FitResult:
    """Estimate the ``free`` parameters of ``model`` from ``data``.

    Weighted Gauss-Newton differential correction (Eq. 39, weights 1/sigma^2
    of Eq. 53-54) with the hand-coded sensitivities (Eq. 40-51), a
    Levenberg-Marquardt safeguard when a step does not lower the cost,
    physical bounds (stiffnesses stay positive, compliances non-negative,
    axial_coupling in [0, 1]) and a priori information (Eq. 142-145: each
    ``prior[name] = (mean, sigma)`` adds a pseudo-measurement). The
    covariance (Eq. 55) comes from the SVD of the weighted Jacobian: a
    direction the data do not see gets an infinite sigma, not a number.

    Parameters
    ----------
    model:
        Starting model; parameters not in ``free`` stay at its values.
    experiments:
        ``{name: load}``, e.g. ``{"F3": beamid.TipForce(fy=3.0)}``.
    data:
        :class:`beamid.Measurements` (:func:`beamid.read_measurements`).
    free:
        Names of the parameters to estimate.
    prior:
        Optional a priori ``{name: (mean, sigma)}`` for free parameters, or a
        previous :class:`FitResult`: its estimates and full covariance become
        the a priori information (Eq. 146-148, 164-166) and its free
        parameters are freed here too.
    max_iter:
        Gauss-Newton iterations; a fit still moving after them raises
        :class:`beamid.ConvergenceError` (``exc.partial`` holds the last
        iterate).
    tol:
        Static solver tolerance (0: default).
    jacobian:
        ``"auto"`` (default): releases on the implicit integrator steer the
        iteration with sensitivities integrated at rtol 1e-6 (predictions
        and residuals at their own tolerance); at the end the Jacobian is
        evaluated at the release's own tolerance, the fit iterates on with
        it if it still promises a chi-square decrease above 0.01, and the
        covariance comes from it (docs/workflow.md, "How the fit uses the
        Jacobian"). ``"exact"``: sensitivities at the release's own
        tolerance at every iteration. Static experiments are the same
        either way.
    nuisance:
        The measurement chain's nuisance parameters fitted with the physics
        (docs/workflow_dynamic.md, "The measurement chain"):
        ``{"time_offset": [experiment, ...], "bias": [(experiment,
        quantity), ...], "scale": [...], "initial_velocity": [release,
        ...]}`` (a dict instead of a list gives start values). A release's
        clock offset t0 is the model time at its record's zero (the row at
        record time t is the model at t + t0); a channel's bias b and scale
        s make a row read s h + b; a release's initial velocity v0 is its
        tip's normal velocity at t = 0 (the static shape q starts with the
        velocity field v0 q / w_tip(q); ``v0[release]``). Their
        estimates and sigmas are ``result.nuisance`` and
        ``result.nuisance_sigmas``; ``result.cov`` (the physics block of
        ``result.full_cov``) accounts for them.
    loss:
        ``"linear"`` (least squares), ``"huber"`` or ``"cauchy"``: a robust
        loss by iteratively reweighted least squares (the covariance from
        the reweighted Jacobian); rows whose standardized residual passes
        3.5 are ``result.gross_errors`` (left out of chi2 and dof).
    burn_in:
        A time (s) for every release, or ``{experiment: time}``: rows
        before it are predicted and shown, not fitted.
    estimate_sigma:
        ``True`` (every channel), quantity names or (experiment, quantity)
        pairs: their sigma is estimated from the residuals (the data's
        sigmas are only its start), one degree of freedom each;
        ``result.sigma_estimates`` holds each with its uncertainty.

    starts:
        More fits from random starts around ``model`` (each free parameter
        times U(1 - start_spread, 1 + start_spread), start k from
        ``SeedSequence(start_seed, spawn_key=(k,))``); the best end point is
        the result (the given start's unless another went lower by more than
        0.05, the noise floor's scale), ``result.starts`` says where every
        start ended and
        ``result.start_won`` which won (docs/workflow_dynamic.md, "Reaching
        the best fit"). ``None`` (default): 4 more starts when a fit with
        releases ends far above its degrees of freedom (p < 0.001) or
        stalls and the mesh check does not name the mesh; 0: never.
    workers, client:
        Where the starts run, as in :func:`beamid.consistency`: ``workers``
        local processes (1: this process; None: the cores, when the starts
        are long enough to pay for the processes) or a Dask ``client``.
    grow:
        Grow the record: fit the releases' rows up to a window of about a
        second first, then twice that, ... up to the whole record, each from
        the last window's estimates (``result.path`` lists the windows), so
        the phase is caught before the whole record is fitted (the windows
        before the last at rtol 1e-6, the whole record at the releases' own
        tolerance). ``None`` (default): on records longer than 4 s; True: on
        records of 2 s and more; False: never.
    homotopy:
        The friction homotopy (a model with joint friction on releases with
        the sign law): fit on the smooth law mu N v / sqrt(v^2 + vs^2) at
        vs = 1e-2, then 1e-3 m/s, then on the sign law, each stage from the
        last one's estimates (``result.path`` lists the stages), so the
        stick-slip pattern settles before Gauss-Newton sees its kinks.
        ``None`` (default): when the plain fit ends far above its degrees
        of freedom or stalls and the mesh is not the likely cause (the
        path's end replaces the fit when it goes lower by more than 0.05;
        ``result.start_won`` is then "friction homotopy"); True: always (the
        path is the fit); False: never.
    mesh:
        Check the mesh of a fit with releases that ends far above its
        degrees of freedom or stalls (``result.mesh_check``; one plain run at
        twice the elements per beam, and a refit there when a prediction
        moves by more than a sigma): when the discretization is the likely
        cause, a warning names the elements per beam that would do.

    A parameter that runs away (beyond 100 times its start, or a stiffness
    below a ten-thousandth of it) is held where it was found and the others
    are fitted; a fit whose damped steps stop lowering the cost stalls.
    Both come back flagged (``result.stop``, ``result.note``,
    ``result.flags``), not raised. ConvergenceError is for a model the
    solver cannot solve at the values asked, and for the iteration limit.
    """
    _check_fit_args(data, tol, max_iter)
    if not isinstance(model, Model):
        raise InputError(f"model must be a beamid.Model, got {type(model).__name__}")
    _check.choice("jacobian", jacobian, ("auto", "exact"))
    exps = _check_experiments(experiments)   # once: the checks below take the dict
    chain = parse_nuisance(nuisance, exps, data)
    rows = parse_rows(loss, burn_in, estimate_sigma, exps, data)
    check_sigma_given(data, rows)
    prob = build_problem(model, experiments, data, tol, chain, rows)
    if jacobian == "exact":
        # key fd = 2 (beamid_family): a release's sensitivities at its own
        # tolerance at every iteration (1, central differences, is kept)
        prob = dataclasses.replace(prob, exp_specs=tuple(
            {**spec, "fd": 2.0} if kind == LOAD_RELEASE and spec.get("fd", 0.0) == 0.0
            else spec for kind, spec in zip(prob.exp_kind, prob.exp_specs)))
    if isinstance(prior, FitResult):
        free_names, free_idx = _free_indices(model, _with_carried(free, prior))
        prior_map, ptable, pcov = _carried_prior(model, prior)
    else:
        free_names, free_idx = _free_indices(model, free)
        (prior_map, ptable), pcov = _prior_arrays(model, free_names, prior), None
    starts, start_spread, start_seed, workers, client, mesh, grow = _check_robust_args(
        starts, start_spread, start_seed, workers, client, mesh, grow)
    if homotopy is not None and not isinstance(homotopy, (bool, np.bool_)):
        _check.fail("homotopy", homotopy, "None (automatic), True or False")
    homotopy = None if homotopy is None else bool(homotopy)
    exp_names = list(exps)
    params0, free_idx = _with_chain(model, chain, exp_names, free_idx)

    def plain() -> FitResult:
        if not rows:
            raw = _ce.fit(prob, params0, free_idx, ptable, prior_cov=pcov,
                          max_iter=int(max_iter))
            return _result(model, experiments, data, free_names, prior_map, raw, chain=chain)
        raw = _ce.fit_chain(prob, params0, free_idx, ptable, prior_cov=pcov,
                            max_iter=int(max_iter))
        out = _result(model, experiments, data, free_names, prior_map, raw, chain=chain)
        return with_row_treatment(out, rows, raw)

    checked = _ROBUST.get("fit")
    # the measurement chain's fits (nuisance parameters, a loss, burn-in,
    # estimated sigmas) are one start without the mesh check: the several
    # starts and the mesh check refit through fit without the chain's keywords
    if checked is None or chain or rows:
        return plain()
    return checked(plain, model, experiments, data, free, prior,
                   {"max_iter": max_iter, "tol": tol, "jacobian": jacobian},
                   starts=starts, spread=start_spread, seed=start_seed, workers=workers,
                   client=client, mesh=mesh, grow=grow, homotopy=homotopy)


def _with_chain(model: Model, chain: ChainSpec | None, exp_names: list[str],
                free_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The parameter vector and free indices with the chain's nuisance
    parameters after the model's (all of them free)."""
    params0 = model.vector()
    if not chain:
        return params0, free_idx
    starts = chain.starts(exp_names)
    extra = np.arange(params0.size + 1, params0.size + starts.size + 1, dtype=np.int32)
    return np.concatenate([params0, starts]), np.concatenate([free_idx, extra]).astype(np.int32)


def _check_robust_args(starts, spread, seed, workers, client, mesh, grow) -> tuple:
    """Argument checks of fit's keywords for its own end (issue 30): the
    several starts, where they run, the mesh check and growing the record."""
    starts = _check.count("starts", starts, min=0, max=MAX_STARTS, none=True,
                          expected="None (automatic), 0 or a positive integer")
    spread = _check.real("start_spread", spread, above=0.0, below=1.0,
                         expected="a number in (0, 1)")
    seed = _check.count("start_seed", seed, min=0, max=2**128, expected="an integer >= 0")
    workers = _check.count("workers", workers, min=1, none=True,
                           expected="None (the cores) or an integer >= 1")
    client = _check.dask_client("client", client)
    mesh = _check.flag("mesh", mesh)
    if grow is not None and not isinstance(grow, (bool, np.bool_)):
        _check.fail("grow", grow, "None (automatic), True or False")
    grow = None if grow is None else bool(grow)
    return starts, spread, seed, workers, client, mesh, grow


def _with_carried(free: Sequence[str] | str, prior: "FitResult") -> tuple[str, ...]:
    """The free parameters of a fit carrying ``prior`` forward: the ones
    asked for, then the previous fit's (Eq. 147: both are updated)."""
    names = _check.names("free", free)
    return names + tuple(n for n in prior.free if n not in names)


def _carried_prior(model: Model, prior: "FitResult"):
    """A previous fit as a priori information: (prior by name, its
    prior_table, full covariance) (Eq. 146-148, 164-166)."""
    cov = np.asarray(prior.cov, float)
    if not np.all(np.isfinite(cov)):
        bad = [n for n in prior.free if not math.isfinite(prior.sigmas[n])]
        raise InputError(f"prior: the previous fit did not determine {', '.join(bad) or 'all'}"
                         " (infinite sigma): its covariance cannot be carried forward")
    names = tuple(model.names()[model.index(n)] for n in prior.free)
    rows = [(model.index(n) + 1, float(prior.estimates[f]), float(np.sqrt(cov[i, i])))
            for i, (n, f) in enumerate(zip(names, prior.free))]
    return {n: (m, s) for n, (_, m, s) in zip(names, rows)}, _ce.prior_table(rows), cov


def with_row_treatment(out: FitResult, rows: RowTreatment, raw: dict) -> FitResult:
    """The fit ``out`` with the rows as the measurement chain's treatments
    ``rows`` judged them (``raw``: the keys weights, sigma_used, sigma_sd and
    flagged of beamid_chain_fit): each residual's sigma, the weights, the
    fitted rows, the gross errors and the estimated sigmas."""
    data = out.data
    sig = raw["sigma_used"]
    residuals = [r._replace(sigma=float(s)) for r, s in zip(out.residuals, sig)]
    est = {}
    for e, q in rows.estimate:
        k = next(i for i, (x, y) in enumerate(zip(data.experiment, data.quantity))
                 if x == e and y == q)
        est[f"{e}:{q}"] = (float(sig[k]), float(raw["sigma_sd"][k]))
    return dataclasses.replace(
        out, residuals=residuals, loss=rows.loss, weights=raw["weights"],
        fitted_rows=np.array([t >= rows.burn_in.get(e, 0.0) for e, t in
                              zip(data.experiment, data.t)], bool),
        gross_errors=tuple(int(i) for i in np.flatnonzero(raw["flagged"])),
        sigma_estimates=est, treatment=rows)


def _result(start: Model, experiments: Experiments, data: Measurements,
            free: tuple[str, ...], prior: dict, raw: dict,
            nominal: Model | None = None, chain: ChainSpec | None = None) -> FitResult:
    npar = start.vector().size
    nf = len(free)
    full_cov = None
    nuis, nuis_sig = {}, {}
    if chain:
        exp_names = list(experiments)
        names = chain.names(exp_names)
        extra = np.asarray(raw["params"][npar:], float)
        nuis = {n: float(v) for n, v in zip(names, extra)}
        nuis_sig = {n: float(v) for n, v in zip(names, raw["sigmas"][nf:])}
        chain = chain.with_values(exp_names, extra)
        full_cov = raw["cov"]
        raw = dict(raw, params=raw["params"][:npar], sigmas=raw["sigmas"][:nf],
                   cov=raw["cov"][:nf, :nf], corr=raw["corr"][:nf, :nf], flags=raw["flags"][:nf],
                   log_params=raw["log_params"][:nf])
    fitted = Model(start.nbeams, raw["params"])
    stop = raw.get("stop", "converged")
    note = _named(start, raw.get("note", "")) if stop not in ("converged", "evaluated") \
        or raw.get("start") else ""
    stop = "converged" if stop == "evaluated" else stop
    est = {n: float(fitted[n]) for n in free}
    sig = {n: float(s) for n, s in zip(free, raw["sigmas"])}
    residuals = [Residual(e, float(t), q, float(v), float(p), float(s), float(r))
                 for e, t, q, v, s, p, r in zip(data.experiment, data.t, data.quantity,
                                                data.value, data.sigma, raw["predictions"],
                                                raw["normalized"])]
    log = [IterationLog(k, float(c), float(lam), float(st),
                        {n: float(v) for n, v in zip(free, raw["log_params"][:, k])})
           for k, (c, lam, st) in enumerate(zip(raw["log_cost"], raw["log_lambda"],
                                                raw["log_step"]))]
    flags = {n: FLAG_TEXT.get(int(f), "flagged") for n, f in zip(free, raw["flags"])}
    return FitResult(
        model=fitted, start=start, experiments=dict(experiments), data=data, free=free,
        prior=prior, estimates=est, sigmas=sig, cov=raw["cov"], corr=raw["corr"],
        chi2=raw["chi2"], chi2_prior=raw["chi2_prior"], dof=raw["dof"],
        iterations=raw["iterations"], converged=raw["converged"], cond=raw["cond"],
        rank=raw["rank"], flags=flags, residuals=residuals, log=log,
        warnings=_warnings(free, raw["flags"], raw["corr"], raw["cond"], raw["rank"],
                           stop, note if stop != "converged" else "")
        + _mode_crossings(start, fitted, experiments, data),
        stop=stop, note=note, nominal=nominal if nominal is not None else start,
        refit_start=raw.get("start"), nuisance=nuis, nuisance_sigmas=nuis_sig,
        full_cov=full_cov, chain=chain if chain else None)


def _mode_crossings(start: Model, fitted: Model, experiments: Experiments,
                    data: Measurements) -> tuple[str, ...]:
    """Warnings for the modes of the modal experiments whose order changed
    between the start and the end of a fit: the rows freq[k] (and the others
    of mode k) then compare with a model mode that was not mode k at the
    start (a mode moved across another). Modes are followed by the MAC of
    their shapes at ten stations a beam (normal and tangential motion)."""
    out = []
    for name, x in experiments.items():
        fam = family(x)
        if fam is None or fam.name != "modal":
            continue
        modes = [observations.parse(q).mode for e, q in zip(data.experiment, data.quantity)
                 if e == name]
        if not modes or max(modes) < 1:
            continue
        n = max(modes)
        try:
            # shapes along the whole arm (not the free unknowns: a compliance
            # fitted from 0 adds a hinge, and unknowns, during the fit)
            where = tuple((kind, b, start[f"L{b}"] * (j / 10) * (1 - 1e-12))
                          for b in range(1, start.nbeams + 1) for j in range(1, 11)
                          for kind in ("shape_n", "shape_t"))
            a = _modal.modal_analysis(start, x.load, nmodes=n, stations=where,
                                      elements_per_beam=x.elements_per_beam)
            more = min(n + 5, a.nmodes_model)     # a mode may have dropped below mode n
            b = _modal.modal_analysis(fitted, x.load, nmodes=more, stations=where,
                                      elements_per_beam=x.elements_per_beam)
        except (BeamidError, ValueError):
            continue
        m = _modal.mac(a.shapes, b.shapes)
        for k in sorted(set(modes)):
            j = int(np.argmax(m[k - 1])) + 1
            if j != k:
                out.append(f"experiment {name!r}: model mode {k} at the start is mode {j} at the "
                           f"end of the fit (MAC {m[k - 1, j - 1]:.2f}): a mode moved across "
                           f"another, so the rows of mode {k} now compare with another mode; "
                           "check the pairing (beamid.pair_modes)")
    return tuple(out)


def predict(model: Model, experiments: Experiments, data: Measurements,
            wrt: Sequence[str] = ()) -> tuple[np.ndarray, np.ndarray]:
    """Model values of the data rows and their derivatives with respect to
    ``wrt`` (rows x len(wrt)), as the fit uses them."""
    prob = build_problem(model, experiments, data)
    idx = np.array([model.index(n) + 1 for n in wrt], np.int32)
    return _ce.problem_predict(prob, model.vector(), idx)


def _check_quantities(exps, quantities, sigma) -> None:
    """Argument checks of simulate_measurements (InputError naming the argument)."""
    if isinstance(quantities, str) or not isinstance(quantities, (Mapping, Sequence)):
        raise InputError(f"quantities = {quantities!r}, expected a list of quantity names "
                         "or {experiment: [names]}")
    lists = quantities.values() if isinstance(quantities, Mapping) else [quantities]
    if isinstance(quantities, Mapping):
        missing = [n for n in exps if n not in quantities]
        if missing:
            raise InputError(f"quantities has no entry for experiment {missing[0]!r} "
                             f"(experiments: {', '.join(exps)})")
    for qs in lists:
        for q in ([qs] if isinstance(qs, str) else qs):
            if q not in QUANTITIES:
                try:
                    observations.parse(q)
                except InputError:
                    raise InputError(f"quantities: {q!r} is not a quantity, expected one of "
                                     f"{', '.join(QUANTITIES)} (a station kind as "
                                     "kind@beam:s)") from None
            if isinstance(sigma, Mapping) and q not in sigma:
                raise InputError(f"sigma has no entry for quantity {q!r}")
    values = list(sigma.values()) if isinstance(sigma, Mapping) else [sigma]
    for v in values:
        _check.real("sigma", v, above=0.0, expected="a finite standard deviation > 0")


def simulate_measurements(model: Model, experiments: Experiments, quantities: Sequence[str] | Mapping,
             sigma: float | Mapping[str, float] = 1e-3, *, seed: int | None = None,
             noise: bool = False,
             t: Sequence[float] | Mapping[str, Sequence[float]] | None = None,
             nuisance: Mapping[str, Any] | None = None) -> Measurements:
    """Synthetic measurements of ``quantities`` in every experiment.

    ``quantities`` is a list used for every experiment or a mapping
    ``{experiment: [quantities]}``. ``sigma`` is one number or a mapping by
    quantity. With ``noise=True`` Gaussian errors of that sigma are drawn
    from ``numpy.random.default_rng(seed)``. ``t``: the measurement times of
    the :class:`beamid.Release` experiments (one sequence for all, or
    ``{experiment: times}``); static experiments are measured at t = 0.
    ``nuisance``: a measurement chain to simulate, as :func:`fit` takes it
    with start values (``{"initial_velocity": {"free": 0.2}}``: a release
    thrown with tip normal velocity 0.2 m/s; ``{"time_offset": {"free":
    0.015}}``, biases and scales likewise): the data read through it.
    """
    if not isinstance(model, Model):
        raise InputError(f"model must be a beamid.Model, got {type(model).__name__}")
    exps = _check_experiments(experiments)
    _check_quantities(exps, quantities, sigma)
    seed = _check.count("seed", seed, min=0, max=2**128, none=True)
    noise = _check.flag("noise", noise)
    if isinstance(t, Mapping):
        t = {str(k): v for k, v in t.items()}
    def listed(q):
        return [q] if isinstance(q, str) else list(q)

    # static experiments measuring only the tip, elbow and wire are solved here
    # and read by name; any other mix (a release, a modal test, a station's
    # gauge or curvature) is predicted through the inverse problem's families
    direct = {"u_tip", "w_tip", *_static_outputs, *_static_aliases}
    mixed = (any(family(x).name != "static" for x in exps.values())
             or any(q not in direct for name in exps
                    for q in listed(quantities[name] if isinstance(quantities, Mapping)
                                    else quantities)))
    rows = []
    for name, x in exps.items():
        qs = quantities[name] if isinstance(quantities, Mapping) else quantities
        times = [0.0]
        if timed(x):
            times = t.get(name) if isinstance(t, Mapping) else t
            if times is None:
                raise InputError(f"t: no measurement times for the release experiment {name!r}")
            times = [float(v) for v in _check.reals("t", times, scalar=True, min=0.0)]
        elif not mixed:     # static experiments alone: solved here, measured by name
            result = solve_static(model, x)
        for tk in times:
            for q in ([qs] if isinstance(qs, str) else qs):
                s = float(sigma[q]) if isinstance(sigma, Mapping) else float(sigma)
                rows.append((name, tk, q, measurement_value(result, q) if not mixed else 0.0, s))
    data = Measurements.from_rows(rows, source="<simulated>")
    values = data.value
    if nuisance is not None:
        spec = parse_nuisance(nuisance, exps, data)
        values, _ = _ce.problem_predict(build_problem(model, exps, data, chain=spec),
                                        np.concatenate([model.vector(),
                                                        spec.starts(list(exps))]),
                                        np.zeros(0, np.int32))
    elif mixed:
        values, _ = _ce.problem_predict(build_problem(model, exps, data), model.vector(),
                                        np.zeros(0, np.int32))
    if noise:
        rng = np.random.default_rng(seed)
        values = values + rng.standard_normal(len(data)) * data.sigma
    return data.with_values(values)


class StageSigma(NamedTuple):
    """What one stage of :func:`identify` taught about one parameter."""

    stage: str
    parameter: str
    estimate: float
    sigma_before: float   # a priori (math.inf: not estimated before)
    sigma_after: float
    flag: str = ""        # the stage fit's flag of the parameter ("ok", "weak", ...)


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`: the fit of every stage, in order, and per
    stage and parameter the sigma before and after (``table``)."""

    stages: dict[str, FitResult]
    table: list[StageSigma]

    @property
    def final(self) -> FitResult:
        return list(self.stages.values())[-1]

    def summary(self) -> str:
        w = max([10] + [len(r.stage) + 2 for r in self.table])
        lines = [f"{'stage':<{w}}{'parameter':<12}{'estimate':>12}{'sigma before':>14}"
                 f"{'sigma after':>13}  flag"]
        for r in self.table:
            lines.append(f"{r.stage:<{w}}{r.parameter:<12}{r.estimate:>12.4g}"
                         f"{r.sigma_before:>14.3g}{r.sigma_after:>13.3g}  {r.flag}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def __repr__(self) -> str:
        return (f"<Identification: {len(self.stages)} stages ({', '.join(self.stages)}); "
                f"print() shows the table>")

    def plot(self, ax=None):
        """Bar chart of sigma / estimate per stage and parameter (log scale)."""
        import matplotlib.pyplot as plt
        if _check.axes("ax", ax) is None:
            _, ax = plt.subplots(figsize=(6.4, 3.8), layout="constrained")
        names = list(dict.fromkeys(r.parameter for r in self.table))
        stages = list(self.stages)
        width = 0.8 / max(len(stages), 1)
        for k, stage in enumerate(stages):
            vals = [next((abs(r.sigma_after / r.estimate) for r in self.table
                          if r.stage == stage and r.parameter == n and r.estimate != 0),
                         np.nan) for n in names]
            ax.bar(np.arange(len(names)) + k * width, vals, width, label=stage)
        ax.set_xticks(np.arange(len(names)) + 0.4 - width / 2, names)
        ax.set_yscale("log")
        ax.set_xlabel("parameter")
        ax.set_ylabel("sigma / estimate after the stage (-)")
        ax.set_title("what each stage taught: relative sigma after it")
        ax.legend(title="stage")
        return ax


def identify(model: Model, stages: Mapping[str, tuple] | Sequence[tuple], *,
             max_iter: int | Mapping[str, int] = 50,
             starts: Mapping[str, Model] | None = None) -> Identification:
    """The sequential identification of Chapter VI: static -> free -> forced.

    ``stages`` is ``{name: (experiments, data, free)}`` (or a list of such
    triples, named stage1, stage2, ...). Each stage fits its ``free``
    parameters from its data starting where the previous stage ended, with
    the previous stage's estimates and full covariance as a priori
    information (Eq. 146-148, 164-166; the carried parameters are updated
    too). The first stage may be given as ``(experiments, data, free,
    prior)`` with a dict prior; a later stage's a priori information is the
    carried fit (a dict prior given there is not used). ``starts`` (optional,
    by stage name): the model a stage starts from (a stage deck's own), its
    carried parameters replaced by the previous stage's estimates.
    ``max_iter``: one limit for every stage or ``{stage: limit}`` (50 for a
    stage not named).
    """
    return _identify(model, stages, max_iter, starts, lambda _, m, e, d, free, prior, limit:
                     fit(m, e, d, free=free, prior=prior, max_iter=limit))


def _identify(model: Model, stages, max_iter, starts, stage_fit) -> Identification:
    """:func:`identify` with stage ``name``'s fit made by ``stage_fit(name,
    start model, experiments, data, free, prior, max_iter)`` (as :func:`fit`
    with a dict prior or the previous stage's FitResult)."""
    if isinstance(stages, (str, bytes)) or not isinstance(stages, (Mapping, Sequence)):
        _check.fail("stages", stages, "{name: (experiments, data, free)} or a list of such "
                    "triples")
    items = list(stages.items()) if isinstance(stages, Mapping) else [
        (f"stage{k + 1}", s) for k, s in enumerate(stages)]
    starts = _check.mapping("starts", starts, none=True)
    for name, start in (starts or {}).items():
        _check.instance(f"starts[{name!r}]", start, Model, "a beamid.Model")
    if isinstance(max_iter, Mapping):
        for name, limit in max_iter.items():
            _check.count(f"max_iter[{name!r}]", limit, min=1)
    else:
        _check.count("max_iter", max_iter, min=1)
    if not items:
        raise InputError("stages is empty: give {name: (experiments, data, free)}")
    fits: dict[str, FitResult] = {}
    table: list[StageSigma] = []
    current, previous = model, None
    known: dict[str, float] = {}
    for name, spec in items:
        if not isinstance(spec, tuple) or len(spec) not in (3, 4):
            raise InputError(f"stage {name!r}: expected (experiments, data, free[, prior])")
        exps, data, free = spec[:3]
        prior = spec[3] if len(spec) == 4 else None
        if previous is not None:
            prior = previous
        if starts and name in starts:
            carried = {n: current[n] for n in (previous.free if previous else ())}
            current = starts[name].replace(**carried) if carried else starts[name]
        limit = max_iter.get(name, 50) if isinstance(max_iter, Mapping) else max_iter
        free = _check.names(f"stage {name!r}: free", free)
        fit_k = stage_fit(name, current, exps, data, free, prior, limit)
        for p in fit_k.free:
            before = known.get(p, math.inf)
            if isinstance(prior, Mapping) and p in fit_k.prior:
                before = fit_k.prior[p][1]
            table.append(StageSigma(name, p, fit_k.estimates[p], before, fit_k.sigmas[p],
                                    fit_k.flags.get(p, "")))
            known[p] = fit_k.sigmas[p]
        fits[name] = fit_k
        current, previous = fit_k.model, fit_k
    return Identification(fits, table)
