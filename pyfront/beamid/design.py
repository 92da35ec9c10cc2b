"""Experiment advisor: which measurement would determine a parameter best?

For each candidate measurement (an experiment and a quantity with its
sigma) the advisor predicts the sigma a parameter would have after that
measurement is added to a fit's data: the Fisher information of the fit
(J^T W J of its weighted rows, Eq. 53-55, plus the a priori rows of
Eq. 142-145) plus the candidate's sensitivity row g over the free
parameters at the estimates, g g^T / sigma^2, inverted. With
``target=None`` the criterion is the D-criterion det(cov)^(1/(2n)) over all
free parameters (the geometric-mean sigma of the joint confidence
ellipsoid). The information algebra runs in Fortran (``beamid_design``);
the sensitivities are those the fit itself uses.

>>> import beamid
>>> truth = beamid.pace(axial_coupling=0.0)
>>> exps = {f"F{f:g}": beamid.TipForce(fy=f) for f in (3.0, 5.0, 6.5, 8.0)}
>>> data = beamid.simulate_measurements(truth, exps, ["y_tip"], sigma=1e-3)
>>> fit = beamid.fit(truth, exps, data)
>>> adv = beamid.design(fit, {"M2": beamid.TipMoment(2.0)}, ["tip_angle", "y_tip"],
...                     sigma={"tip_angle": 1e-3, "y_tip": 1e-3}, target="EI2")
>>> adv.ranking[0][0]
('M2', 'tip_angle')

The prediction is first order (linearized at the estimates); check a
choice by simulation: ``data.merge(beamid.simulate_measurements(...))`` and
``beamid.fit`` on the merged set (tests/test_design.py does).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np

from . import _core_estimation as _ce
from . import observations
from .consistency import _check_fit, _deck_fit, _output_prefix, _save_figure
from . import _check
from .errors import InputError, _write_text
from .estimation import FitResult, predict
from .fit_decks import read_fit_deck
from .loads import RadialWire, Release, TipForce, TipMoment
from .measurements import QUANTITIES, Measurements
from .plot_fit import parameter_unit
from .plotting import agg_pyplot


class RankedMeasurement(NamedTuple):
    """One entry of a ranking: ``((experiment, quantity), predicted)``."""

    key: tuple[str, str]
    predicted: float


class Ranking(list):
    """Candidate measurements best first. ``ranking[0]`` is the best entry;
    ``ranking["F12", "y_elbow"]`` (or ``ranking[("F12", "y_elbow")]``) the
    entry of that measurement; ``ranking.rank(key)`` its 0-based rank."""

    def __getitem__(self, item):  # type: ignore[override]
        if isinstance(item, tuple) and len(item) == 2 and all(isinstance(s, str) for s in item):
            for entry in self:
                if entry.key == item:
                    return entry
            raise KeyError(f"no candidate measurement {item!r}; candidates: "
                           + ", ".join(f"{e}/{q}" for (e, q), _ in self))
        return super().__getitem__(item)

    def rank(self, key: tuple[str, str]) -> int:
        """0-based rank of a candidate measurement."""
        if tuple(key) not in self.keys():
            raise KeyError(f"no candidate measurement {key!r}")
        return self.keys().index(tuple(key))

    def keys(self) -> list[tuple[str, str]]:
        return [e.key for e in self]


@dataclass(frozen=True)
class Advice:
    """Result of :func:`design`."""

    target: str | None           #: parameter name, or None for the D-criterion
    free: tuple[str, ...]
    current: float               #: the criterion with the fit's data only
    ranking: Ranking             #: ((experiment, quantity), predicted) best first
    sigma: dict[tuple[str, str], float]        #: sigma of every candidate row
    sensitivity: dict[tuple[str, str], np.ndarray]  #: d value / d free at the estimates
    loads: dict[str, Any]        #: the candidate experiments
    skipped: tuple[tuple[str, str, str], ...] = ()  #: (experiment, quantity, reason)

    @property
    def criterion(self) -> str:
        return (f"predicted sigma of {self.target}" if self.target else
                "D-criterion det(cov)^(1/(2n))")

    @property
    def criterion_label(self) -> str:
        """The criterion with its unit, for an axis."""
        if not self.target:
            return f"{self.criterion} (geometric mean of the sigmas, mixed units)"
        return f"{self.criterion} ({parameter_unit(self.target)})"

    def gain(self, key: tuple[str, str]) -> float:
        """current / predicted for a candidate (how many times smaller)."""
        if not isinstance(key, tuple) or tuple(key) not in self.ranking.keys():
            _check.fail("key", key, "an (experiment, quantity) of the ranking, e.g. "
                        f"{self.ranking.keys()[:1]}")
        return self.current / self.ranking[key].predicted

    def __str__(self) -> str:
        return self.table(20)

    def __repr__(self) -> str:
        best = f"{self.ranking[0].key[0]}/{self.ranking[0].key[1]}" if self.ranking else "none"
        return (f"<Advice: {self.criterion} now {self.current:.4g}, {len(self.ranking)} "
                f"candidate measurements, best {best}; print() shows the table>")

    def table(self, top: int | None = None) -> str:
        """The ranking as text (best first)."""
        top = _check.count("top", top, min=0, none=True)
        head = f"{'rank':<6}{'experiment':<14}{'quantity':<12}{'sigma':>10}{'predicted':>13}{'gain':>8}"
        lines = [f"{self.criterion}: now {self.current:.4g} "
                 f"(free: {', '.join(self.free)})", head, "-" * len(head)]
        for i, ((e, q), v) in enumerate(self.ranking[:top] if top else self.ranking):
            gain = self.current / v if v > 0 else math.inf
            lines.append(f"{i + 1:<6}{e:<14}{q:<12}{self.sigma[(e, q)]:>10.3g}{v:>13.4g}"
                         f"{gain:>8.2f}")
        if self.skipped:
            lines.append("skipped (not defined for that experiment): "
                         + ", ".join(f"{e}/{q}" for e, q, _ in self.skipped))
        return "\n".join(lines)

    def plot(self, path: str | os.PathLike | None = None, top: int = 15, ax: Any = None):
        """Horizontal bars of the predicted criterion of the best ``top``
        candidates, with the current value; writes a PNG when ``path`` is given."""
        path = _check.path("path", path, none=True)
        top = _check.count("top", top, min=1)
        _check.axes("ax", ax)
        plt = agg_pyplot(path is not None, force=False)
        entries = list(self.ranking[:top])[::-1]
        if ax is None:
            fig, ax = plt.subplots(figsize=(6.5, 0.32 * len(entries) + 1.4))
        else:
            fig = ax.figure
        ys = np.arange(len(entries))
        vals = np.array([v for _, v in entries])
        if math.isfinite(self.current):
            ax.hlines(ys, vals, self.current, color="tab:blue", alpha=0.4, lw=2.0)
        ax.plot(vals, ys, "o", color="tab:blue")
        for y, v in zip(ys, vals):
            ax.annotate(f"{v:.3g}", (v, y), textcoords="offset points", xytext=(-4, 5),
                        ha="right", fontsize=7)
        ax.set_yticks(range(len(entries)))
        ax.set_yticklabels([f"{e} / {q}" for (e, q), _ in entries], fontsize=8)
        if math.isfinite(self.current):
            ax.axvline(self.current, color="tab:red", ls="--", lw=1.0,
                       label=f"now {self.current:.3g}")
        ax.set_xscale("log")
        from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

        lo = float(np.nanmin(vals)) if vals.size else 1.0
        hi = max(float(np.nanmax(vals)) if vals.size else 1.0,
                 self.current if math.isfinite(self.current) else 0.0)
        if math.isfinite(lo) and math.isfinite(hi) and lo > 0:
            ax.set_xlim(lo / 1.6, hi * 1.3)
            # labelled ticks at 1, 2, 5 (or every digit) of each decade: a log
            # axis over less than a decade otherwise shows one label
            ticks = _log_ticks(lo / 1.6, hi * 1.3)
            ax.xaxis.set_major_locator(FixedLocator(ticks))
            ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
            ax.xaxis.set_minor_locator(NullLocator())
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel(self.criterion_label)
        ax.set_title("which measurement next (best at the top)", fontsize=9)
        ax.legend(fontsize=7)
        _save_figure(fig, path)
        return ax


def _log_ticks(lo: float, hi: float) -> list[float]:
    """Tick values of a log axis over [lo, hi]: 1, 2, 5 times the powers of
    ten inside, or every digit when that leaves fewer than three."""
    decades = range(math.floor(math.log10(lo)) - 1, math.ceil(math.log10(hi)) + 1)
    for mults in ((1, 2, 5), tuple(range(1, 10))):
        ticks = [m * 10.0 ** k for k in decades for m in mults]
        ticks = [float(f"{t:.6g}") for t in ticks if lo <= t <= hi]
        if len(ticks) >= 3:
            return ticks
    return ticks


def information(fit: FitResult) -> np.ndarray:
    """Fisher information of a fit over its free parameters: J^T W J of its
    data rows at the estimates plus 1/sigma^2 of every a priori row. Equals
    inv(fit.cov) when every parameter is determined."""
    _, jac = predict(fit.model, fit.experiments, fit.data, fit.free)
    a = jac / fit.data.sigma[:, None]
    info = a.T @ a
    for name, (_, s) in fit.prior.items():
        j = fit.free.index(name)
        info[j, j] += 1.0 / s ** 2
    return info


def _sigma_of(sigma: float | Mapping[str, float], q: str) -> float:
    if isinstance(sigma, Mapping):
        if q not in sigma:
            raise InputError(f"sigma has no entry for quantity {q!r} (given: "
                             f"{', '.join(sigma) or 'none'})")
        value = sigma[q]
    else:
        value = sigma
    try:
        s = float(value)
    except (TypeError, ValueError):
        raise InputError(f"sigma[{q!r}] = {value!r}, expected a number > 0") from None
    if not (math.isfinite(s) and s > 0.0):
        raise InputError(f"sigma[{q!r}] = {value!r}, expected a finite number > 0")
    return s


def time_label(quantity: str, t: float) -> str:
    """The quantity label of a release's candidate row at time t: 'w_tip@0.65'."""
    return f"{quantity}@{t:g}"


def _release_times(candidates: Mapping[str, Any], times) -> tuple[dict, dict]:
    """Split candidates into experiments and, for releases, their
    measurement times: ``(Release, times)`` or ``times=`` (one sequence for
    every release or ``{name: times}``)."""
    loads, rtimes = {}, {}
    for name, value in candidates.items():
        name = str(name)
        if isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], Release):
            value, ts = value
        elif isinstance(value, Release):
            ts = times.get(name) if isinstance(times, Mapping) else times
            if ts is None:
                raise InputError(f"candidate {name!r} is a release: give its measurement times "
                                 f"({name!r}: (release, times)) or times=")
        else:
            loads[name] = value
            continue
        ts = _check.reals(f"times of {name!r}", ts, scalar=True)
        if ts.size == 0 or not np.all(np.isfinite(ts) & (ts > 0.0)):
            raise InputError(f"candidate {name!r}: measurement times {ts.tolist()}, expected "
                             "finite times > 0 s (after the release)")
        loads[name], rtimes[name] = value, [float(t) for t in ts]
    return loads, rtimes


def _rows(experiments: dict, quantities, sigma, rtimes: Mapping[str, list] | None = None):
    """Candidate rows (experiment, quantity, sigma, t): one per release time."""
    rows = []
    for name in experiments:
        qs = quantities.get(name, ()) if isinstance(quantities, Mapping) else quantities
        for q in _check.names("quantities", qs):
            if q not in QUANTITIES:
                raise InputError(f"quantity {q!r}, expected one of {', '.join(QUANTITIES)}")
            for t in (rtimes or {}).get(name, [0.0]):
                rows.append((name, q, _sigma_of(sigma, q), t))
    if not rows:
        raise InputError("no candidate measurements: give candidates and quantities")
    return rows


def _sensitivities(fit: FitResult, exps: dict, rows):
    """Sensitivity of every candidate row (rows a load cannot produce, e.g. a
    wire force without a wire, are skipped with the reason). A release's row
    is labelled by its time (time_label)."""
    out, skipped = [], []
    by_exp: dict[str, list] = {}
    for e, q, s, t in rows:
        by_exp.setdefault(e, []).append((q, s, t))

    def label(e, q, t):
        return time_label(q, t) if isinstance(exps[e], Release) else q

    for e, items in by_exp.items():
        table = Measurements.from_rows([(e, t, q, 0.0, s) for q, s, t in items],
                                       source="<candidates>")
        try:
            _, jac = predict(fit.model, {e: exps[e]}, table, fit.free)
            out += [(e, label(e, q, t), s, jac[i]) for i, (q, s, t) in enumerate(items)]
            continue
        except InputError:
            pass
        for q, s, t in items:  # find the rows that cannot be predicted
            one = Measurements.from_rows([(e, t, q, 0.0, s)], source="<candidates>")
            try:
                _, jac = predict(fit.model, {e: exps[e]}, one, fit.free)
            except InputError as exc:
                skipped.append((e, label(e, q, t), str(exc).splitlines()[0]))
                continue
            out.append((e, label(e, q, t), s, jac[0]))
    return out, skipped


def design(fit: FitResult, candidates: Mapping[str, Any],
           quantities: Sequence[str] | Mapping[str, Sequence[str]] = ("y_tip",),
           sigma: float | Mapping[str, float] = 1e-3, target: str | None = "EI2", *,
           times: Sequence[float] | Mapping[str, Sequence[float]] | None = None) -> Advice:
    """Rank candidate measurements by the sigma of ``target`` they would leave.

    Parameters
    ----------
    fit:
        A :class:`beamid.FitResult`; its estimates are where the
        sensitivities are taken, its data and prior give the information now.
    candidates:
        ``{name: experiment}`` (static loads: ``TipForce``, ``TipMoment``,
        ``RadialWire``; releases ``beamid.Release`` with their measurement
        times, ``{name: (release, times)}`` or ``times=``). A name of one of
        the fit's own experiments adds quantities (or times) to that
        experiment (the load must be the same). A release's candidate rows
        are one per time, labelled ``"w_tip@0.65"`` (quantity at t = 0.65 s).
    quantities:
        Quantities measured in every candidate, or ``{name: [quantities]}``.
    sigma:
        One sigma, or ``{quantity: sigma}``.
    target:
        A free parameter, or ``None`` for the D-criterion over all free
        parameters.
    times:
        Measurement times (s) of the release candidates given without them:
        one sequence for all or ``{name: times}``.

    Returns an :class:`Advice`; ``advice.ranking`` lists
    ``((experiment, quantity), predicted)`` best first and is indexable by
    rank and by ``(experiment, quantity)``.
    """
    _check_fit(fit)
    if not isinstance(candidates, Mapping) or not candidates:
        raise InputError("candidates must be a non-empty dict {name: experiment}, e.g. "
                         "{'M2': beamid.TipMoment(2.0)}")
    exps = dict(fit.experiments)
    loads, rtimes = _release_times(candidates, times)
    for name, load in loads.items():
        if name in exps and exps[name] != load:
            raise InputError(f"candidate {name!r} = {load!r} differs from the fit's "
                             f"experiment of that name ({exps[name]!r}); rename it")
        exps[name] = load
    if _check.text("target", target, none=True) is None:
        tindex = 0
    else:
        if target not in fit.free:
            raise InputError(f"target = {target!r} is not a free parameter of the fit "
                             f"(free: {', '.join(fit.free)}); None ranks by the D-criterion")
        tindex = fit.free.index(target) + 1
    rows = _rows(loads, quantities, sigma, rtimes)
    evaluated, skipped = _sensitivities(fit, exps, rows)
    if not evaluated:
        raise InputError("no candidate measurement can be predicted: "
                         + "; ".join(f"{e}/{q}: {why}" for e, q, why in skipped))
    g = np.array([r[3] for r in evaluated], float).T.reshape(len(fit.free), len(evaluated))
    sig = np.array([r[2] for r in evaluated], float)
    base, crit, order = _ce.rank_candidates(information(fit), g, sig, tindex)
    ranking = Ranking(RankedMeasurement((evaluated[i][0], evaluated[i][1]), float(crit[i]))
                      for i in order)
    return Advice(target=target, free=tuple(fit.free), current=base, ranking=ranking,
                  sigma={(e, q): s for e, q, s, _ in evaluated},
                  sensitivity={(e, q): np.array(j) for e, q, _, j in evaluated},
                  loads=loads, skipped=tuple(skipped))


def predicted_covariance(fit: FitResult, rows: Sequence[tuple[Sequence[float], float]] = ()
                         ) -> tuple[np.ndarray, np.ndarray]:
    """(cov, sigmas) predicted after adding measurement rows ``(g, sigma)``
    (sensitivity over ``fit.free`` and sigma) to the fit's information."""
    info = information(fit)
    rows = list(rows)
    if rows:
        g = np.array([np.asarray(r[0], float) for r in rows]).T.reshape(len(fit.free), len(rows))
        sig = np.array([float(r[1]) for r in rows])
        if not np.all(np.isfinite(sig) & (sig > 0)):
            raise InputError(f"predicted_covariance: sigmas {sig.tolist()}, expected > 0")
        info = _ce.information_update(info, g, sig)
    cov, sig, _, _ = _ce.information_covariance(info)
    return cov, sig


#: Quantities the command ranks by default: the static probe kinds of the
#: core's observation table (beamid.observations), those an experiment needs
#: nothing for first (x_tip y_tip tip_angle x_elbow y_elbow, then wire_force;
#: u_tip, w_tip are their twins).
DEFAULT_QUANTITIES = tuple(sorted(observations.probe_kinds("static"),
                                  key=lambda q: observations.kinds()[q].needs != "none"))


#: sigma of a candidate quantity the deck has no rows of (``beamid design``
#: without ``--sigma``): 1 mm, 1 mrad, 0.1 N, 0.01 N m (the measurement
#: sigmas of the dissertation's tests, docs/deviations.md); printed when used
DEFAULT_SIGMA = {"x_tip": 1e-3, "y_tip": 1e-3, "x_elbow": 1e-3, "y_elbow": 1e-3,
                 "u_tip": 1e-3, "w_tip": 1e-3, "tip_angle": 1e-3, "wire_force": 0.1,
                 "motor_torque": 0.01}
_UNIT = {"tip_angle": "rad", "wire_force": "N", "motor_torque": "N m"}


def parse_sigma(items: Sequence[str] | None, quantities: Sequence[str], data: Measurements,
                notes: list[str] | None = None) -> dict[str, float]:
    """Sigmas of the command line: ``1e-3`` (every quantity) or
    ``QUANTITY=SIGMA`` items; a quantity without one takes the median sigma of
    the deck's rows of that quantity, else :data:`DEFAULT_SIGMA` (said in
    ``notes`` when a list is given). Errors name ``--sigma``."""
    out: dict[str, float] = {}
    default = None
    for item in items or ():
        q, eq, v = (str(item).partition("=")[0].strip(), "=" in str(item),
                    str(item).partition("=")[2].strip())
        if eq:
            if q not in QUANTITIES:
                raise InputError(f"--sigma {item}: unknown quantity {q!r}, expected one of "
                                 f"{', '.join(QUANTITIES)}")
        else:
            v = str(item)
        try:
            value = float(v)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0.0):
            raise InputError(f"--sigma {item}: {v!r} is not a sigma, expected a finite number "
                             "> 0 (QUANTITY=SIGMA or one SIGMA for all)")
        if eq:
            out[q] = value
        else:
            default = value
    for q in (q for q in quantities if q not in out):
        if default is not None:
            out[q] = default
            continue
        own = [s for s, qq in zip(data.sigma, data.quantity) if qq == q]
        if own:
            out[q] = float(np.median(own))
            continue
        out[q] = DEFAULT_SIGMA[q]
        if notes is not None:
            notes.append(f"sigma of {q}: {DEFAULT_SIGMA[q]:g} {_UNIT.get(q, 'm')} (default: the "
                         f"deck has no {q} rows; set it with --sigma {q}=VALUE)")
    return out


def run_design_deck(deck: str | os.PathLike, forces: Sequence[float] = (),
                    moments: Sequence[float] = (), wires: Sequence[float] = (),
                    quantities: Sequence[str] | None = None,
                    sigma: Sequence[str] | None = None, target: str | None = None,
                    out: str | os.PathLike | None = None, top: int = 20, plots: bool = True,
                    times: Sequence[float] = ()) -> tuple[str, list[Path], Advice]:
    """``beamid design DECK``: fit an estimation deck and rank candidate
    measurements: transverse tip forces ``F<f>`` (fy = f), tip moments
    ``M<m>`` and radial wires ``Lw<length>`` (the deck's own experiments when
    none is given), each measuring ``quantities``. Writes
    ``<prefix>_design.csv`` (rank, experiment, quantity, sigma, predicted)
    and ``_design.png``. A deck's release experiments are candidates at the
    measurement ``times`` (s; ``--times``), one row per time, measuring by
    default the quantities of the deck's own rows. Returns (text, files,
    advice)."""
    # the command line's errors first, in its words (before the deck's fit runs)
    d = read_fit_deck(deck)
    if target is not None and target not in d.free:
        raise InputError(f"--target {target}: not a free parameter of {deck} (free: "
                         f"{', '.join(d.free)}); leave --target out to rank by the "
                         "D-criterion over all free parameters")
    for q in quantities or ():
        if q not in QUANTITIES:
            raise InputError(f"--quantities {q}: unknown quantity, expected one of "
                             f"{', '.join(QUANTITIES)}")
    for flag, vals, low in (("--force", forces, -math.inf), ("--moment", moments, -math.inf),
                            ("--wire", wires, 0.0), ("--times", times, 0.0)):
        for v in vals:
            if not (math.isfinite(float(v)) and float(v) > low):
                raise InputError(f"--{flag.lstrip('-')} {v:g}: expected a finite number"
                                 + (" > 0" if low == 0.0 else ""))
    if not isinstance(top, int) or top < 1:
        raise InputError(f"--top {top}: expected a count >= 1")
    notes: list[str] = []
    parse_sigma(sigma, list(quantities or ()), d.data, None)    # its errors, before the fit
    d, base = _deck_fit(deck)
    cands: dict[str, Any] = {}
    for f in forces:
        cands[f"F{float(f):g}"] = TipForce(fy=float(f))
    for m in moments:
        cands[f"M{float(m):g}"] = TipMoment(float(m))
    for w in wires:
        cands[f"Lw{float(w):g}"] = RadialWire(float(w))
    for name in list(cands):
        if name in base.experiments and base.experiments[name] != cands[name]:
            cands[f"{name}_new"] = cands.pop(name)
    if not cands:
        cands = dict(base.experiments)
    releases = [n for n, x in cands.items() if isinstance(x, Release)]
    if releases and not times:
        # the deck's own measurement times of its releases (printed)
        tables = [d.data, *(st.data for st in d.stages)]    # identify decks: every stage's
        times = sorted({float(t) for m in tables for e, t in zip(m.experiment, m.t)
                        if e in releases and t > 0.0})
        if not times:
            raise InputError(f"{deck}: the release experiment {releases[0]!r} is a candidate "
                             "at measurement times: give --times T [T ...] (s after the "
                             "release)")
        notes.append("measurement times: " + " ".join(f"{t:g}" for t in times) + " s (the "
                     "deck's own; set them with --times)")
    if quantities:
        qs = tuple(quantities)
    elif releases:
        qs = tuple(dict.fromkeys(d.data.quantity))    # the deck's own quantities
    else:
        qs = DEFAULT_QUANTITIES
    sig = parse_sigma(sigma, qs, d.data, notes)
    adv = design(base, cands, qs, sigma=sig, target=target,
                 times=[float(t) for t in times] if releases else None)
    prefix = _output_prefix(deck, out, d.output_prefix)
    lines = ["rank,experiment,quantity,sigma,predicted"]
    lines += [f"{i + 1},{e},{q},{adv.sigma[(e, q)]:.17g},{v:.17g}"
              for i, ((e, q), v) in enumerate(adv.ranking)]
    files = _write_text(Path(f"{prefix}_design.csv"), f"# beamid design: {adv.criterion}, "
                        f"now {adv.current:.17g}\n" + "\n".join(lines) + "\n")
    if plots:
        png = Path(f"{prefix}_design.png")
        adv.plot(png, top=min(top, 15))
        files.append(png)
    text = f"{base.summary()}\n\n" + "".join(n + "\n" for n in notes) + adv.table(top)
    return text, files, adv
