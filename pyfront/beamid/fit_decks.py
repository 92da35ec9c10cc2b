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
from . import chain as _chain
from . import load_histories as _lh
from .diagnosis import Ladder, _run_ladder, compare
from .errors import InputError, _write_text
from .estimation import (FitResult, _carried_prior, _free_indices, _identify, _prior_arrays,
                         _result as _fit_result, identify, with_row_treatment)
from . import _core_estimation as _ce
from .loads import LOAD_MODAL, LOAD_RELEASE, LOAD_WIRE, Load, Modal, RadialWire, Release, TipLoad
from .channels import Sensor, read_channels
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
    taken as a value column of the legacy positional form)."""
    if not isinstance(spec, dict):
        spec = _core.spec_from_column(spec)
    if kind == LOAD_MODAL:
        held = (RadialWire(spec["wire_length"]) if spec.get("wire_length", 0.0) > 0.0 else
                TipLoad(spec.get("fx", 0.0), spec.get("fy", 0.0), spec.get("moment", 0.0)))
        return Modal(held, elements_per_beam=int(round(spec.get("elements_per_beam", 4))))
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
    replaced runs that task, as ``beamid fit|compare|diagnose|improve DECK``),
    from the deck as read (its handle: the file is not read again)."""
    if hasattr(deck, "path"):
        handle = deck_handle(deck)
        if handle is not None:
            return [Path(p) for p in handle.run_task(deck.task)[1]]
        return [Path(p) for p in _core.run_deck(str(deck.path), deck.task)]
    return [Path(p) for p in _core.run_deck(str(check_path(deck, "deck")))]


def deck_handle(deck: Any) -> _core.DeckHandle | None:
    """The open handle of the file a deck object was read from (None: the
    deck was not read by read_deck, its handle was closed, or its ``path``
    was replaced since)."""
    handle = getattr(deck, "handle", None)
    if not isinstance(handle, _core.DeckHandle) or handle.closed:
        return None
    if Path(handle.path) != Path(deck.path):
        return None
    return handle


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
    #: the measurement chain of &fit (time_offset, bias, scale: beamid.chain.ChainSpec;
    #: loss, burn_in, estimate_sigma: beamid.chain.RowTreatment), None when not asked
    nuisance: Any = None
    treatment: Any = None
    #: &fit items given apart from the file (the command line's measurement
    #: chain options, :func:`chain_options`): the deck reads with them
    fit_keys: str = ""
    #: the deck as read once by the Fortran reader (beamid._core.DeckHandle:
    #: the deck file and its measurement files, each opened once); its run
    #: goes through it. None for a FitDeck built by hand (run reads its path).
    handle: Any = field(default=None, repr=False, compare=False)


def _stage_data(values: dict, stage: int, path: str, experiments: dict) -> Measurements:
    """The data of &fit group `stage` (0-based): its measurement CSV, or a
    logger file read through the deck's &sensor table (read_channels)."""
    loggers = values.get("loggers", {})
    if stage not in loggers:
        return read_measurements(path, experiments)
    experiment, sigma = loggers[stage]
    sensors = [Sensor(n, o, s) for n, o, s in values.get("sensors", ())]
    return read_channels(path, experiment, sigma=sigma, sensors=sensors)


def _rows_measurements(rows: tuple, source: str, experiments: dict) -> Measurements:
    """Measurements from the rows of the deck reader (as read_measurements
    builds them from its file), checked against the deck's experiments."""
    names, t, quantity, value, sigma, lines = rows
    data = Measurements(names, t, quantity, value, sigma, source=str(Path(source)), lines=lines)
    data.check_experiments(experiments)
    return data


def chain_options(time_offset=(), bias=(), scale=(), loss: str | None = None,
                  burn_in: float | None = None, estimate_sigma=None,
                  initial_velocity=()) -> str:
    """The &fit items of the measurement chain's options of ``beamid
    fit|compare|diagnose|improve DECK`` (docs/decks.md, "The measurement
    chain"), for :func:`read_fit_deck`'s ``fit_keys``: the Fortran deck reader
    checks them as the deck's own. ``estimate_sigma``: None (not asked), an
    empty list (every channel) or channels.

    >>> chain_options(time_offset=["free"], bias=["free:w_tip"], loss="huber")
    "time_offset = 'free'\\nbias = 'free:w_tip'\\nloss = 'huber'"
    """
    items = []

    def words(key: str, values) -> None:
        values = [values] if isinstance(values, str) else list(values)
        for v in values:
            if not isinstance(v, str) or "'" in v or "\n" in v or not v.strip():
                _check.fail(key, v, "a name without quotes or line breaks")
        if values:
            items.append(f"{key} = " + ", ".join(f"'{v}'" for v in values))

    words("time_offset", time_offset)
    words("bias", bias)
    words("scale", scale)
    words("initial_velocity", initial_velocity)
    if loss is not None:
        words("loss", [loss])
    if burn_in is not None:
        items.append(f"burn_in = {_check.real('burn_in', burn_in)!r}")
    if estimate_sigma is not None:
        words("estimate_sigma", list(estimate_sigma) or ["all"])
    return "\n".join(items)


def _fit_deck(path: Path, values: dict, fit_keys: str = "", handle: Any = None) -> FitDeck:
    """A FitDeck from the values of the Fortran reader (beamid._core.read_deck),
    its measurements from ``handle`` (the deck as read; None: read the files)."""
    model = Model(values["nbeams"], values["params"])
    names = model.names()
    experiments = {n: load(kind, vals) for n, kind, vals in values["experiments"]}
    spec, tab = _core.deck_histories(handle if handle is not None else str(path))
    for j, name in enumerate(experiments):     # the &history groups of each release
        cols = spec[1:, spec[0] == j + 1]
        if cols.shape[1]:
            experiments[name] = dataclasses.replace(experiments[name],
                                                    loads=_lh.from_columns(cols, tab))

    def rows(stage: int, source: str) -> Measurements:
        if handle is None:
            return _stage_data(values, stage, source, experiments)
        return _rows_measurements(handle.data(stage), source, experiments)

    data = rows(0, values["data_path"])
    stages = tuple(Stage(s["name"], data if k == 0 else rows(k + 1, s["data_path"]),
                         tuple(names[i] for i in s["free"]), s["max_iter"])
                   for k, s in enumerate(values.get("stages", ())))
    nuisance, treatment = _chain.from_deck(values["experiments"], data)
    return FitDeck(path=path, task=values["task"], output=values["output"], model=model,
                   experiments=experiments, data=data,
                   free=tuple(names[i] for i in values["free"]),
                   prior={names[i]: (m, s) for i, m, s in values["prior"]},
                   candidates=tuple(values["candidates"]) or None, alpha=values["alpha"],
                   max_iter=values["max_iter"], published=published(values),
                   stages=stages, nuisance=nuisance, treatment=treatment, fit_keys=fit_keys,
                   handle=handle)


def read_fit_deck(path: str | os.PathLike, fit_keys: str = "") -> FitDeck:
    """Read and validate an estimation deck (the reader of :func:`beamid.read_deck`;
    the deck and its measurement files are opened once, held by the
    FitDeck's ``handle``); ``fit_keys``: &fit items given apart, which replace
    the deck's (the command line's measurement chain options,
    :func:`chain_options`)."""
    path = check_path(path)
    fit_keys = _check.text("fit_keys", fit_keys, empty=True)
    handle = _core.DeckHandle(path, fit_keys)
    values = handle.values()
    if values["task"] not in FIT_TASKS:
        handle.close()
        raise InputError(f"{path}: task {values['task']!r} is not an estimation task "
                         f"{FIT_TASKS}")
    return _fit_deck(path, values, fit_keys, handle)


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
        handle = _check_as_read(deck)
    else:
        deck = read_fit_deck(deck)
        handle = deck.handle
    with handle.lock:      # the run the handle holds: from its start to its files
        out = (identify_deck(deck, handle) if deck.task == "identify" else
               _deck_result(deck, handle))
        summary, written = _ce.deck_task_write_report(handle, deck.task, deck.output)
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


def _check_as_read(deck: FitDeck) -> Any:
    """InputError unless ``deck`` is its file as read, but for ``task`` and
    ``output``: the Fortran runs the deck file (its fit once, for the files
    and the result). Returns the handle of the deck as read (the deck's own,
    else the file read now)."""
    handle = deck_handle(deck)
    if handle is None:
        read = read_fit_deck(deck.path, deck.fit_keys)
        handle = read.handle
    else:
        read = _fit_deck(deck.path, handle.values(), deck.fit_keys, handle)
    differ = [f.name for f in dataclasses.fields(FitDeck)
              if f.name not in ("task", "output", "handle")
              and not _same(getattr(deck, f.name), getattr(read, f.name))]
    if differ:
        shown = "; ".join(f"{n} = {getattr(deck, n)!r}, expected {getattr(read, n)!r}"
                          if len(repr(getattr(deck, n))) < 80 else f"{n} differs"
                          for n in differ)
        raise InputError(f"run_fit_deck: {shown} (as {deck.path} reads: a FitDeck runs as "
                         "its file reads, only task and output may be replaced; write the change "
                         "into the deck file)")
    return handle


def _deck_result(deck: FitDeck, handle: Any) -> Any:
    """The result of the deck's task, FitResult (fit), Comparison (compare),
    Diagnosis (diagnose) or Ladder (improve), from the ladder the Fortran of
    ``beamid-batch`` runs on the deck as read there (its problem and
    candidates; ``_core_estimation.deck_task_start`` on the deck's
    ``handle``, which holds the run and returns its rungs); the caller holds
    ``handle.lock`` until ``deck_task_write`` has written the deck's files
    from the same ladder."""
    _ce.deck_task_start(handle, deck.task)
    names = deck.model.names()
    exps = list(deck.experiments)
    own = deck.nuisance or _chain.ChainSpec()
    if deck.task in ("fit", "compare"):     # the ladder ended at its fit, undiagnosed
        rung = _ce.ladder_rungs(len(names) + len(own.names(exps)), [], handle)[0]
        raw, phys, sub = _chain.split_ladder_fit(rung["fit"], rung["free"], len(names), own,
                                                 exps)
        free_names = tuple(names[i] for i in phys)   # the fit's own, as _run_ladder
        prior_map = _prior_arrays(deck.model, free_names, deck.prior)[0]
        fit = _fit_result(deck.model, deck.experiments, deck.data, free_names, prior_map,
                          raw, chain=sub or None)
        if rung["rows"] is not None:
            fit = with_row_treatment(fit, deck.treatment or _chain.RowTreatment(),
                                     rung["rows"])
        return fit if deck.task == "fit" else compare(fit)
    prior_map = _prior_arrays(deck.model, _free_indices(deck.model, deck.free)[0], deck.prior)[0]
    improve = deck.task == "improve"
    ladder = _run_ladder(deck.model, deck.experiments, deck.data, prior_map, deck.candidates,
                         deck.alpha, len(deck.candidates or ()) * improve, deck.task,
                         own=deck.nuisance, treatment=deck.treatment, run=handle)
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


def identify_deck(deck: FitDeck, handle: Any = None) -> Any:
    """:func:`beamid.identify` on the stages of an identification deck (task
    ``identify``): the deck's model is the start, its experiments serve every
    stage, the first stage takes the deck's a priori values. Each stage is
    fitted by the Fortran of ``beamid-batch`` on the deck as read there
    (``_core_estimation.deck_task_start`` on ``handle``, default the deck's
    own), so its files can then be written from the same fits
    (``deck_task_write(handle)``, under ``handle.lock`` from the first stage
    on)."""
    if deck.task != "identify" or not deck.stages:
        raise InputError(f"{deck.path}: task {deck.task!r} is not 'identify' (one &fit group "
                         "per stage)")
    if handle is None:
        handle = _check_as_read(deck)
    names, number = deck.model.names(), {s.name: k for k, s in enumerate(deck.stages, 1)}

    def stage_fit(name, start, exps, data, _free, prior, _limit):   # as estimation.fit's
        carried = _carried_prior(start, prior)[0] if isinstance(prior, FitResult) else None
        _ce.deck_task_start(handle, "identify", number[name])
        r = _ce.ladder_rungs(len(names), [], handle)[0]
        free = tuple(names[i] for i in r["free"])
        prior_map = _prior_arrays(start, free, prior)[0] if carried is None else carried
        return _fit_result(start, exps, data, free, prior_map, r["fit"])

    stages = {s.name: (deck.experiments, s.data, s.free) + ((deck.prior,) if k == 0 and
                                                             deck.prior else ())
              for k, s in enumerate(deck.stages)}
    with handle.lock:
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
