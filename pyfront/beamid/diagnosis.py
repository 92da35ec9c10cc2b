"""Compare, diagnose, add the missing effect: the model-improvement workflow.

>>> import beamid
>>> truth = beamid.pace(axial_coupling=0.0, elbow_flex=0.004)
>>> exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (2.0, 4.0, 6.0, 8.0)}
>>> data = beamid.simulate_measurements(truth, exps, ["x_tip", "y_tip", "tip_angle"], sigma=1e-4)
>>> fit = beamid.fit(beamid.pace(axial_coupling=0.0), exps, data, free=("EI1", "EI2"))
>>> beamid.diagnose(fit).verdict.effect
'elbow_flex'

The statistics run in Fortran (``beamid_estimation``): for every candidate
effect the fitted model has switched off, a score (Lagrange-multiplier) test
with the free parameters projected out predicts the chi-square drop and a
first-order estimate; the leading candidates are confirmed by refits
(likelihood ratio). This module names the results, words the verdict, and
drives :func:`improve`.

Candidate effects live in a registry (:data:`EFFECTS`): the built-in ones
are the core's table (Fortran ``beamid_effects``: names, parameters, null
values, bounds, the families that see them, the default candidates), user
blocks are added with :func:`register_effect`, and the release
family its comparison, diagnosis wording, default candidates and mesh
refinement with :func:`register_release_family` (``beamid.dyn_diagnosis``
builds on this module, so this module does not import it).
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, NamedTuple, Sequence

import numpy as np

from . import _check, _core_estimation as _ce
from .errors import ConvergenceError, InputError
from .estimation import (FLAG_TEXT, FitResult, Experiments, build_problem, fit as _fit,
                         flag_is_problem)
from .estimation import _check_experiments, _free_indices, _named, _prior_arrays, _result
from .estimation import with_row_treatment as _with_row_treatment
from . import chain as _chain, chain_refit as _chain_refit
from .chain import split_ladder_fit as _split_ladder_fit
from .loads import RadialWire, TipLoad, family as _family
from .measurements import Measurements
from .model import Model
from .progress import progress


# ------------------------------------------------------------------ registry

@dataclass(frozen=True)
class Effect:
    """A physical effect a model can switch on.

    ``params(model)`` names the parameters that switch it on; at their null
    value ``null_value`` (0 for every built-in effect) the effect is off, and
    physical values lie within ``lower`` and ``upper``. ``kinds`` says which
    experiment families can see it (``static``, ``dynamic``, ``modal``).
    """

    name: str
    description: str
    params: Callable[[Model], tuple[str, ...]]
    kinds: tuple[str, ...] = ("static",)
    null_value: float = 0.0
    lower: float = 0.0
    upper: float = math.inf
    #: what kind of cause it is: "physics" (an effect of the model) or
    #: "measurement chain" (a flaw of the record: beamid.chain's nuisance
    #: parameters, whose names come from the fit's experiments and data)
    cause: str = "physics"

    @property
    def one_sided(self) -> bool:
        """The null value is the lower bound: tests look at one side only."""
        return self.null_value <= self.lower

    def __post_init__(self) -> None:
        _check.text("Effect: name", self.name)
        _check.text("Effect: description", self.description, empty=True)
        if not callable(self.params):
            _check.fail("Effect: params", self.params, "a function of the model that names "
                        "the effect's parameters")
        object.__setattr__(self, "kinds", _check.names("Effect: kinds", self.kinds,
                                                       allowed=("static", "dynamic", "modal")))
        lower = _check.real("Effect: lower", self.lower, finite=False)
        upper = _check.real("Effect: upper", self.upper, finite=False, above=lower,
                            expected=f"a number above lower = {lower:g}")
        null = _check.real("Effect: null_value", self.null_value, min=lower, max=upper,
                           expected=f"a finite number within [{lower:g}, {upper:g}]")
        for field_name, value in (("lower", lower), ("upper", upper), ("null_value", null)):
            object.__setattr__(self, field_name, value)
        object.__setattr__(self, "cause", _check.choice("Effect: cause", self.cause,
                                                        ("physics", "measurement chain")))


EFFECTS: dict[str, Effect] = {}


def register_effect(effect: Effect) -> None:
    """Add (or replace) a candidate effect in the registry."""
    _check.instance("effect", effect, Effect, "a beamid.Effect")
    EFFECTS[effect.name] = effect


def _core_params(name: str) -> Callable[[Model], tuple[str, ...]]:
    """The parameters of the core's effect ``name`` in a model."""
    def params(model: Model) -> tuple[str, ...]:
        names = model.names()
        return tuple(names[i] for i in _ce.effect_table(model.nbeams)[name].params)
    return params


# the built-in effects: the core's table (names, descriptions and families do
# not depend on the number of beams; the parameters do)
for _row in _ce.effect_table(1).values():
    register_effect(Effect(_row.name, _row.description, _core_params(_row.name),
                           kinds=_row.kinds, null_value=_row.null_value, lower=_row.lower,
                           upper=_row.upper))
# the measurement chain's candidates (beamid.chain: nuisance parameters and
# row treatments of release fits, not effects of the model)
for _name, _text in _chain.CANDIDATE_EFFECTS:
    register_effect(Effect(_name, _text, lambda m: (), kinds=("dynamic",),
                           cause="measurement chain"))

#: Candidate effects tried for static experiments, in order.
STATIC_CANDIDATES = _ce.default_effects("static")

#: Candidate effects tried for modal experiments alone (issue 27): what a
#: modal test sees that the static arm does not; ``mesh`` (the modal tests at
#: twice their elements per beam) is named, not tried by default.
MODAL_CANDIDATES = _ce.default_effects("modal")

_STATES = dict(_ce.CANDIDATE_STATES)


def _families(experiments: Any) -> list:
    """The core's family of each experiment (beamid.loads.family; None for
    what is not an experiment), [] for what is not a set of experiments."""
    try:
        return [_family(x) for x in dict(experiments).values()]
    except (TypeError, ValueError):
        return []


def _modal_only(experiments: Any) -> bool:
    """Are all experiments modal tests (the core's 'modal' family)?"""
    fams = _families(experiments)
    return bool(fams) and all(f is not None and f.name == "modal" for f in fams)


def _meshed(experiments: Any) -> bool:
    """Has this set of experiments one with a mesh of its own (a release, a
    modal test: the core family's mesh key), which the ``mesh`` candidate
    refines?"""
    return any(f is not None and f.meshed for f in _families(experiments))


def _dynamic(experiments: Any) -> bool:
    """Has this set of experiments one whose rows are records in time (a
    release: the core family is timed; beamid.dyn_diagnosis takes over)?
    Public as beamid.dyn_diagnosis.is_dynamic."""
    return any(f is not None and f.timed for f in _families(experiments))


#: What fits with release experiments need from beamid.dyn_diagnosis, which
#: builds on this module's types and fills this in when it is imported (the
#: package imports it): ``compare`` (fit -> TimeComparison), ``diagnosis``
#: (the DynDiagnosis from the Fortran arrays), ``default_candidates``
#: (experiments -> candidate names) and ``refine_mesh``.
_RELEASE_FAMILY: dict[str, Callable[..., Any]] = {}


def register_release_family(*, compare: Callable[..., Any], diagnosis: Callable[..., Any],
                            default_candidates: Callable[..., Any],
                            refine_mesh: Callable[..., Any],
                            candidate: type | None = None) -> None:
    """Install the functions of the release family (beamid.dyn_diagnosis)
    that compare, diagnose, add_effect and improve call on fits with
    releases; ``candidate`` is the family's Candidate class (the measurement
    chain's row candidates of a diagnosis are made of it)."""
    _RELEASE_FAMILY.update(compare=compare, diagnosis=diagnosis,
                           default_candidates=default_candidates, refine_mesh=refine_mesh,
                           candidate=candidate or Candidate)


def _effect(name: str | Effect) -> Effect:
    if isinstance(name, Effect):
        return name
    try:
        return EFFECTS[str(name)]
    except KeyError:
        raise InputError(f"unknown effect {name!r}, expected one of "
                         f"{', '.join(EFFECTS)}") from None


# ------------------------------------------------------------------- compare

class CompareRow(NamedTuple):
    experiment: str
    quantity: str
    load: float          # load level (N for forces, N m for moments, m of wire pull-in)
    measured: float
    model: float
    sigma: float
    normalized: float


@dataclass(frozen=True)
class StructureTest:
    """A test for systematic structure in normalized residuals."""

    name: str
    statistic: float
    p_value: float
    detail: str


@dataclass(frozen=True)
class Comparison:
    """Measured against model values after a fit (:func:`compare`)."""

    fit: FitResult
    rows: tuple[CompareRow, ...]
    chi2: float
    dof: int
    expected: float          # E[chi2] = dof
    expected_sigma: float    # sqrt(2 dof)
    p_value: float           # P(chi2_dof > chi2)
    per_experiment: dict[str, float]
    tests: tuple[StructureTest, ...]
    systematic: bool         # a structure test or the chi-square fails at 1 %
    #: runs, expected runs, runs z, runs p, trend slope, trend z, trend p (NaN: undefined)
    structure: tuple[float, ...] = ()

    def __str__(self) -> str:
        lines = [f"{'experiment':<12}{'quantity':<12}{'load':>8}{'measured':>14}"
                 f"{'model':>14}{'sigma':>11}{'normalized':>12}"]
        for r in self.rows:
            lines.append(f"{r.experiment:<12}{r.quantity:<12}{r.load:>8.4g}{r.measured:>14.7g}"
                         f"{r.model:>14.7g}{r.sigma:>11.3g}{r.normalized:>12.3f}")
        lines.append(f"chi2 = {self.chi2:.4g}, expected {self.expected:.4g} +- "
                     f"{self.expected_sigma:.3g} (dof {self.dof}), p = {self.p_value:.3g}")
        for t in self.tests:
            lines.append(f"{t.name}: statistic {t.statistic:.3g}, p = {t.p_value:.3g} "
                         f"({t.detail})")
        lines.append("systematic structure: the model misses something" if self.systematic
                     else "no systematic structure: residuals look like noise")
        return "\n".join(lines)

    def __repr__(self) -> str:
        return (f"<Comparison of {len(self.rows)} rows: chi2 {self.chi2:.4g} for {self.dof} "
                f"dof, p = {self.p_value:.3g}, "
                f"{'systematic structure' if self.systematic else 'no systematic structure'}>")


def load_level(load: TipLoad | RadialWire, model: Model) -> float:
    """A scalar that orders experiments by how hard they load the arm:
    the force magnitude, else the moment magnitude, else for a wire the
    pull-in (total length - Lw); for a release or a modal test, its load's (as
    beamid-batch)."""
    # an experiment that holds a static load (a release, a modal test) is
    # ordered by that load
    load = getattr(load, "load", None) or load
    if isinstance(load, RadialWire):
        return model.total_length - load.Lw
    force = math.hypot(load.fx, load.fy)
    return force if force > 0.0 else abs(load.moment)


def compare(fit: FitResult) -> Comparison:
    """Per experiment and quantity, measured against model values, normalized
    residuals, chi-square against its expectation, and two tests for
    systematic structure against load: a Wald-Wolfowitz runs test on the
    signs of the residuals ordered by load (within each quantity) and a
    weighted trend (slope of the normalized residuals against load)."""
    if not isinstance(fit, FitResult):
        raise InputError(f"compare: fit = {fit!r}, expected a beamid.FitResult (beamid.fit)")
    if _dynamic(fit.experiments):   # time histories: beamid.dyn_diagnosis
        return _RELEASE_FAMILY["compare"](fit)
    levels = {name: load_level(load, fit.model) for name, load in fit.experiments.items()}
    rows = tuple(CompareRow(r.experiment, r.quantity, levels[r.experiment], r.measured,
                            r.model, r.sigma, r.normalized) for r in fit.residuals)
    chi2 = float(sum(r.normalized ** 2 for r in rows))
    dof = fit.dof
    p = _ce.chi2_sf(chi2 + fit.chi2_prior, dof) if dof > 0 else math.nan
    per_exp: dict[str, float] = {}
    for r in rows:
        per_exp[r.experiment] = per_exp.get(r.experiment, 0.0) + r.normalized ** 2
    # structure against load (Fortran: beamid_estimation residual_structure)
    quantities = list(dict.fromkeys(r.quantity for r in rows))
    st = _ce.residual_structure(np.array([r.load for r in rows]),
                                np.array([quantities.index(r.quantity) for r in rows]),
                                np.array([r.normalized for r in rows]))
    tests = []
    if not math.isnan(st[0]):
        tests.append(StructureTest("runs test", float(st[2]), float(st[3]),
                                   f"{int(st[0])} runs of signs, {st[1]:.2f} expected"))
    else:
        tests.append(StructureTest("runs test", math.nan, math.nan,
                                   "all residuals have one sign" if rows else "no residuals"))
    if not math.isnan(st[4]):
        tests.append(StructureTest("trend against load", float(st[5]), float(st[6]),
                                   f"slope {st[4]:.3g} sigma per unit load"))
    systematic = (not math.isnan(p) and p < 0.01) or any(
        t.p_value < 0.01 for t in tests if not math.isnan(t.p_value))
    return Comparison(fit=fit, rows=rows, chi2=chi2, dof=dof, expected=float(dof),
                      expected_sigma=math.sqrt(2.0 * max(dof, 0)), p_value=p,
                      per_experiment=per_exp, tests=tuple(tests), systematic=systematic,
                      structure=tuple(float(v) for v in st))


# ------------------------------------------------------------------ diagnose

class _ByRankAndName:
    """Indexing shared by the ranked results of this module: by position
    (int or slice) and by effect name (str); iteration and ``len`` over the
    items; ``in`` by effect name. A subclass names its items (``_items``),
    what an int and a str select (``_keys``) and how a missing name is
    reported (``_missing``)."""

    _keys = ("rank", "effect name")

    def _items(self) -> tuple:
        raise NotImplementedError

    def _missing(self, key: str) -> str:
        raise NotImplementedError

    def __getitem__(self, key: int | slice | str):
        items = self._items()
        if isinstance(key, str):
            for item in items:
                if item.effect == key:
                    return item
            raise KeyError(self._missing(key))
        if isinstance(key, (int, np.integer, slice)) and not isinstance(key, bool):
            return items[key]
        raise TypeError(f"a {type(self).__name__} is indexed by {self._keys[0]} (int) or "
                        f"{self._keys[1]} (str), not {type(key).__name__}")

    def __iter__(self):
        return iter(self._items())

    def __len__(self) -> int:
        return len(self._items())

    def __contains__(self, effect: object) -> bool:
        return any(item.effect == effect for item in self._items())


@dataclass(frozen=True)
class Candidate:
    """One candidate effect in a :class:`Diagnosis`.

    ``chi2_drop``, ``p_value``, ``estimate`` and ``sigma`` are those of the
    refit (likelihood ratio) when one was made, else of the score test
    (first order); both are kept in the ``score_*``/``lr_*`` fields.
    """

    effect: str
    params: tuple[str, ...]
    state: str
    score_drop: float = math.nan
    score_p: float = math.nan
    first_order: dict[str, float] = field(default_factory=dict)
    first_order_sigma: dict[str, float] = field(default_factory=dict)
    physical: bool = True
    identifiable: bool = True
    refit: bool = False
    lr_drop: float = math.nan
    lr_p: float = math.nan
    refit_estimate: dict[str, float] = field(default_factory=dict)
    refit_sigma: dict[str, float] = field(default_factory=dict)
    refit_flags: dict[str, str] = field(default_factory=dict)
    refit_model: Model | None = None
    significant: bool = False
    acceptable: bool = False
    rival: bool = False
    separating: tuple[str, str, float] | None = None
    #: a refit was tried (``refit`` says whether one of its starts converged)
    refit_tried: bool = False
    #: the start the refit kept: "first-order estimate", "nominal model" or
    #: "continuation" (None: no refit, or none converged)
    refit_start: str | None = None
    #: what each refit start gave (why the refit failed, when it did)
    refit_note: str = ""
    #: "physics" or "measurement chain" (Effect.cause)
    cause: str = "physics"

    @property
    def refit_failed(self) -> bool:
        """A refit was tried and none of its starts converged."""
        return self.refit_tried and not self.refit

    @property
    def chi2_drop(self) -> float:
        return self.lr_drop if self.refit and not math.isnan(self.lr_drop) else self.score_drop

    @property
    def p_value(self) -> float:
        return self.lr_p if self.refit and not math.isnan(self.lr_p) else self.score_p

    @property
    def estimate(self) -> dict[str, float]:
        return self.refit_estimate if self.refit and self.refit_estimate else self.first_order

    @property
    def sigma(self) -> dict[str, float]:
        return self.refit_sigma if self.refit and self.refit_sigma else self.first_order_sigma


@dataclass(frozen=True)
class Diagnosis(_ByRankAndName):
    """Result of :func:`diagnose`: candidates ranked best first.

    Indexable by rank (``diagnosis[0]`` is the best candidate, slices give
    tuples) and by effect name (``diagnosis["material_cubic"]``); iterating
    gives the candidates in rank order; ``len`` is their number.
    """

    fit: FitResult
    candidates: tuple[Candidate, ...]
    verdict: Candidate | None
    rivals: tuple[Candidate, ...]
    alpha: float
    alpha_each: float
    message: str

    def _items(self) -> tuple[Candidate, ...]:
        return self.candidates

    def _missing(self, key: str) -> str:
        return (f"{key!r} is not a candidate of this diagnosis (candidates: "
                f"{', '.join(c.effect for c in self.candidates)})")

    def __repr__(self) -> str:
        best = self.verdict.effect if self.verdict is not None else "none"
        return (f"<{type(self).__name__} of {len(self.candidates)} candidates: verdict "
                f"{best}; print() shows the table>")

    def __str__(self) -> str:
        lines = [f"{'rank':<5}{'effect':<16}{'score drop':>11}{'score p':>10}{'refit drop':>11}"
                 f"{'refit p':>10}  estimate (sigma)"]
        for k, c in enumerate(self.candidates, start=1):
            if c.state != "tested":
                lines.append(f"{'-':<5}{c.effect:<16}  ({c.state})")
                continue
            est = ", ".join(f"{n} = {c.estimate.get(n, math.nan):.4g} "
                            f"({c.sigma.get(n, math.nan):.2g})" for n in c.params)
            notes = []
            if not c.physical:
                notes.append("nonphysical first-order estimate")
            if not c.identifiable:
                notes.append("not separable from the free parameters")
            if c.refit_failed:
                notes.append("refit failed: no start converged")
            if c.refit and c.refit_flags and any(map(flag_is_problem, c.refit_flags.values())):
                notes.append("; ".join(f"{n}: {v}" for n, v in c.refit_flags.items()
                                       if flag_is_problem(v)))
            lines.append(f"{k:<5}{c.effect:<16}{c.score_drop:>11.4g}{c.score_p:>10.2g}"
                         f"{(c.lr_drop if c.refit else math.nan):>11.4g}"
                         f"{(c.lr_p if c.refit else math.nan):>10.2g}  {est}"
                         + (f"  [{'; '.join(notes)}]" if notes else ""))
        lines.append(self.message)
        return "\n".join(lines)


def _candidate(raw: dict, c: int, eff: Effect, params: tuple[str, ...], model: Model,
               exp_names: list[str], cls: type | None = None, keep: np.ndarray | None = None,
               **extra: Any) -> Candidate:
    """Candidate ``c`` of a diagnosis from the Fortran result arrays, read by
    the column names the Fortran exports (static and dynamic diagnoses
    alike): ``cls`` the result type (default :class:`Candidate`), ``keep``
    the mask of the block's parameters tested (default all), ``extra`` the
    fields a subclass adds (not set on a candidate that was not tested)."""
    cls = cls or Candidate
    cst, pst, starts = raw["cstats"], raw["pstats"], raw["starts"]

    def s(name: str) -> float:   # this candidate's column, by its Fortran name
        return float(cst[name][c])

    def ps(name: str) -> np.ndarray:
        block = pst[name][starts[c]:starts[c + 1]]
        return block if keep is None else block[keep]

    state = _STATES[int(s("state"))]
    if state != "tested":
        return cls(eff.name, params, state, cause=eff.cause)
    if keep is not None:
        params = tuple(n for n, k in zip(params, keep) if k)
    refit = bool(s("refit_done")) and bool(s("refit_ok"))
    sep = None
    if s("rival") and s("sep_experiment") > 0:
        sep = (exp_names[int(s("sep_experiment")) - 1],
               _ce.QUANTITY_NAMES[int(s("sep_quantity"))], s("separation"))
    chain_values = raw.get("chain_values", {})
    null = {n: float(chain_values[n]) if n in chain_values else float(model[n]) for n in params}
    each = list(enumerate(params))
    return cls(
        effect=eff.name, params=params, state=state, score_drop=s("score_drop"),
        score_p=s("score_p"),
        first_order={n: null[n] + float(ps("estimate")[j]) for j, n in each},
        first_order_sigma={n: float(ps("sigma")[j]) for j, n in each},
        physical=bool(s("physical")), identifiable=bool(s("identifiable")), refit=refit,
        lr_drop=s("lr_drop") if refit else math.nan,
        lr_p=s("lr_p") if refit else math.nan,
        refit_estimate={n: float(ps("refit_value")[j]) for j, n in each} if refit else {},
        refit_sigma={n: float(ps("refit_sigma")[j]) for j, n in each} if refit else {},
        refit_flags={n: FLAG_TEXT.get(int(ps("refit_flag")[j]), "flagged")
                     for j, n in each} if refit else {},
        refit_model=Model(model.nbeams, raw["refit_params"][:, c]) if refit else None,
        significant=bool(s("significant")), acceptable=bool(s("acceptable")),
        rival=bool(s("rival")), separating=sep, refit_tried=bool(s("refit_done")),
        refit_start=raw["refit_start"][c], refit_note=_named(model, raw["notes"][c]),
        cause=eff.cause, **extra)


def _effect_request(fit: FitResult, effect: str | Effect, max_iter: int,
                    starts: Sequence[str] | str | None) -> tuple[Effect, tuple[str, ...], int]:
    """The checks of add_effect (static and dynamic alike): the effect, its
    parameters and the bit mask of the refit starts asked for (0: all)."""
    eff = _effect(effect)
    params = tuple(eff.params(fit.model))
    if not params:
        raise InputError(f"effect {eff.name!r} has no parameters in a "
                         f"{fit.model.nbeams}-beam model")
    already = [p for p in params if p in fit.free]
    if already:
        raise InputError(f"effect {eff.name!r}: {', '.join(already)} already free")
    _check.count("max_iter", max_iter, min=1)
    names = [n for k, n in sorted(_ce.START_NAMES.items()) if n]
    mask = 0
    for name in _check.names("starts", starts, none=True) or ():
        if name not in names:
            raise InputError(f"starts names {name!r}, expected some of {', '.join(names)}")
        mask |= 1 << names.index(name)
    if starts is not None and mask == 0:
        raise InputError(f"starts is empty: name some of {', '.join(names)}")
    return eff, params, mask


def diagnose(fit: FitResult, candidates: Sequence[str | Effect] | None = None, *,
             alpha: float = 0.01, nrefit: int = 3, ambiguity_delta: float = 4.0,
             collinear: float = 0.98, nominal: Model | None = None) -> Diagnosis:
    """Which switched-off effect would explain the residuals of ``fit``?

    For each candidate whose parameters are all at their null values and not
    free: a score (Lagrange-multiplier) test from the sensitivities at the
    null, with the free parameters projected out, gives the predicted
    chi-square drop, a first-order estimate with sigma and a p-value;
    effects with a sign (compliances, axial_coupling >= 0) are one-sided,
    and a candidate whose first-order estimate is nonphysical is not offered.
    The ``nrefit`` leading candidates are refitted (likelihood ratio). The
    verdict is the best refit significant at ``alpha`` / (number tested)
    whose parameters are determined; rivals explain the residuals about as
    well (drops within ``ambiguity_delta`` or |cosine| of their first-order
    residual changes above ``collinear``), and for each rival the
    measurement that would separate it from the verdict is named.

    Each refit starts from the first-order estimate (the free parameters
    moved along with it), from the nominal model (``nominal``, default the
    model the user started from, ``fit.nominal``) with the effect off, and
    by continuation in the effect's strength from its null value, and keeps
    the best that converges; a candidate none of whose starts converges is
    named in the message with the reason.
    """
    if not isinstance(fit, FitResult):
        raise InputError(f"diagnose needs a FitResult from beamid.fit, got {type(fit).__name__}")
    _check.real("alpha", alpha, above=0.0, below=1.0,
                expected="a significance level in (0, 1)")
    nrefit = _check.count("nrefit", nrefit, min=0)
    ambiguity_delta = _check.real("ambiguity_delta", ambiguity_delta, min=0.0)
    collinear = _check.real("collinear", collinear, min=0.0, max=1.0)
    user_fit, fit = fit, _chain.judged_fit(fit)   # the rows it judges (fitted, not gross errors)
    model = fit.model
    with_mesh, effects, names, blocks = _candidate_set(model, fit.experiments, candidates)
    rows = [e for e in effects if e.name in _chain.ROW_CANDIDATES]
    keep = [k for k, e in enumerate(effects) if e.name not in _chain.ROW_CANDIDATES]
    effects, names, blocks = ([x[k] for k in keep] for x in (effects, names, blocks))
    ext = _chain.diagnosis_extension(fit, effects, names, blocks)
    prob = build_problem(model, fit.experiments, fit.data, chain=ext.spec)
    free_idx = np.array([model.index(n) + 1 for n in fit.free], np.int32)
    free_idx = np.concatenate([free_idx, ext.free]).astype(np.int32)
    nominal = _nominal(fit, nominal)
    raw = _ce.problem_diagnose(prob, np.concatenate([model.vector(), ext.values]), free_idx,
                               _prior_arrays(model, fit.free, fit.prior)[1], blocks, alpha,
                               int(nrefit), ambiguity_delta, collinear,
                               np.concatenate([nominal.vector(), ext.values]), with_mesh)
    ext.trim(raw, model.vector().size)
    diag = _diagnosis(fit, raw, effects, names, alpha, with_mesh)
    if rows:
        diag = _with_row_candidates(diag, rows)
    return dataclasses.replace(diag, fit=user_fit) if user_fit is not fit else diag


def _with_row_candidates(diag: Diagnosis, rows: list[Effect]) -> Diagnosis:
    """The diagnosis with the measurement chain's row candidates
    (beamid.chain.row_candidates) ranked in: gross errors are the verdict
    when their refit drops the chi-square most; noise larger than stated
    when nothing else is significant and the residuals are white."""
    dynamic = _dynamic(diag.fit.experiments)
    cls = type(diag.candidates[0]) if diag.candidates else Candidate
    if dynamic:
        cls = _RELEASE_FAMILY["candidate"]
    extra = _chain_refit.row_candidates(diag.fit, rows, diag.alpha_each, cls)
    verdict = diag.verdict
    for c in extra:
        if c.effect == "gross_errors" and c.significant and (
                verdict is None or c.chi2_drop > verdict.chi2_drop):
            verdict = c
    noise = next((c for c in extra if c.effect == "noise"), None)
    white = False
    if noise is not None and noise.significant and verdict is None:
        cmp = compare(diag.fit)
        series = getattr(cmp, "series", ())
        level = diag.alpha / max(1, 3 * len(series))
        white = bool(series) and not any(s.p_min < level for s in series
                                         if not math.isnan(s.p_min))
        if white:
            verdict = noise
    ranked = list(diag.candidates)
    for c in extra:
        # gross errors by their chi-square drop; noise (chi2 - dof, no refit:
        # not comparable) after the tested candidates unless it is the verdict
        pos = next((k for k, r in enumerate(ranked) if r.state != "tested"
                    or (c.effect != "noise" and not (r.chi2_drop >= c.chi2_drop))),
                   len(ranked))
        ranked.insert(0 if c is verdict else pos, c)
    if verdict is diag.verdict:
        return dataclasses.replace(diag, candidates=tuple(ranked))
    message = _verdict_message(diag.fit, tuple(ranked), verdict, (), diag.alpha,
                               diag.alpha_each)
    if verdict is noise:
        f = noise.estimate["sigma factor"]
        message += (f"\n  white residuals with chi2/dof = {f * f:.3g}: the stated sigmas are "
                    f"too small by a factor {f:.3g}; fit with estimate_sigma=True")
    elif verdict is not None:
        message += ("\n  the refit with a Huber loss flags these rows as gross errors "
                    "(fit with loss='huber')")
    return dataclasses.replace(diag, candidates=tuple(ranked), verdict=verdict, rivals=(),
                               message=message)


def _candidate_set(model: Model, experiments, candidates):
    """(with_mesh, effects, their parameter names, their 1-based blocks) of
    the candidates asked for (default: the static ones, or with releases
    beamid.dyn_diagnosis.default_candidates); with releases ``mesh`` is the
    mesh test, not a block."""
    dynamic = _dynamic(experiments)
    if candidates is None and dynamic:
        candidates = _RELEASE_FAMILY["default_candidates"](experiments)
    if candidates is None and _modal_only(experiments):
        candidates = MODAL_CANDIDATES
    if isinstance(candidates, (str, Effect)):
        candidates = [candidates]
    elif candidates is not None:
        if isinstance(candidates, (bytes, Mapping)) or not hasattr(candidates, "__iter__"):
            _check.fail("candidates", candidates, "effect names or beamid.Effect objects")
        candidates = list(candidates)
    cands = list(STATIC_CANDIDATES if candidates is None else candidates)
    for c in cands:
        if not isinstance(c, (str, Effect)):
            _check.fail("candidates", candidates, f"effect names or beamid.Effect ("
                        f"{_check.show(c)} is neither)")
    if not cands:
        raise InputError("candidates is empty: name at least one effect")
    meshed = _meshed(experiments)
    mesh = [meshed and _effect(c).name == "mesh" for c in cands]
    effects = [_effect(c) for c, m in zip(cands, mesh) if not m]
    # the measurement chain's candidates are named and placed by
    # beamid.chain.diagnosis_extension (their parameters follow the model's)
    names = [e.params(model) if e.cause == "physics" else () for e in effects]
    return (any(mesh), effects, names,
            [np.array([model.index(n) + 1 for n in ns], np.int32) for ns in names])


def _diagnosis(fit: FitResult, raw: dict, effects: list[Effect], names: list[tuple[str, ...]],
               alpha: float, with_mesh: bool = False) -> Diagnosis:
    """The Diagnosis of a fit from the Fortran result arrays (with releases:
    beamid.dyn_diagnosis names the results, a DynDiagnosis)."""
    if _dynamic(fit.experiments) or with_mesh:   # with_mesh: releases or modal tests
        return _RELEASE_FAMILY["diagnosis"](fit, raw, effects, names, alpha, with_mesh)
    out = [_candidate(raw, c, eff, names[c], fit.model, list(fit.experiments))
           for c, eff in enumerate(effects)]
    ranked = tuple(out[i] for i in raw["ranking"])
    verdict = out[int(raw["dstats"]["verdict"]) - 1] if raw["dstats"]["verdict"] > 0 else None
    alpha_each = float(raw["dstats"]["alpha_each"])
    rivals = tuple(c for c in ranked if c.rival)
    message = _verdict_message(fit, ranked, verdict, rivals, alpha, alpha_each)
    return Diagnosis(fit=fit, candidates=ranked, verdict=verdict, rivals=rivals, alpha=alpha,
                     alpha_each=alpha_each, message=message)


def _undetermined(fit: FitResult) -> list[str]:
    """The line naming the fitted parameters the data do not determine (if any)."""
    flagged = [f"{n} ({f})" for n, f in fit.flags.items() if flag_is_problem(f)]
    return ["fitted parameters not determined by these data: " + ", ".join(flagged)
            ] if flagged else []


def _verdict_message(fit: FitResult, ranked, verdict, rivals, alpha, alpha_each,
                     notes: Sequence[str] = ()) -> str:
    """The verdict in words; ``notes`` (lines on the verdict's parameters)
    stand after the rivals, before what would separate them."""
    lines = _undetermined(fit)
    if verdict is None:
        p = _ce.chi2_sf(fit.chi2 + fit.chi2_prior, fit.dof) if fit.dof > 0 else math.nan
        tested = [c for c in ranked if c.state == "tested"]
        if not tested:
            lines.append("no candidate effect left to test (all are free or switched on)")
        failed = [c for c in ranked if c.refit_failed]
        if failed:
            # never "not explained by any known effect" while a candidate
            # could not be refitted: name it and say why
            for c in failed:
                lines.append(f"the refit of {c.effect} failed (score drop {c.score_drop:.4g}, "
                             f"p = {c.score_p:.2g}): {c.refit_note}")
            strong = [c for c in failed if c.score_p < alpha_each]
            consistent = ("the fit is consistent with the noise" if not (p < alpha) else
                          "the misfit is real")
            if strong:
                lines.append(f"no verdict: {', '.join(c.effect for c in strong)} "
                             f"{'is' if len(strong) == 1 else 'are'} significant by the "
                             f"first-order test but could not be confirmed by a refit "
                             f"(chi2/dof = {fit.chi2_per_dof:.3g}, p = {p:.3g}; {consistent})")
            else:
                lines.append(f"no verdict: no refit is significant at {alpha:g}, and the "
                             f"first-order tests of {', '.join(c.effect for c in failed)}, "
                             f"whose refit failed, are not significant either (chi2/dof = "
                             f"{fit.chi2_per_dof:.3g}, p = {p:.3g}; {consistent})")
            return "\n".join(lines)
        lines.append(f"residuals not explained by any known effect: no candidate is "
                     f"significant at {alpha:g} (chi2/dof = {fit.chi2_per_dof:.3g}, "
                     f"p = {p:.3g}" + ("; the fit is consistent with the noise)"
                                       if not (p < alpha) else
                                       "; the misfit is real but none of the candidates "
                                       "explains it)"))
        return "\n".join(lines)
    est = ", ".join(f"{n} = {verdict.estimate[n]:.5g} +- {verdict.sigma[n]:.2g}"
                    for n in verdict.params)
    what = ("measurement chain, not physics" if verdict.cause == "measurement chain"
            else "missing effect")
    lines.append(f"{what}: {verdict.effect} (chi-square drop {verdict.chi2_drop:.4g}, "
                 f"p = {verdict.p_value:.2g}; {est})")
    for c in ranked:
        if c.refit_failed and c.score_p < alpha_each:
            lines.append(f"  (the refit of {c.effect} failed, score drop {c.score_drop:.4g}: "
                         f"{c.refit_note})")
    if rivals:
        names = ", ".join(r.effect for r in rivals)
        lines.append(f"ambiguous: {verdict.effect} and {names} explain the residuals about "
                     f"as well (chi-square drops " + ", ".join(
                         f"{c.effect} {c.chi2_drop:.3g}" for c in (verdict, *rivals)) + ")")
    lines += notes
    for r in rivals:
        if r.separating:
            (e, q, k), t = r.separating, getattr(r, "separating_time", None)
            when = f" at t = {t:g} s" if t is not None else ""
            lines.append(f"  to separate {verdict.effect} from {r.effect}: measure {q}{when} in "
                         f"experiment {e} (their refits differ there by {k:.3g} sigma)")
    return "\n".join(lines)


# ------------------------------------------------------------- add / improve

def _nominal(fit: FitResult, nominal: Model | None) -> Model:
    """The model the refits also start from: ``nominal``, else the one the
    user started from (``fit.nominal``), with every parameter that is not
    free in ``fit`` at its fitted value."""
    base = nominal if nominal is not None else (fit.nominal or fit.start)
    if not isinstance(base, Model) or base.nbeams != fit.model.nbeams:
        raise InputError(f"nominal must be a beamid.Model with {fit.model.nbeams} beams, got "
                         f"{base!r}")
    return fit.model.with_params({n: base[n] for n in fit.free})


def add_effect(fit: FitResult, effect: str | Effect, *, max_iter: int = 50,
               nominal: Model | None = None,
               starts: Sequence[str] | None = None) -> FitResult:
    """Refit with the parameters of ``effect`` free as well.

    The refit starts where it can converge (Fortran ``refit_effect``): from
    the first-order (score-test) estimate of the effect with the free
    parameters moved along with it, from the nominal model (``nominal``,
    default ``fit.nominal``, the model the user started from) with the
    effect off, and by continuation in the effect's strength from its null
    value; the best that converges is kept (``result.refit_start`` says
    which, ``result.note`` what every start gave). A refit that runs away or
    stalls comes back flagged; :class:`beamid.ConvergenceError` only when no
    start converges at all (the message says why for each). ``starts``
    limits the starts tried (names as in ``refit_start``; default all). On
    fits with release experiments the effect ``mesh`` refits at twice the
    elements per beam (releases and modal tests alike).
    """
    _check.instance("fit", fit, FitResult, "a beamid.FitResult (beamid.fit)")
    if _meshed(fit.experiments) and _effect(effect).name == "mesh":
        # the same fit at twice the elements per beam
        refine_mesh = _RELEASE_FAMILY["refine_mesh"]
        return _fit(fit.model, refine_mesh(fit.experiments), fit.data, free=fit.free,
                    prior=fit.prior or None, max_iter=max_iter, starts=0, mesh=False)
    if _effect(effect).cause == "measurement chain":   # a refit with the chain's parameters
        return _chain_refit.add_chain_effect(fit, _effect(effect).name, max_iter=max_iter)
    fit = _chain.judged_fit(fit)    # the rows the fit judges: fitted, not gross errors
    eff, params, mask = _effect_request(fit, effect, max_iter, starts)
    model = fit.model
    nominal = _nominal(fit, nominal)
    prob = build_problem(model, fit.experiments, fit.data)
    free_idx = np.array([model.index(n) + 1 for n in fit.free], np.int32)
    block = np.array([model.index(n) + 1 for n in params], np.int32)
    prior_map, ptable = _prior_arrays(model, fit.free, fit.prior)
    try:
        raw = _ce.fit(prob, model.vector(), free_idx, ptable, max_iter=int(max_iter),
                      block=block, nominal=nominal.vector(), start_mask=mask)
    except ConvergenceError as exc:
        raise ConvergenceError(_named(model, f"add_effect({eff.name!r}): {exc}")) from None
    start = model.with_params(dict(zip(fit.free + params, raw["log_params"][:, 0])))
    return _result(start, fit.experiments, fit.data, fit.free + params, prior_map, raw,
                   nominal=nominal.with_params({n: float(raw["params"][model.index(n)])
                                                for n in params}))


class LadderStep(NamedTuple):
    """One rung of :func:`improve`: the effect added (None for the start)."""

    step: int
    effect: str | None
    chi2: float
    dof: int
    chi2_per_dof: float
    estimates: dict[str, float]
    sigmas: dict[str, float]
    fit: FitResult
    diagnosis: Diagnosis
    #: parameters the rung switched on (the effect's, or the members of its
    #: block the data determine)
    params: tuple[str, ...] = ()
    #: parameters an earlier rung switched on that this rung's fit no longer
    #: needs (set back to their null values: a rival member of the block)
    removed: tuple[str, ...] = ()
    #: the check that the rung's fit is at its best before the ladder goes
    #: on (with releases, a rung that ends far above its degrees of freedom
    #: is refitted from the nominal model with its effect as fitted; "" when
    #: not run; the table prints it when it ran)
    at_best: str = ""

    def __repr__(self) -> str:
        return (f"<LadderStep {self.step}: {self.effect or '(start)'}, chi2 {self.chi2:.5g} "
                f"for {self.dof} dof>")


@dataclass(frozen=True)
class Ladder(_ByRankAndName):
    """Result of :func:`improve`: its rungs, indexable by number (``ladder[0]``
    is the start) and by the effect a rung added (``ladder["drag"]``);
    iterating gives the rungs in order; ``len`` is their number."""

    steps: tuple[LadderStep, ...]

    @property
    def fit(self) -> FitResult:
        """The final fit."""
        return self.steps[-1].fit

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects added, rung by rung."""
        return tuple(s.effect for s in self.steps if s.effect)

    _keys = ("rung", "added effect")

    def _items(self) -> tuple[LadderStep, ...]:
        return self.steps

    def _missing(self, key: str) -> str:
        return f"{key!r} was not added by this ladder (added: {', '.join(self.effects) or 'none'})"

    def __repr__(self) -> str:
        return (f"<Ladder of {len(self.steps)} rungs: added {', '.join(self.effects) or 'none'}"
                f"; final chi2 {self.fit.chi2:.5g} for {self.fit.dof} dof; print() shows the "
                "table>")

    def __str__(self) -> str:
        lines = [f"{'step':<6}{'effect added':<18}{'chi2':>12}{'dof':>5}{'chi2/dof':>11}"
                 "  estimates (sigma)"]
        for s in self.steps:
            est = ", ".join(f"{n} = {v:.5g} ({s.sigmas[n]:.2g})" for n, v in s.estimates.items())
            lines.append(f"{s.step:<6}{(s.effect or '(start)'):<18}{s.chi2:>12.5g}{s.dof:>5}"
                         f"{s.chi2_per_dof:>11.4g}  {est}")
            if s.removed:
                lines.append(f"{'':<6}{'':<18}{', '.join(s.params)} instead of "
                             f"{', '.join(s.removed)} (no longer needed)")
            if s.at_best:     # the at-its-best check ran: what it found
                lines.append(f"{'':<6}{'':<18}{s.at_best}")
        lines.append(self.steps[-1].diagnosis.message)
        return "\n".join(lines)


def improve(model: Model, experiments: Experiments, data: Measurements,
            free: Sequence[str] = ("EI1", "EI2"),
            prior: Mapping[str, tuple[float, float]] | None = None, *,
            candidates: Sequence[str | Effect] | None = None, alpha: float = 0.01,
            max_steps: int | None = None, max_iter: int = 50) -> Ladder:
    """Fit, then repeat diagnose and add the verdict's effect until no
    candidate is significant (at most ``max_steps`` rungs, default one per
    candidate); return the ladder of fits.

    The ladder runs in Fortran (``beamid_ladder``, the one ``beamid-batch``
    runs for ``task = 'improve'``). With release experiments
    (:mod:`beamid.dyn_diagnosis`) it is stepwise in both directions: a block
    reduced to the members the data determine (drag at the elbow or at the
    tip) stays a candidate of the later rungs with its members still at
    null, and after every rung the parameters that earlier rungs switched on
    are tested again (one-sided Wald test at the rung's level alpha / number
    tested): one the new fit no longer needs, typically the rival member of
    a block picked while another effect was still missing, goes back to its
    null value and the rung is refitted without it (``LadderStep.removed``).
    A significant ``mesh`` candidate refines every release and modal test
    to the recommended elements per beam; the mesh is tested until found adequate.
    """
    if not isinstance(model, Model):
        raise InputError(f"model must be a beamid.Model, got {type(model).__name__}")
    _check.real("alpha", alpha, above=0.0, below=1.0,
                expected="a significance level in (0, 1)")
    max_iter = _check.count("max_iter", max_iter, min=1)
    max_steps = _check.count("max_steps", max_steps, min=0, none=True)
    _chain.check_sigma_given(data, None, "improve")
    with_mesh, effects, names, blocks = _candidate_set(model, experiments, candidates)
    limit = len(effects) + with_mesh if max_steps is None else max_steps
    free_names, free_idx = _free_indices(model, free)
    prior_map, ptable = _prior_arrays(model, free_names, prior)
    # the chain's row candidates join the ladder when named (beamid_ladder row_rung)
    named = {e.name for e in effects} if candidates is not None else set()
    ext = _chain_extension(model, _check_experiments(experiments), data, effects, names,
                           blocks)
    with _ce.ladder_start(build_problem(model, experiments, data, chain=ext.spec),
                          np.concatenate([model.vector(), ext.values]), free_idx,
                          ptable, blocks, with_mesh, alpha, limit, int(max_iter),
                          gross="gross_errors" in named, noise="noise" in named) as run:
        return _run_ladder(model, experiments, data, prior_map, candidates, alpha, limit,
                           run=run)


def _at_best(model: Model, note: str) -> str:
    """The ladder's at-its-best check in a rung's raw fit note (beamid_ladder
    rung_at_best), parameters named; "" when it did not run."""
    part = next((p for p in str(note).split("; ") if p.startswith("at its best")), "")
    return _named(model, part) if part else ""


def _chain_extension(model: Model, experiments: Experiments, data: Measurements,
                     effects: list[Effect], names: list, blocks: list, own=None):
    """The measurement chain's candidates of a ladder (beamid.chain.extension):
    their names and blocks filled in, the nuisance parameters returned (after
    the ladder's own, ``own``: a deck's &fit nuisance parameters). The
    row candidates (gross errors, noise) are diagnose's only: dropped here
    (in place)."""
    keep = [k for k, e in enumerate(effects) if e.name not in _chain.ROW_CANDIDATES]
    for x in (effects, names, blocks):
        x[:] = [x[k] for k in keep]
    return _chain.extension(model, dict(experiments), data, own, effects, names, blocks)


def _run_ladder(model: Model, experiments: Experiments, data: Measurements,
                prior_map: Mapping[str, tuple[float, float]],
                candidates: Sequence[str | Effect] | None, alpha: float,
                max_steps: int, desc: str = "improve", own=None, treatment=None,
                run: Any = None) -> Ladder:
    """Run the ladder of the handle ``run`` (``_ce.ladder_start``'s, or a
    deck's handle ``_ce.deck_task_start`` started it on) a rung per call,
    with a progress bar labelled ``desc`` on a terminal (none when
    max_steps = 0: a diagnosis alone, one call), and name its rungs."""
    with_mesh, effects, names, blocks = _candidate_set(model, experiments, candidates)
    ext = _chain_extension(model, experiments, data, effects, names, blocks, own)
    for _ in progress(itertools.count(), total=max_steps + 1, desc=desc,   # on a tty only
                      enabled=None if max_steps else False):
        if _ce.ladder_step(run):
            break
    npar = model.vector().size
    all_names = model.names() + tuple(ext.names)
    rows_now = treatment or _chain.RowTreatment()
    steps = []
    for k, r in enumerate(_ce.ladder_rungs(len(all_names), blocks, run)):
        if r["elements_per_beam"]:
            experiments = _RELEASE_FAMILY["refine_mesh"](experiments, r["elements_per_beam"])
        raw, phys, sub = _split_ladder_fit(r["fit"], r["free"], npar, ext.spec,
                                           list(experiments))
        fit = _result(Model(model.nbeams, r["start"][:npar]), experiments, data,
                      tuple(all_names[i] for i in phys), prior_map, raw,
                      nominal=Model(model.nbeams, r["nominal"][:npar]), chain=sub or None)
        fit = dataclasses.replace(fit, refit_start=r["refit_start"])
        if r["effect"] == "gross_errors":        # the ladder's row candidates (row_rung)
            rows_now = dataclasses.replace(rows_now, loss="huber")
        elif r["effect"] == "noise":
            rows_now = dataclasses.replace(rows_now, estimate=tuple(sorted(
                set(zip(data.experiment, data.quantity)))))
        if r["rows"] is not None:     # a loss, burn-in or estimated sigmas
            fit = _with_row_treatment(fit, rows_now, r["rows"])
        if ext.names:
            ext.trim(r["diag"], npar)
            r["diag"]["chain_values"] = dict(zip(ext.names, r["fit"]["params"][npar:]))
        diag = _diagnosis(fit, r["diag"], effects, names, alpha, with_mesh)
        effect = r["effect"]
        if effect is not None and effect.isdigit():   # a candidate's number (not a deck's name)
            effect = effects[int(effect) - 1].name
        steps.append(LadderStep(k, effect, fit.chi2, fit.dof, fit.chi2_per_dof,
                                dict(fit.estimates), dict(fit.sigmas), fit, diag,
                                tuple(all_names[i] for i in r["params"]),
                                tuple(all_names[i] for i in r["removed"]),
                                _at_best(model, r["fit"].get("note", ""))))
        if getattr(diag, "mesh", None) is not None:
            with_mesh = False    # the mesh is judged once (beamid_ladder)
    return Ladder(tuple(steps))
