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
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import f90nml

from . import _core
from .diagnosis import Diagnosis, Ladder, compare, diagnose, improve
from .errors import InputError
from .estimation import FitResult, fit
from .loads import RadialWire, TipLoad
from .measurements import Measurements, read_measurements
from .model import Model

FIT_TASKS = ("fit", "compare", "diagnose", "improve")
GROUPS = {
    "beamid": {"task", "output", "preset", "nbeams"},
    "model": {"l", "ei", "ea", "rho", "c", "m", "j", "mu", "c_drag", "joint_flex",
              "axial_coupling", "root_flex", "eta", "r_motor", "tau_motor"},
    "experiment": {"name", "kind", "fx", "fy", "moment", "wire_length"},
    "fit": {"data", "free", "prior_names", "prior_means", "prior_sigmas", "candidates",
            "alpha", "max_iter"},
}
_PER_BEAM = {"l": "L{}", "ei": "EI{}", "ea": "EA{}", "rho": "rho{}", "c": "C{}"}
_PER_POINT = {"m": "m_{}", "j": "J_{}", "mu": "mu_{}", "c_drag": "c_{}"}


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

    @property
    def output_prefix(self) -> Path:
        out = Path(self.output)
        return out if out.is_absolute() else self.path.parent / out


def _list(value: Any) -> list:
    if value is None:
        return []
    return list(value) if isinstance(value, (list, tuple)) else [value]


def _num(path: Path, group: str, name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{path}: in &{group}: {name} = {value!r}, expected a number")
    return float(value)


def _point(nbeams: int, k: int) -> str:
    return "tip" if k == nbeams else ("elbow" if k == 1 else f"joint{k}")


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
    values = {n: float(v) for n, v in zip(_core.param_names(nbeams), base)}
    for var, value in (groups.get("model", [{}])[0] or {}).items():
        if var in _PER_BEAM or var in _PER_POINT or var == "joint_flex":
            for k, entry in enumerate(_list(value), start=1):
                if entry is None:
                    continue
                if var in _PER_BEAM:
                    pname = _PER_BEAM[var].format(k)
                elif var in _PER_POINT:
                    pname = _PER_POINT[var].format(_point(nbeams, k))
                else:
                    pname = f"{_point(nbeams, k)}_flex"
                if pname not in values:
                    raise InputError(f"{path}: in &model: {var}({k}) is beyond the "
                                     f"{nbeams}-beam chain")
                values[pname] = _num(path, "model", f"{var}({k})", entry)
        else:
            values[var] = _num(path, "model", var, value)
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
        nums = {v: _num(path, "experiment", v, item[v])
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
    free = tuple(str(f) for f in _list(fg.get("free")) if f)
    if not free:
        raise InputError(f"{path}: &fit free is missing: name the parameters to estimate")
    for f in free:
        try:
            model.index(f)
        except InputError:
            raise InputError(f"{path}: &fit free = {f!r} is not a parameter name") from None
    pn = [str(p) for p in _list(fg.get("prior_names")) if p]
    pm = _list(fg.get("prior_means"))
    ps = _list(fg.get("prior_sigmas"))
    if not (len(pn) == len(pm) == len(ps)):
        raise InputError(f"{path}: &fit prior_names, prior_means and prior_sigmas must have "
                         f"equal lengths (got {len(pn)}, {len(pm)}, {len(ps)})")
    prior = {n: (_num(path, "fit", f"prior_means({i + 1})", m),
                 _num(path, "fit", f"prior_sigmas({i + 1})", s))
             for i, (n, m, s) in enumerate(zip(pn, pm, ps))}
    cands = tuple(str(c) for c in _list(fg.get("candidates")) if c) or None
    alpha = _num(path, "fit", "alpha", fg.get("alpha", 0.01))
    max_iter = int(fg.get("max_iter", 50))
    return FitDeck(path=path, task=task, output=str(output), model=model,
                   experiments=experiments, data=data, free=free, prior=prior,
                   candidates=cands, alpha=alpha, max_iter=max_iter)


def _write(path: Path, lines: list[str]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")


def _e(x: float) -> str:
    return f"{x:.16E}" if math.isfinite(x) else ("Infinity" if x > 0 else
                                                ("NaN" if math.isnan(x) else "-Infinity"))


def write_fit_files(result: FitResult, prefix: Path) -> list[Path]:
    """Estimates, covariance and residual table as CSV."""
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
    paths = [Path(f"{prefix}_estimates.csv"), Path(f"{prefix}_covariance.csv"),
             Path(f"{prefix}_residuals.csv")]
    for p, lines in zip(paths, (est, cov, res)):
        _write(p, lines)
    return paths


def write_ranking(diag: Diagnosis, path: Path) -> None:
    lines = ["rank,effect,state,score_drop,score_p,refit_drop,refit_p,physical,acceptable,"
             "rival,parameter,estimate,sigma"]
    for k, c in enumerate(diag.candidates, start=1):
        for n in c.params or ("",):
            lines.append(f"{k},{c.effect},{c.state},{_e(c.score_drop)},{_e(c.score_p)},"
                         f"{_e(c.lr_drop)},{_e(c.lr_p)},{int(c.physical)},{int(c.acceptable)},"
                         f"{int(c.rival)},{n},{_e(c.estimate.get(n, math.nan))},"
                         f"{_e(c.sigma.get(n, math.nan))}")
    _write(path, lines)


def run_fit_deck(deck: FitDeck | str | os.PathLike, plots: bool = True
                 ) -> tuple[str, list[Path], Any]:
    """Run an estimation deck; return (report text, files written, result)."""
    if not isinstance(deck, FitDeck):
        deck = read_fit_deck(deck)
    prefix = deck.output_prefix
    files: list[Path] = []
    if deck.task == "improve":
        ladder: Ladder = improve(deck.model, deck.experiments, deck.data, free=deck.free,
                                 prior=deck.prior, candidates=deck.candidates,
                                 alpha=deck.alpha, max_iter=deck.max_iter)
        files += write_fit_files(ladder.fit, prefix)
        write_ranking(ladder.steps[-1].diagnosis, Path(f"{prefix}_ranking.csv"))
        lines = ["step,effect,chi2,dof,chi2_per_dof"] + [
            f"{s.step},{s.effect or 'start'},{_e(s.chi2)},{s.dof},{_e(s.chi2_per_dof)}"
            for s in ladder.steps]
        _write(Path(f"{prefix}_ladder.csv"), lines)
        files += [Path(f"{prefix}_ranking.csv"), Path(f"{prefix}_ladder.csv")]
        text = str(ladder)
        if plots:
            files += _plots(ladder=ladder, prefix=prefix)
        return text, files, ladder
    result = fit(deck.model, deck.experiments, deck.data, free=deck.free, prior=deck.prior,
                 max_iter=deck.max_iter)
    files += write_fit_files(result, prefix)
    text = result.summary()
    out: Any = result
    if deck.task == "compare":
        cmp = compare(result)
        text += "\n" + str(cmp)
        out = cmp
        if plots:
            files += _plots(cmp=cmp, prefix=prefix)
    elif deck.task == "diagnose":
        diag = diagnose(result, deck.candidates, alpha=deck.alpha)
        write_ranking(diag, Path(f"{prefix}_ranking.csv"))
        files.append(Path(f"{prefix}_ranking.csv"))
        text += "\n" + str(diag)
        out = diag
    return text, files, out


def _plots(prefix: Path, cmp=None, ladder=None) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .plot_fit import plot_ladder, plot_measured_vs_model, plot_normalized_residuals

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
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        plot_measured_vs_model(c, ax=axes[0])
        plot_normalized_residuals(c, ax=axes[1])
        fig.tight_layout()
        p = Path(f"{prefix}_compare{'_' + tag if tag else ''}.png")
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)
    return written
