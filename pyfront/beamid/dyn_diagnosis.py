"""Find the missing effect in time histories: compare, diagnose, add, improve
on fits with :class:`beamid.Release` experiments (alone or mixed with static
ones).

:func:`beamid.compare`, :func:`beamid.diagnose`, :func:`beamid.add_effect`
and :func:`beamid.improve` call into this module when the fit has a release
experiment, so the static workflow works unchanged on time histories.

The candidate effects of a release (names fixed): ``friction`` (mu_elbow,
mu_tip, Eq. 101-102), ``drag`` (c_elbow, c_tip), ``rotary_inertia``
(J_elbow, J_tip, Eq. 130-132), ``kelvin_voigt`` (eta), ``motor_lag``
(tau_motor), ``elbow_flex``, ``root_flex`` (all one-sided: null value 0,
physical values positive), and ``mesh``: the same fit at twice the elements
per beam. An effect whose sensitivity is zero on every data row (a motor lag
without a motor) is listed as "not seen by these experiments", not tested.
The candidates, their parameters, null values and bounds are the core's
effects table (Fortran ``beamid_effects``).

The statistics run in Fortran (``beamid_dyn_diagnosis``): score tests from
the forward sensitivities at the null values, refits, ranking, the probe
rows (every measurable quantity at every measured time) that separate
rivals, the mesh test and the tests for structure in time.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import _check, _core_estimation as _ce
from .errors import _write_all
from .estimation import FitResult, predict
from .loads import family
from .measurements import Measurements, quantity_unit
from .model import Model

# the static registry, verdict words and result types (diagnosis.py does not
# import this module: this module installs its functions there at the end)
from . import diagnosis as _dg
from .diagnosis import Candidate, Diagnosis, Effect
from . import chain as _chain

#: standardized residual beyond which compare flags a row (beamid_chain_fit GROSS_Z)
GROSS_Z = 3.5

__all__ = ["DYNAMIC_CANDIDATES", "is_dynamic", "diagnose_dynamic", "add_effect_dynamic",
           "improve_dynamic", "compare_dynamic", "refine_mesh", "MeshCandidate",
           "DynCandidate", "DynDiagnosis", "TimeSeries", "TimeComparison",
           "plot_time_comparison"]


# the candidate effects of a release (their parameters, null values, bounds
# and families) are the core's table (beamid_effects), registered with the
# static ones by beamid.diagnosis


def _with_chain(names: tuple[str, ...]) -> tuple[str, ...]:
    """The core's default candidates with the measurement chain's
    (beamid.chain) before the mesh, which is tried last."""
    chain = tuple(n for n, _ in _chain.CANDIDATE_EFFECTS if n not in _chain.OPT_IN_CANDIDATES)
    rest = tuple(n for n in names if n != "mesh")
    return rest + chain + (("mesh",) if "mesh" in names else ())


#: Candidate effects tried for release experiments, in order (the core's
#: table, with the measurement chain's candidates of beamid.chain).
DYNAMIC_CANDIDATES = _with_chain(_ce.default_effects("dynamic"))

#: has this set of experiments a release (time histories)?
is_dynamic = _dg._dynamic


def default_candidates(experiments: Any) -> tuple[str, ...]:
    """Dynamic candidates, and for mixed fits the static ones too."""
    static = any(not (f is not None and f.timed) for f in _dg._families(experiments))
    if not static:
        return DYNAMIC_CANDIDATES
    return tuple(dict.fromkeys(_dg.STATIC_CANDIDATES + DYNAMIC_CANDIDATES))


def refine_mesh(experiments: Any, elements_per_beam: int | None = None,
                factor: int = 2) -> dict:
    """The experiments with every release and modal test at
    ``elements_per_beam`` (default ``factor`` times its own)."""
    out = {}
    for name, x in dict(experiments).items():
        fam = family(x)
        if fam is not None and fam.meshed:
            # the core family's mesh key is the experiment's elements_per_beam
            n = int(elements_per_beam) if elements_per_beam else x.elements_per_beam * factor
            x = dataclasses.replace(x, elements_per_beam=n)
        out[name] = x
    return out


# ------------------------------------------------------------------ diagnose

@dataclass(frozen=True)
class DynCandidate(Candidate):
    """A :class:`beamid.Candidate` of a fit with time histories: the
    separating measurement of a rival also has its time (s)."""

    separating_time: float | None = None
    #: parameters of the effect the data do not need (the block does not fit
    #: significantly better than its best member) or do not determine
    #: (first-order estimate below 2 sigma): left at their null values
    left_at_null: tuple[str, ...] = ()
    #: of those, the ones the score tests find about as good alone as the
    #: member tested (these data hardly tell them apart: drag at the elbow
    #: or at the tip); improve tests them again at its later rungs
    ambiguous_with: tuple[str, ...] = ()


@dataclass(frozen=True)
class MeshCandidate(Candidate):
    """The ``mesh`` candidate: the fit at twice the elements per beam.

    ``chi2_drop`` is the drop of the refined refit, ``max_change`` the
    largest change of a prediction at the fitted values in sigma units (at
    ``max_change_at`` = (experiment, t, quantity)), ``recommended`` the
    elements per beam that bring the discretization error below 0.3 sigma
    (assuming the h^4 convergence of the cubic elements).
    """

    elements_per_beam: int = 0
    recommended: int = 0
    max_change: float = math.nan
    max_change_at: tuple[str, float, str] | None = None


@dataclass(frozen=True)
class DynDiagnosis(Diagnosis):
    """:class:`beamid.Diagnosis` of a fit with time histories; ``mesh`` is
    the mesh candidate (None when not asked), ``not_seen`` the effects the
    experiments cannot see."""

    mesh: MeshCandidate | None = None
    not_seen: tuple[str, ...] = ()


#: beamid.diagnose, add_effect and improve serve fits with releases too (one
#: implementation each; when the ``mesh`` candidate is significant it is the
#: verdict: refine the mesh before any physical effect is offered); the
#: names of this module stay for scripts that use them.
diagnose_dynamic, add_effect_dynamic, improve_dynamic = _dg.diagnose, _dg.add_effect, _dg.improve


def _dyn_diagnosis(fit: FitResult, raw: dict, effects: list[Effect],
                   names: list[tuple[str, ...]], alpha: float, with_mesh: bool) -> DynDiagnosis:
    """The DynDiagnosis of a fit with releases from the Fortran result arrays."""
    model = fit.model
    exp_names = list(fit.experiments)
    out: list[Candidate] = []
    for c, eff in enumerate(effects):
        block = slice(raw["starts"][c], raw["starts"][c + 1])
        keep = raw["kept"][block]
        # the block as tested; the rest at null (not needed or determined)
        values = raw.get("chain_values", {})
        left = tuple(n for n, k in zip(names[c], keep)
                     if not k and n not in fit.free and n not in values
                     and float(model[n]) == 0.0)
        alike = tuple(n for n, a in zip(names[c], raw["ambiguous"][block]) if a)
        sep_t = (float(raw["sep_t"][c]) if raw["cstats"]["rival"][c]
                 and raw["cstats"]["sep_experiment"][c] > 0 else None)
        out.append(_dg._candidate(raw, c, eff, names[c], model, exp_names, cls=DynCandidate,
                                  keep=keep, separating_time=sep_t, left_at_null=left,
                                  ambiguous_with=alike))
    ranked = [out[i] for i in raw["ranking"]]
    verdict = out[int(raw["dstats"]["verdict"]) - 1] if raw["dstats"]["verdict"] > 0 else None
    alpha_each = float(raw["dstats"]["alpha_each"])
    mesh = None
    m = raw["mstats"]
    if with_mesh:
        if m["done"]:
            row = int(m["max_row"]) - 1
            at = ((fit.data.experiment[row], float(fit.data.t[row]), fit.data.quantity[row])
                  if 0 <= row < len(fit.data) else None)
            drop, p, significant = float(m["drop"]), float(m["p_value"]), bool(m["significant"])
            mesh = MeshCandidate(
                "mesh", (), "tested", score_drop=drop, score_p=p, refit=bool(m["ok"]),
                refit_tried=True, lr_drop=drop, lr_p=p,
                refit_model=Model(model.nbeams, raw["mesh_params"]),
                significant=significant, acceptable=significant,
                elements_per_beam=int(m["elements_per_beam"]),
                recommended=int(m["recommended"]), max_change=float(m["max_change"]),
                max_change_at=at)
        else:
            mesh = MeshCandidate("mesh", (), "not in this model")
        if mesh.significant:
            ranked.insert(0, mesh)
            verdict = mesh
        else:
            k = sum(1 for c in ranked if c.state == "tested")
            ranked.insert(k, mesh)
    rivals = tuple(c for c in ranked if c.rival) if verdict is not mesh or mesh is None else ()
    not_seen = tuple(c.effect for c in ranked if c.state == _dg._STATES[4])
    message = _message(fit, tuple(ranked), verdict, rivals, alpha, alpha_each, mesh, not_seen)
    return DynDiagnosis(fit=fit, candidates=tuple(ranked), verdict=verdict, rivals=rivals,
                        alpha=alpha, alpha_each=alpha_each, message=message, mesh=mesh,
                        not_seen=not_seen)


def _message(fit, ranked, verdict, rivals, alpha, alpha_each, mesh, not_seen) -> str:
    lines = []
    if mesh is not None and mesh.significant:
        where = ""
        if mesh.max_change_at:
            e, t, q = mesh.max_change_at
            # a modal entry (freq[3], shape_n@1:0.4[2]) has no time
            when = "" if str(q).endswith("]") else f" at t = {t:g} s"
            where = f" ({q}{when} in experiment {e})"
        lines += _dg._undetermined(fit)
        lines.append(
            f"refine the mesh: at {2 * mesh.elements_per_beam} elements per beam instead of "
            f"{mesh.elements_per_beam} the chi-square drops by {mesh.chi2_drop:.4g} "
            f"(p = {mesh.p_value:.2g}) and a prediction moves by up to {mesh.max_change:.3g} "
            f"sigma{where}; use {mesh.recommended} elements per beam (discretization error "
            f"below 0.3 sigma) before any physical effect is offered")
    else:
        notes = []
        alike = getattr(verdict, "ambiguous_with", ()) if verdict is not None else ()
        if alike:
            notes.append(f"  ambiguous: {' or '.join(verdict.params + alike)} of "
                         f"{verdict.effect} (these data hardly tell them apart; "
                         f"{', '.join(verdict.params)} explains them a little better now, "
                         "and improve tests the others again once more effects are in)")
        rest = tuple(n for n in getattr(verdict, "left_at_null", ()) if n not in alike)
        if verdict is not None and rest:
            notes.append(f"  {', '.join(rest)} of {verdict.effect} left at "
                         "the null value: these data do not need or determine it")
        lines.append(_dg._verdict_message(fit, tuple(c for c in ranked if c is not mesh),
                                          verdict, rivals, alpha, alpha_each, notes))
        if mesh is not None and mesh.state == "tested":
            lines.append(f"mesh: twice the elements per beam ({2 * mesh.elements_per_beam}) do "
                         f"not fit significantly better (chi-square drop "
                         f"{mesh.chi2_drop:.3g}, p = {mesh.p_value:.2g}; predictions move by up "
                         f"to {mesh.max_change:.3g} sigma)")
    if not_seen:
        lines.append("not seen by these experiments (zero sensitivity on every row, not "
                     "tested): " + ", ".join(not_seen))
    return "\n".join(lines)


# ------------------------------------------------------------------- compare

@dataclass(frozen=True)
class TimeSeries:
    """One quantity of one release experiment over time after a fit."""

    experiment: str
    quantity: str
    unit: str
    t: np.ndarray
    measured: np.ndarray
    sigma: np.ndarray
    model: np.ndarray
    normalized: np.ndarray
    chi2: float
    expected: float            #: number of rows (the fit's dof share is not subtracted)
    runs: float
    expected_runs: float
    runs_p: float              #: one-sided: too few runs of signs
    autocorrelation: float     #: lag-1 autocorrelation of the normalized residuals
    autocorrelation_p: float   #: one-sided: neighbours alike
    amplitude_slope: float     #: trend of |normalized| with time (1/s)
    amplitude_p: float         #: two-sided
    #: rows whose standardized residual passes GROSS_Z (3.5): gross errors
    flagged: np.ndarray | None = None
    #: rows fitted (False: before the fit's burn-in, shown but not fitted)
    fitted: np.ndarray | None = None

    @property
    def p_min(self) -> float:
        ps = [p for p in (self.runs_p, self.autocorrelation_p, self.amplitude_p)
              if not math.isnan(p)]
        return min(ps) if ps else math.nan


@dataclass(frozen=True)
class TimeComparison:
    """Measured against model over time (:func:`beamid.compare` on a fit with
    release experiments): per release and quantity a :class:`TimeSeries`
    (indexable by ``(experiment, quantity)``), the static rows of a mixed fit
    as in the static compare, and the overall chi-square."""

    fit: FitResult
    series: tuple[TimeSeries, ...]
    static_rows: tuple
    chi2: float
    dof: int
    expected: float
    expected_sigma: float
    p_value: float
    systematic: bool

    def __getitem__(self, key) -> TimeSeries:
        if isinstance(key, tuple):
            for s in self.series:
                if (s.experiment, s.quantity) == tuple(key):
                    return s
            raise KeyError(f"no series {key!r}")
        return self.series[key]

    def __len__(self) -> int:
        return len(self.series)

    def __repr__(self) -> str:
        return (f"<TimeComparison of {len(self.series)} series: chi2 {self.chi2:.4g} for "
                f"{self.dof} dof, p = {self.p_value:.3g}; print() shows the table>")

    def __str__(self) -> str:
        lines = [f"{'experiment':<12}{'quantity':<13}{'rows':>5}{'chi2':>10}{'expected':>9}"
                 f"{'runs':>6}{'exp.':>7}{'runs p':>9}{'lag-1 r':>9}{'r p':>9}"
                 f"{'|r| slope':>10}{'slope p':>9}{'flagged':>8}"]
        flagged = []
        for s in self.series:
            nflag = int(np.sum(s.flagged)) if s.flagged is not None else 0
            lines.append(f"{s.experiment:<12}{s.quantity:<13}{len(s.t):>5}{s.chi2:>10.4g}"
                         f"{s.expected:>9.3g}{s.runs:>6.0f}{s.expected_runs:>7.2f}"
                         f"{s.runs_p:>9.2g}{s.autocorrelation:>9.3f}{s.autocorrelation_p:>9.2g}"
                         f"{s.amplitude_slope:>10.3g}{s.amplitude_p:>9.2g}{nflag:>8d}")
            if nflag:
                flagged += [f"{s.experiment} {s.quantity} t = {t:g} s ({z:+.3g} sigma)"
                            for t, z in zip(s.t[s.flagged], s.normalized[s.flagged])]
        if flagged:
            lines.append("gross errors (|normalized residual| > 3.5): " + "; ".join(flagged))
        if self.static_rows:
            lines.append(f"{len(self.static_rows)} static rows, chi2 "
                         f"{sum(r.normalized ** 2 for r in self.static_rows):.4g}")
        lines.append(f"chi2 = {self.chi2:.4g}, expected {self.expected:.4g} +- "
                     f"{self.expected_sigma:.3g} (dof {self.dof}), p = {self.p_value:.3g}")
        lines.append("systematic structure in time: the model misses something"
                     if self.systematic else
                     "no systematic structure: residuals look like noise")
        return "\n".join(lines)

    def plot(self, path=None, fig=None, title: str | None = None):
        """The figure of :func:`plot_time_comparison`; saved as PNG at ``path``."""
        path = _check.path("path", path, none=True)
        title = _check.text("title", title, empty=True, none=True)
        if fig is not None:
            from matplotlib.figure import Figure

            _check.instance("fig", fig, Figure, "None or a matplotlib Figure")
        fig = plot_time_comparison(self, fig=fig, title=title)
        if path is not None:
            kinds = fig.canvas.get_supported_filetypes()
            if path.suffix.lstrip(".").lower() not in kinds:
                _check.fail("path", path, "a file name ending in ." + ", .".join(kinds))
            _write_all([(path, lambda tmp: fig.savefig(tmp, dpi=110))])
        return fig


def compare_dynamic(fit: FitResult, alpha: float = 0.01) -> TimeComparison:
    """Per release experiment and quantity: measured with sigma against the
    model over time, normalized residuals, chi-square against its
    expectation, and the tests for structure in time (Fortran
    ``time_structure``): runs of signs, lag-1 autocorrelation, trend of the
    residual amplitude. ``systematic`` when the overall chi-square or a
    series' test is significant at ``alpha`` / (number of tests)."""
    series = []
    static_rows = []
    groups: dict[tuple[str, str], list] = {}
    timed = {e for e, x in fit.experiments.items() if (f := family(x)) is not None and f.timed}
    for r in fit.residuals:
        if r.experiment in timed:
            groups.setdefault((r.experiment, r.quantity), []).append(r)
        else:
            static_rows.append(r)
    fitted = fit.fitted_rows if fit.fitted_rows is not None else np.ones(len(fit.residuals),
                                                                           bool)
    index = {id(r): i for i, r in enumerate(fit.residuals)}
    for (e, q), rows in groups.items():
        rows = sorted(rows, key=lambda r: r.t)
        t = np.array([r.t for r in rows])
        z = np.array([r.normalized for r in rows])
        used = np.array([bool(fitted[index[id(r)]]) for r in rows])
        flag = used & (np.abs(z) > GROSS_Z)
        # the structure tests see the fitted rows that are not gross errors
        keep = used & ~flag if fit.loss != "linear" else used
        st = _ce.time_structure(t[keep], z[keep])
        series.append(TimeSeries(
            e, q, quantity_unit(q), t, np.array([r.measured for r in rows]),
            np.array([r.sigma for r in rows]), np.array([r.model for r in rows]), z,
            float(np.sum(z[keep] ** 2)), float(np.sum(keep)),
            *(float(v) for v in st[[0, 1, 3, 4, 6, 7, 9]]), flagged=flag, fitted=used))
    chi2 = (float(fit.chi2) if fit.weights is not None
            else float(sum(r.normalized ** 2 for r in fit.residuals)))
    dof = fit.dof
    p = _ce.chi2_sf(chi2 + fit.chi2_prior, dof) if dof > 0 else math.nan
    ntests = 1 + 3 * len(series)
    level = alpha / ntests
    systematic = (not math.isnan(p) and p < level) or any(
        s.p_min < level for s in series if not math.isnan(s.p_min))
    return TimeComparison(fit, tuple(series), tuple(static_rows), chi2, dof, float(dof),
                          math.sqrt(2.0 * max(dof, 0)), p, systematic)


#: markers per panel of a time comparison: a denser record is thinned
MAX_MARKERS = 150
#: points of the model's curve over a release
DENSE_POINTS = 400


def _dense_model(cmp: TimeComparison) -> dict:
    """The fitted model over each release on a dense time grid (the curve
    between the measurement times): {(experiment, quantity): (t, y)}; a
    series whose prediction fails keeps its values at the sample times."""
    out: dict = {}
    by_exp: dict[str, list] = {}
    for s in cmp.series:
        by_exp.setdefault(s.experiment, []).append(s)
    for e, series in by_exp.items():
        tmax = max(float(np.max(s.t)) for s in series)
        grid = np.union1d(np.linspace(0.0, tmax, DENSE_POINTS),
                          np.concatenate([s.t for s in series]))
        rows = [(e, t, s.quantity, 0.0, 1.0) for s in series for t in grid]
        try:
            pred, _ = predict(cmp.fit.model, {e: cmp.fit.experiments[e]},
                              Measurements.from_rows(rows, source="<dense>"))
        except Exception:   # noqa: BLE001 - the figure falls back to the samples
            continue
        for k, s in enumerate(series):
            out[(e, s.quantity)] = (grid, pred[k * grid.size:(k + 1) * grid.size])
    return out


def plot_time_comparison(cmp: TimeComparison, fig=None, title: str | None = None):
    """One column per (experiment, quantity): on top measured values with
    their error bars (every k-th of a record denser than MAX_MARKERS) and
    the model as a continuous curve over time (dense output between the
    measurement times; unit on the axis), below the normalized residuals
    with their +-1 error bars and the +-2 sigma band; the figure's title
    gives ``title`` (e.g. which fit) and the overall chi-square. Returns
    the figure."""
    title = _check.text("title", title, empty=True, none=True)
    import matplotlib.pyplot as plt


    n = max(len(cmp.series), 1)
    if fig is None:
        fig = plt.figure(figsize=(4.2 * n, 5.6))
    axes = fig.subplots(2, n, squeeze=False, sharex="col")
    dense = _dense_model(cmp)
    for k, s in enumerate(cmp.series):
        top, bottom = axes[0, k], axes[1, k]
        tm, ym = dense.get((s.experiment, s.quantity), (s.t, s.model))
        top.plot(tm, ym, "-", color="C0", label="model")
        # a dense record: every k-th sample, so that the model stays visible
        step = max(1, int(math.ceil(len(s.t) / MAX_MARKERS)))
        sl = slice(None, None, step)
        label = "measured +- sigma" + (f" (every {step}th)" if step > 1 else "")
        top.errorbar(s.t[sl], s.measured[sl], yerr=s.sigma[sl], fmt="o", ms=3, color="C1",
                     capsize=2, elinewidth=1.0, label=label)
        top.set_title(f"{s.experiment}: {s.quantity}")
        top.set_ylabel(f"{s.quantity} ({s.unit})")
        top.legend(fontsize=7)
        bottom.axhspan(-2.0, 2.0, color="0.9", label="+-2 sigma")
        bottom.axhline(0.0, color="0.5", lw=0.8, label="zero")
        # in sigma units the error bar is +-1: visible where sigma is not
        # beside the motion's amplitude
        bottom.errorbar(s.t[sl], s.normalized[sl], yerr=np.ones_like(s.normalized[sl]),
                        fmt="o-" if step == 1 else "o", ms=3, color="C3", capsize=2,
                        elinewidth=1.0, label="normalized residual +- 1 sigma")
        if s.flagged is not None and np.any(s.flagged):
            for ax, y in ((top, s.measured), (bottom, s.normalized)):
                ax.plot(s.t[s.flagged], y[s.flagged], "x", ms=9, mew=2, color="k",
                        label="gross error (|r| > 3.5)")
        if s.fitted is not None and not np.all(s.fitted):
            t_end = float(np.max(s.t[~s.fitted]))
            for ax in (top, bottom):
                ax.axvspan(float(np.min(s.t)), t_end, color="0.8", alpha=0.5,
                           label="burn-in (not fitted)")
        bottom.set_xlabel("t (s)")
        bottom.set_ylabel("(measured - model) / sigma")
        bottom.set_title(f"chi2 {s.chi2:.3g} / {s.expected:.0f}, lag-1 r {s.autocorrelation:.2f}",
                         fontsize=8)
        bottom.legend(fontsize=7)
    fig.suptitle((f"{title}: " if title else "")
                 + f"measured vs model: chi2 = {cmp.chi2:.4g}, dof {cmp.dof}"
                 + (f", chi2/dof = {cmp.chi2 / cmp.dof:.4g}" if cmp.dof > 0 else "")
                 + (" (systematic residuals)" if cmp.systematic else ""), fontsize=11)
    fig.tight_layout()
    return fig


# compare, diagnose, add_effect and improve in beamid.diagnosis call these on
# fits with releases
_dg.register_release_family(compare=compare_dynamic, diagnosis=_dyn_diagnosis,
                            default_candidates=default_candidates, refine_mesh=refine_mesh,
                            candidate=DynCandidate)
