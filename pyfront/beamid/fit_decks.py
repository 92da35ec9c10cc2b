"""Decks for the estimation tasks fit, compare, diagnose and improve
(format: docs/decks.md, section "Estimation decks").

>>> # &beamid task = 'improve', output = 'out/demo', preset = 'pace' /
>>> # &model axial_coupling = 0.0 /
>>> # &experiment name = 'F2', kind = 'tip', fy = 2.0 /      (one group per experiment)
>>> # &fit data = 'demo.csv', free = 'EI1', 'EI2' /

The outputs are CSV files next to the deck: ``<output>_estimates.csv``
(name, estimate, sigma, flag), ``<output>_covariance.csv``,
``<output>_residuals.csv``, ``<output>_ranking.csv`` (diagnose, improve),
``<output>_compare.csv`` (compare) and ``<output>_ladder.csv`` (improve),
written by the Fortran task runners of ``beamid-batch`` (the same bytes),
plus PNG figures for compare and improve. The deck is read and validated by
the Fortran reader of ``beamid-batch`` too (:func:`beamid.read_deck`).
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import _check, _core
from .diagnosis import Ladder, _run_ladder, compare
from .errors import InputError, _write_text
from .estimation import (FitResult, _carried_prior, _free_indices, _identify, _prior_arrays,
                         _result as _fit_result, identify)
from . import _core_estimation as _ce
from .loads import LOAD_MODAL, LOAD_RELEASE, LOAD_WIRE, Load, Modal, RadialWire, Release, TipLoad
from .measurements import Measurements, read_measurements
from .model import Model
from .plot_fit import ladder_titles, plot_compare, plot_ladder
from .plotting import agg_pyplot, save_png

FIT_TASKS = ("fit", "compare", "diagnose", "improve", "identify")


# ---- shared with decks.py (which imports this module, never the other way):
# the values of the Fortran deck reader as Python objects, the Fortran task runner

class OutputPrefix:
    """The ``output_prefix`` of a deck (``path``: the deck file, ``output``: as given)."""

    path: Path
    output: str

    @property
    def output_prefix(self) -> Path:
        """Output prefix resolved against the deck's folder."""
        out = Path(self.output)
        return out if out.is_absolute() else self.path.parent / out


@dataclass(frozen=True)
class Published:
    """Published values a deck reproduces (group &published)."""

    table: str
    row: str
    values: dict[str, tuple[float, int]]  # quantity -> (value, decimal digits)
    deviations: tuple[str, ...] = ()
    note: str = ""
    #: the class of the deviations ("formulation", "random draws",
    #: "unexplained"; "" for none given) and the heading of docs/deviations.md
    #: that explains them
    kind: str = ""
    section: str = ""


def published(values: dict) -> tuple[Published, ...]:
    """The &published groups as read by the Fortran reader."""
    return tuple(Published(table=g["table"], row=g["row"], values=g["values"],
                           deviations=tuple(g["deviations"]), note=g["note"],
                           kind=g.get("kind", ""), section=g.get("section", ""))
                 for g in values["published"])


def load(kind: int, spec) -> Load | Release | Modal:
    """A load or a release from the reader's (kind, spec by the core's key
    names: fx, fy, moment, wire_length, elements_per_beam, ...; a list is
    taken as a value column of the core's layout)."""
    if not isinstance(spec, dict):
        values = [float(x) for x in spec]
        spec = {k: values[sk.row] for k, sk in _core.spec_keys().items() if sk.row < len(values)}
    if kind == LOAD_MODAL:
        return Modal(TipLoad(spec.get("fx", 0.0), spec.get("fy", 0.0), spec.get("moment", 0.0)),
                     elements_per_beam=int(round(spec.get("elements_per_beam", 4))))
    if kind == LOAD_RELEASE:
        keys = _core.spec_keys()
        return Release.from_spec({k: v for k, v in spec.items() if "release" in keys[k].families})
    if kind == LOAD_WIRE:
        return RadialWire(spec["wire_length"])
    return TipLoad(spec["fx"], spec["fy"], spec["moment"])


def check_path(path: Any, what: str = "path") -> Path:
    """``path`` as a Path; InputError naming ``what`` unless a str or os.PathLike."""
    return _check.path(f"read_deck: {what}", path)


def run_files(deck: Any) -> list[Path]:
    """Run a deck's task with the runners of ``beamid-batch`` (the same
    Fortran, so the same bytes) and return the files written (all or none).
    A deck object runs its file with its ``task`` (so a FitDeck whose task was
    replaced runs that task, as ``beamid fit|compare|diagnose|improve DECK``)."""
    if hasattr(deck, "path"):
        return [Path(p) for p in _core.run_deck(str(deck.path), deck.task)]
    return [Path(p) for p in _core.run_deck(str(check_path(deck, "deck")))]


# ---- estimation decks

@dataclass(frozen=True)
class Stage:
    """One stage of an identification deck (task ``identify``: one ``&fit``
    group per stage, in order; docs/workflow.md)."""

    name: str
    data: Measurements
    free: tuple[str, ...]
    max_iter: int = 50


@dataclass(frozen=True)
class FitDeck(OutputPrefix):
    """A parsed estimation deck."""

    path: Path
    task: str
    output: str
    model: Model
    experiments: dict[str, TipLoad | RadialWire | Release]
    data: Measurements
    free: tuple[str, ...]
    prior: dict[str, tuple[float, float]] = field(default_factory=dict)
    candidates: tuple[str, ...] | None = None
    alpha: float = 0.01
    max_iter: int = 50
    published: tuple = ()     #: &published groups (beamid.decks.Published)
    stages: tuple[Stage, ...] = ()   #: task identify: the stages, in order


def _fit_deck(path: Path, values: dict) -> FitDeck:
    """A FitDeck from the values of the Fortran reader (beamid._core.read_deck)."""
    model = Model(values["nbeams"], values["params"])
    names = model.names()
    experiments = {n: load(kind, vals) for n, kind, vals in values["experiments"]}
    data = read_measurements(values["data_path"], experiments)
    stages = tuple(Stage(s["name"], data if k == 0 else
                         read_measurements(s["data_path"], experiments),
                         tuple(names[i] for i in s["free"]), s["max_iter"])
                   for k, s in enumerate(values.get("stages", ())))
    return FitDeck(path=path, task=values["task"], output=values["output"], model=model,
                   experiments=experiments, data=data,
                   free=tuple(names[i] for i in values["free"]),
                   prior={names[i]: (m, s) for i, m, s in values["prior"]},
                   candidates=tuple(values["candidates"]) or None, alpha=values["alpha"],
                   max_iter=values["max_iter"], published=published(values),
                   stages=stages)


def read_fit_deck(path: str | os.PathLike) -> FitDeck:
    """Read and validate an estimation deck (the reader of :func:`beamid.read_deck`)."""
    path = check_path(path)
    values = _core.read_deck(str(path))
    if values["task"] not in FIT_TASKS:
        raise InputError(f"{path}: task {values['task']!r} is not an estimation task "
                         f"{FIT_TASKS}")
    return _fit_deck(path, values)


def run_fit_deck(deck: FitDeck | str | os.PathLike, plots: bool = True
                 ) -> tuple[str, list[Path], Any]:
    """Run an estimation deck; return (report text, files written, result).

    The deck's fit runs once, for the files and the result: the Fortran of
    beamid-batch runs it (and the task's diagnosis or improve ladder, a rung
    at a time, a progress bar on a terminal) on the deck as read there, the
    result objects are built from it, then the CSV files are written from
    it by the batch's writers (all or none); the report and the figures come
    from the result.

    A :class:`FitDeck` runs as its file reads: only its ``task`` and
    ``output`` may be replaced (``dataclasses.replace(deck, task="diagnose")``);
    a FitDeck differing from its file in any other field raises InputError
    naming the fields (write them into the deck file instead)."""
    text, files, out, _, figures = _run_fit_deck(deck, plots)
    return text, files + figures, out


def _run_fit_deck(deck: FitDeck | str | os.PathLike, plots: bool = True
                  ) -> tuple[str, list[Path], Any, str, list[Path]]:
    """:func:`run_fit_deck` as (text, CSV files, result, the summary line
    beamid-batch prints, figures written)."""
    if isinstance(deck, FitDeck):
        _check_as_read(deck)
    else:
        deck = read_fit_deck(deck)
    with _ce.LADDER_LOCK:
        out = identify_deck(deck) if deck.task == "identify" else _deck_result(deck)
        summary, written = _ce.deck_task_write_report(str(deck.path), deck.task, deck.output)
    files = [Path(p) for p in written]
    figures: list[Path] = []
    if isinstance(out, Ladder):
        text = str(out)
        if plots:
            figures += _plots(ladder=out, prefix=deck.output_prefix)
    elif deck.task == "fit":
        text = out.summary()
    else:
        text = out.fit.summary() + "\n" + str(out) if hasattr(out, "fit") else str(out)
        if deck.task == "compare" and plots:
            figures += _plots(cmp=out, prefix=deck.output_prefix)
    return text, files, out, summary, figures


def _same(a: Any, b: Any) -> bool:
    """a equals b, field by field, numpy arrays element by element (NaN equal)."""
    if dataclasses.is_dataclass(a) and not isinstance(a, type):
        return type(a) is type(b) and all(_same(getattr(a, f.name), getattr(b, f.name))
                                          for f in dataclasses.fields(a))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return False
        return bool(np.array_equal(a, b, equal_nan=a.dtype.kind in "fc" and b.dtype.kind in "fc"))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(map(_same, a, b))
    if isinstance(a, float) and isinstance(b, float) and a != a:
        return b != b
    return bool(a == b)


def _check_as_read(deck: FitDeck) -> None:
    """InputError unless ``deck`` is its file as read, but for ``task`` and
    ``output``: the Fortran runs the deck file (its fit once, for the files
    and the result)."""
    read = read_fit_deck(deck.path)
    differ = [f.name for f in dataclasses.fields(FitDeck) if f.name not in ("task", "output")
              and not _same(getattr(deck, f.name), getattr(read, f.name))]
    if differ:
        shown = "; ".join(f"{n} = {getattr(deck, n)!r}, expected {getattr(read, n)!r}"
                          if len(repr(getattr(deck, n))) < 80 else f"{n} differs"
                          for n in differ)
        raise InputError(f"run_fit_deck: {shown} (as {deck.path} reads: a FitDeck runs as "
                         "its file reads, only task and output may be replaced; write the change "
                         "into the deck file)")


def _deck_result(deck: FitDeck) -> Any:
    """The result of the deck's task, FitResult (fit), Comparison (compare),
    Diagnosis (diagnose) or Ladder (improve), from the ladder the Fortran of
    ``beamid-batch`` runs on the deck as read there (its problem and
    candidates; ``_core_estimation.deck_task_start``); the caller holds
    ``_core_estimation.LADDER_LOCK`` until ``deck_task_write`` has written
    the deck's files from the same ladder."""
    _ce.deck_task_start(str(deck.path), deck.task)
    names = deck.model.names()
    if deck.task in ("fit", "compare"):     # the ladder ended at its fit, undiagnosed
        rung = _ce.ladder_rungs(len(names), [])[0]
        free_names = tuple(names[i] for i in rung["free"])   # the fit's own, as _run_ladder
        prior_map = _prior_arrays(deck.model, free_names, deck.prior)[0]
        fit = _fit_result(deck.model, deck.experiments, deck.data, free_names, prior_map,
                          rung["fit"])
        return fit if deck.task == "fit" else compare(fit)
    prior_map = _prior_arrays(deck.model, _free_indices(deck.model, deck.free)[0], deck.prior)[0]
    improve = deck.task == "improve"
    ladder = _run_ladder(deck.model, deck.experiments, deck.data, prior_map, deck.candidates,
                         deck.alpha, len(deck.candidates or ()) * improve, deck.task)
    return ladder if improve else ladder.steps[0].diagnosis


def _plots(prefix: Path, cmp=None, ladder=None) -> list[Path]:
    written = []
    if ladder is not None:
        fig, ax = agg_pyplot().subplots(figsize=(6, 4))
        plot_ladder(ladder, ax=ax)
        fig.tight_layout()
        written.append(save_png(fig, f"{prefix}_ladder.png"))
        titles = ladder_titles(ladder)
        cmp_pairs = [("start", compare(ladder.steps[0].fit), titles[0]),
                     ("final", compare(ladder.fit), titles[1])]
    else:
        cmp_pairs = [("", cmp, None)]
    for tag, c, title in cmp_pairs:      # one panel per quantity and unit (plot_fit.py)
        written.append(save_png(plot_compare(c, title=title),
                                f"{prefix}_compare{'_' + tag if tag else ''}.png"))
    return written


def identify_deck(deck: FitDeck) -> Any:
    """:func:`beamid.identify` on the stages of an identification deck (task
    ``identify``): the deck's model is the start, its experiments serve every
    stage, the first stage takes the deck's a priori values. Each stage is
    fitted by the Fortran of ``beamid-batch`` on the deck as read there
    (``_core_estimation.deck_task_start``), so its files can then be written
    from the same fits (``deck_task_write(path, "identify")``, under
    ``_core_estimation.LADDER_LOCK`` from the first stage on)."""
    if deck.task != "identify" or not deck.stages:
        raise InputError(f"{deck.path}: task {deck.task!r} is not 'identify' (one &fit group "
                         "per stage)")
    names, number = deck.model.names(), {s.name: k for k, s in enumerate(deck.stages, 1)}

    def stage_fit(name, start, exps, data, _free, prior, _limit):   # as estimation.fit's
        carried = _carried_prior(start, prior)[0] if isinstance(prior, FitResult) else None
        _ce.deck_task_start(str(deck.path), "identify", number[name])
        r = _ce.ladder_rungs(len(names), [])[0]
        free = tuple(names[i] for i in r["free"])
        prior_map = _prior_arrays(start, free, prior)[0] if carried is None else carried
        return _fit_result(start, exps, data, free, prior_map, r["fit"])

    stages = {s.name: (deck.experiments, s.data, s.free) + ((deck.prior,) if k == 0 and
                                                             deck.prior else ())
              for k, s in enumerate(deck.stages)}
    with _ce.LADDER_LOCK:
        return _identify(deck.model, stages, 50, None, stage_fit)


def run_identify(decks: list, plots: bool = True) -> tuple[str, list[Path], Any]:
    """``beamid identify DECK [DECK ...]``: each estimation deck is a stage
    (static -> free -> forced), run in order by :func:`beamid.identify`
    (estimates and full covariance carried, Eq. 146-148, 164-166); the first
    deck's model is the start, each later deck's model gives the starting
    values of its newly free parameters. Writes ``<output>_identify.csv``
    (stage, parameter, estimate, sigma_before, sigma_after) with the first
    deck's output prefix, and ``_identify.png`` with ``plots``.

    One deck of task ``identify`` holds all its stages: its files are
    written by the Fortran runner of ``beamid-batch`` (the same bytes:
    ``_identify.csv`` and every stage's ``_<stage>_estimates.csv``,
    ``_covariance.csv``, ``_residuals.csv``)."""
    if not decks:
        raise InputError("identify: give the stage decks in order (static, free, forced)")
    parsed = [d if isinstance(d, FitDeck) else read_fit_deck(d) for d in decks]
    prefix = parsed[0].output_prefix
    staged = [d.path for d in parsed if d.task == "identify"]
    if len(parsed) == 1 and staged:
        _, files, result = run_fit_deck(parsed[0], plots=False)
    elif staged:
        raise InputError(f"identify: {staged[0]} holds its own stages (task 'identify'): "
                         "give it alone")
    else:   # one stage a deck; the CSV all or none (errors._write_all)
        names: list[str] = []
        for d in parsed:
            base = Path(d.output).name or d.path.stem
            names.append(base if base not in names else f"{base}_{len(names) + 1}")
        stages = {n: (d.experiments, d.data, d.free, d.prior or None)
                  for n, d in zip(names, parsed)}
        result = identify(parsed[0].model, stages, max_iter=parsed[0].max_iter,
                          starts={n: d.model for n, d in zip(names, parsed)})
        lines = ["stage,parameter,estimate,sigma_before,sigma_after,flag"]
        lines += [f"{r.stage},{r.parameter},{r.estimate:.16E},{r.sigma_before:.16E},"
                  f"{r.sigma_after:.16E},{r.flag}" for r in result.table]
        text = "\n".join(lines).replace("INF", "inf") + "\n"
        files = _write_text(prefix.with_name(prefix.name + "_identify.csv"), text)
    if plots:
        agg_pyplot()
        files.append(save_png(result.plot().figure,
                              prefix.with_name(prefix.name + "_identify.png"), 100))
    return result.summary() + "\n" + result.final.summary(), files, result
