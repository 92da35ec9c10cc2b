"""Decks for the estimation tasks fit, compare, diagnose and improve
(format: docs/decks.md, section "Estimation decks").

>>> # &beamid task = 'improve', output = 'out/demo', preset = 'pace' /
>>> # &model axial_coupling = 0.0 /
>>> # &experiment name = 'F2', kind = 'tip', fy = 2.0 /      (one group per experiment)
>>> # &fit data = 'demo.csv', free = 'EI1', 'EI2' /

The outputs are CSV files next to the deck: ``<output>_estimates.csv``
(name, estimate, sigma, flag), ``<output>_covariance.csv``,
``<output>_residuals.csv``, ``<output>_ranking.csv`` (diagnose, improve) and
``<output>_ladder.csv`` (improve), plus PNG figures for compare and improve.
``beamid-batch DECK`` reads the same decks with the same checks and writes
the same CSV files (same names, columns and numbers; no figures), so a check
added here belongs in ``fortran/beamid_deck.f90`` too.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import f90nml

from . import _core
from .decks import _PER_BEAM, _PER_POINT, _as_list, _number, _point_name, parse_published
from .diagnosis import EFFECTS, Diagnosis, Ladder, compare, diagnose, improve
from .errors import InputError
from .estimation import FitResult, build_problem, fit
from .loads import RadialWire, TipLoad
from .measurements import Measurements, read_measurements
from .model import Model

FIT_TASKS = ("fit", "compare", "diagnose", "improve")
GROUPS = {
    "beamid": {"task", "output", "preset", "nbeams"},
    "model": {"l", "ei", "ea", "rho", "c", "m", "j", "mu", "c_drag", "joint_flex",
              "axial_coupling", "root_flex", "eta", "r_motor", "tau_motor", "m_elbow",
              "j_elbow", "mu_elbow", "c_elbow", "elbow_flex", "m_tip", "j_tip", "mu_tip",
              "c_tip"},
    "experiment": {"name", "kind", "fx", "fy", "moment", "wire_length"},
    "fit": {"data", "free", "prior_names", "prior_means", "prior_sigmas", "candidates",
            "alpha", "max_iter"},
    "published": {"table", "row", "quantity", "value", "digits", "deviation", "note"},
}


@dataclass(frozen=True)
class FitDeck:
    """A parsed estimation deck."""

    path: Path
    task: str
    output: str
    model: Model
    experiments: dict[str, TipLoad | RadialWire]
    data: Measurements
    free: tuple[str, ...]
    prior: dict[str, tuple[float, float]] = field(default_factory=dict)
    candidates: tuple[str, ...] | None = None
    alpha: float = 0.01
    max_iter: int = 50
    published: tuple = ()     #: &published groups (beamid.decks.Published)

    @property
    def output_prefix(self) -> Path:
        out = Path(self.output)
        return out if out.is_absolute() else self.path.parent / out


def read_fit_deck(path: str | os.PathLike) -> FitDeck:
    """Read and validate an estimation deck; InputError names file and field."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"cannot open {path}: no such file")
    try:
        nml = f90nml.Parser().read(str(path))
    except Exception as exc:
        raise InputError(f"{path}: not a valid namelist deck: {exc}") from None
    groups: dict[str, list] = {}
    for name, group in nml.items():
        if name not in GROUPS:
            raise InputError(f"{path}: unknown group &{name} in an estimation deck, "
                             f"expected one of: {' '.join(GROUPS)}")
        items = group if isinstance(group, list) else [group]
        for item in items:
            for var in item:
                if var not in GROUPS[name]:
                    raise InputError(f"{path}: in &{name}: unknown variable {var!r} (known: "
                                     f"{', '.join(sorted(GROUPS[name]))})")
        groups.setdefault(name, []).extend(items)
    for name in ("beamid", "model", "fit"):
        if len(groups.get(name, [])) > 1:
            raise InputError(f"{path}: group &{name} appears {len(groups[name])} times")
    head = groups.get("beamid", [None])[0]
    if head is None:
        raise InputError(f"{path}: group &beamid is missing")
    task = str(head.get("task", ""))
    if task not in FIT_TASKS:
        raise InputError(f"{path}: &beamid task = {task!r}, expected one of {FIT_TASKS}")
    output = head.get("output")
    if not output:
        raise InputError(f"{path}: &beamid output is missing: give the output path prefix")
    preset = str(head.get("preset") or "pace")
    nbeams, base = _core.preset(preset)
    if head.get("nbeams") not in (None, 0, nbeams):
        raise InputError(f'{path}: &beamid nbeams = {head["nbeams"]} but preset "{preset}" has '
                         f"{nbeams} beams")
    values = {n: float(v) for n, v in zip(_core.param_names(nbeams), base)}
    by_lower = {n.lower(): n for n in values}
    model_items = list((groups.get("model", [{}])[0] or {}).items())
    # arrays first: a named scalar (m_elbow, J_tip, ...) overrides the array entry
    model_items.sort(key=lambda item: not (item[0] in _PER_BEAM or item[0] in _PER_POINT
                                            or item[0] == "joint_flex"))
    for var, value in model_items:
        if var in _PER_BEAM or var in _PER_POINT or var == "joint_flex":
            for k, entry in enumerate(_as_list(value), start=1):
                if entry is None:
                    continue
                if var in _PER_BEAM:
                    pname = _PER_BEAM[var].format(k)
                elif var in _PER_POINT:
                    pname = _PER_POINT[var].format(_point_name(nbeams, k))
                else:
                    pname = f"{_point_name(nbeams, k)}_flex"
                if pname not in values:
                    raise InputError(f"{path}: in &model: {var}({k}) is beyond the "
                                     f"{nbeams}-beam chain")
                values[pname] = _number(path, "model", f"{var}({k})", entry)
        elif var in by_lower:
            values[by_lower[var]] = _number(path, "model", var, value)
        else:
            raise InputError(f"{path}: &model sets an elbow parameter but the chain has one "
                             "beam")
    try:
        model = Model(nbeams, [values[n] for n in _core.param_names(nbeams)])
    except InputError as exc:
        raise InputError(f"{path}: &model: {exc}") from None

    experiments: dict[str, TipLoad | RadialWire] = {}
    for k, item in enumerate(groups.get("experiment", []), start=1):
        name = str(item.get("name") or "")
        if not name:
            raise InputError(f"{path}: &experiment number {k} has no name")
        if name in experiments:
            raise InputError(f"{path}: &experiment name = {name!r} defined twice")
        kind = str(item.get("kind", ""))
        nums = {v: _number(path, "experiment", v, item[v])
                for v in ("fx", "fy", "moment", "wire_length") if v in item}
        if kind == "tip":
            if "wire_length" in nums:
                raise InputError(f"{path}: &experiment {name!r}: kind = 'tip' does not take "
                                 "wire_length")
            experiments[name] = TipLoad(nums.get("fx", 0.0), nums.get("fy", 0.0),
                                        nums.get("moment", 0.0))
        elif kind == "wire":
            if "wire_length" not in nums:
                raise InputError(f"{path}: &experiment {name!r}: kind = 'wire' needs "
                                 "wire_length (m)")
            if any(nums.get(v, 0.0) != 0.0 for v in ("fx", "fy", "moment")):
                raise InputError(f"{path}: &experiment {name!r}: kind = 'wire' does not take "
                                 "fx, fy or moment")
            experiments[name] = RadialWire(nums["wire_length"])
        else:
            raise InputError(f"{path}: &experiment {name!r}: kind = {kind!r}, expected 'tip' "
                             "or 'wire'")
    if not experiments:
        raise InputError(f"{path}: no &experiment groups: define at least one experiment")

    fg = groups.get("fit", [None])[0]
    if fg is None:
        raise InputError(f"{path}: group &fit is missing")
    if not fg.get("data"):
        raise InputError(f"{path}: &fit data is missing: give the measurement CSV file")
    data_path = Path(str(fg["data"]))
    if not data_path.is_absolute():
        data_path = path.parent / data_path
    data = read_measurements(data_path, experiments)
    build_problem(model, experiments, data)  # static rows: t = 0, wire_force needs a wire
    free_given = tuple(str(f) for f in _as_list(fg.get("free")) if f)
    free: tuple[str, ...] = ()
    for f in free_given:
        try:
            canonical = model.names()[model.index(f)]
        except InputError:
            raise InputError(f"{path}: &fit free = {f!r} is not a parameter name") from None
        if canonical in free:
            raise InputError(f"{path}: &fit free names parameter {canonical!r} twice")
        free += (canonical,)
    if not free:
        raise InputError(f"{path}: &fit free is missing: name the parameters to estimate")
    pn = [str(p) for p in _as_list(fg.get("prior_names")) if p]
    pm = _as_list(fg.get("prior_means"))
    ps = _as_list(fg.get("prior_sigmas"))
    if not (len(pn) == len(pm) == len(ps)):
        raise InputError(f"{path}: &fit prior_names, prior_means and prior_sigmas must have "
                         f"equal lengths (got {len(pn)}, {len(pm)}, {len(ps)})")
    prior = {}
    for i, (n, m, s) in enumerate(zip(pn, pm, ps)):
        m = _number(path, "fit", f"prior_means({i + 1})", m)
        s = _number(path, "fit", f"prior_sigmas({i + 1})", s)
        try:
            canonical = model.names()[model.index(n)]
        except InputError:
            raise InputError(f"{path}: &fit prior_names = {n!r} is not a parameter "
                             "name") from None
        if canonical not in free:
            raise InputError(f"{path}: &fit prior_names = {n!r} is not free (free: "
                             f"{', '.join(free)})")
        if not (math.isfinite(m) and math.isfinite(s) and s > 0.0):
            raise InputError(f"{path}: &fit prior for {n!r} = ({m:g}, {s:g}), expected a "
                             "finite mean and sigma > 0")
        prior[n] = (m, s)
    cands = tuple(str(c) for c in _as_list(fg.get("candidates")) if c) or None
    for c in cands or ():
        if c not in EFFECTS:
            raise InputError(f"{path}: &fit candidates = {c!r} is not a known effect, "
                             f"expected one of: {', '.join(EFFECTS)}")
    alpha = _number(path, "fit", "alpha", fg.get("alpha", 0.01))
    if not 0.0 < alpha < 1.0:
        raise InputError(f"{path}: &fit alpha = {alpha:g}, expected a significance level in "
                         "(0, 1)")
    max_iter = fg.get("max_iter", 50)
    if isinstance(max_iter, bool) or not isinstance(max_iter, int):
        raise InputError(f"{path}: in &fit: max_iter = {max_iter!r}, expected an integer")
    if max_iter < 1:
        raise InputError(f"{path}: &fit max_iter = {max_iter}, expected at least 1")
    published = parse_published(path, [g for g in groups.get("published", [])])
    return FitDeck(path=path, task=task, output=str(output), model=model,
                   experiments=experiments, data=data, free=free, prior=prior,
                   candidates=cands, alpha=alpha, max_iter=max_iter, published=published)


def _write(path: Path, lines: list[str]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def _e(x: float) -> str:
    return f"{x:.16E}" if math.isfinite(x) else ("Infinity" if x > 0 else
                                                ("NaN" if math.isnan(x) else "-Infinity"))


def _fit_lines(result: FitResult) -> list[list[str]]:
    """Lines of the estimates, covariance and residual files."""
    est = [f"{'name'},estimate,sigma,flag"] + [
        f"{n},{_e(result.estimates[n])},{_e(result.sigmas[n])},{result.flags[n]}"
        for n in result.free]
    est += [f"chi2,{_e(result.chi2)},,", f"chi2_prior,{_e(result.chi2_prior)},,",
            f"dof,{result.dof},,", f"iterations,{result.iterations},,",
            f"condition_number,{_e(result.cond)},,"]
    cov = [",".join(("name",) + result.free)] + [
        ",".join([n] + [_e(v) for v in row]) for n, row in zip(result.free, result.cov)]
    res = ["experiment,t,quantity,measured,model,sigma,normalized"] + [
        f"{r.experiment},{r.t:g},{r.quantity},{_e(r.measured)},{_e(r.model)},{_e(r.sigma)},"
        f"{_e(r.normalized)}" for r in result.residuals]
    return [est, cov, res]


def _fit_paths(prefix: Path) -> list[Path]:
    return [Path(f"{prefix}_{k}.csv") for k in ("estimates", "covariance", "residuals")]


def _compare_lines(cmp, deck: FitDeck) -> list[str]:
    """Lines of <output>_compare.csv (the file beamid-batch writes for compare)."""
    lines = ["quantity,value", f"chi2,{_e(cmp.chi2)}", f"dof,{cmp.dof}",
             f"expected,{_e(cmp.expected)}", f"expected_sigma,{_e(cmp.expected_sigma)}",
             f"p_value,{_e(cmp.p_value)}"]
    values = list(cmp.structure)
    names = ["runs", "runs_expected", "runs_z", "runs_p", "trend_slope", "trend_z", "trend_p"]
    lines += [f"{n},{_e(v)}" for n, v in zip(names, values)]
    lines.append(f"systematic,{1 if cmp.systematic else 0}")
    lines += [f"chi2[{name}],{_e(cmp.per_experiment.get(name, 0.0))}"
              for name in deck.experiments]
    return lines


def write_fit_files(result: FitResult, prefix: Path) -> list[Path]:
    """Estimates, covariance and residual table as CSV."""
    paths = _fit_paths(prefix)
    for p, lines in zip(paths, _fit_lines(result)):
        _write(p, lines)
    return paths


#: Columns of <output>_ranking.csv (beamid-batch writes the same).
RANKING_HEADER = ("rank,effect,state,parameter,score_drop,score_p,refit_drop,refit_p,"
                  "chi2_drop,p_value,estimate,sigma,physical,identifiable,significant,"
                  "acceptable,rival")


def _ranking_lines(diag: Diagnosis) -> list[str]:
    """One row per candidate parameter, best candidate first; chi2_drop,
    p_value, estimate and sigma are the refit's when one was made, else the
    score test's."""
    lines = [RANKING_HEADER]
    for k, c in enumerate(diag.candidates, start=1):
        for n in c.params or ("",):
            lines.append(f"{k},{c.effect},{c.state},{n},{_e(c.score_drop)},{_e(c.score_p)},"
                         f"{_e(c.lr_drop)},{_e(c.lr_p)},{_e(c.chi2_drop)},{_e(c.p_value)},"
                         f"{_e(c.estimate.get(n, math.nan))},{_e(c.sigma.get(n, math.nan))},"
                         f"{int(c.physical)},{int(c.identifiable)},{int(c.significant)},"
                         f"{int(c.acceptable)},{int(c.rival)}")
    return lines


def write_ranking(diag: Diagnosis, path: Path) -> None:
    _write(path, _ranking_lines(diag))


def run_fit_deck(deck: FitDeck | str | os.PathLike, plots: bool = True
                 ) -> tuple[str, list[Path], Any]:
    """Run an estimation deck; return (report text, files written, result)."""
    if not isinstance(deck, FitDeck):
        deck = read_fit_deck(deck)
    prefix = deck.output_prefix
    # compute everything first: no file is written when a step fails
    outputs: list[tuple[Path, list[str]]] = []
    if deck.task == "improve":
        ladder: Ladder = improve(deck.model, deck.experiments, deck.data, free=deck.free,
                                 prior=deck.prior, candidates=deck.candidates,
                                 alpha=deck.alpha, max_iter=deck.max_iter)
        outputs += list(zip(_fit_paths(prefix), _fit_lines(ladder.fit)))
        outputs.append((Path(f"{prefix}_ranking.csv"),
                        _ranking_lines(ladder.steps[-1].diagnosis)))
        outputs.append((Path(f"{prefix}_ladder.csv"), ["step,effect,chi2,dof,chi2_per_dof"] + [
            f"{s.step},{s.effect or 'start'},{_e(s.chi2)},{s.dof},{_e(s.chi2_per_dof)}"
            for s in ladder.steps]))
        for p, lines in outputs:
            _write(p, lines)
        files = [p for p, _ in outputs]
        text = str(ladder)
        if plots:
            files += _plots(ladder=ladder, prefix=prefix)
        return text, files, ladder
    result = fit(deck.model, deck.experiments, deck.data, free=deck.free, prior=deck.prior,
                 max_iter=deck.max_iter)
    outputs += list(zip(_fit_paths(prefix), _fit_lines(result)))
    text = result.summary()
    out: Any = result
    cmp = None
    if deck.task == "compare":
        cmp = compare(result)
        text += "\n" + str(cmp)
        out = cmp
        outputs.append((Path(f"{prefix}_compare.csv"), _compare_lines(cmp, deck)))
    elif deck.task == "diagnose":
        diag = diagnose(result, deck.candidates, alpha=deck.alpha)
        outputs.append((Path(f"{prefix}_ranking.csv"), _ranking_lines(diag)))
        text += "\n" + str(diag)
        out = diag
    for p, lines in outputs:
        _write(p, lines)
    files = [p for p, _ in outputs]
    if cmp is not None and plots:
        files += _plots(cmp=cmp, prefix=prefix)
    return text, files, out


def _plots(prefix: Path, cmp=None, ladder=None) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plot_fit import plot_compare, plot_ladder

    written = []
    if ladder is not None:
        fig, ax = plt.subplots(figsize=(6, 4))
        plot_ladder(ladder, ax=ax)
        p = Path(f"{prefix}_ladder.png")
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)
        cmp_pairs = [("start", compare(ladder.steps[0].fit)), ("final", compare(ladder.fit))]
    else:
        cmp_pairs = [("", cmp)]
    for tag, c in cmp_pairs:
        fig = plot_compare(c)     # one panel per quantity and unit (plot_fit.py)
        p = Path(f"{prefix}_compare{'_' + tag if tag else ''}.png")
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)
    return written
