"""Namelist decks (format: docs/decks.md).

Tasks: ``static`` (arc-length), ``fe_static`` and ``fe_modes`` (finite
elements, group ``&fe``), ``simulate`` (dynamics, group ``&simulate``: the
arguments of :func:`beamid.simulate`; writes ``<output>_history.csv``) and the
estimation tasks (:mod:`beamid.fit_decks`).

Decks are read, validated and run by the Fortran of the batch executable
``beamid-batch`` (``beamid_deck``, ``beamid_tasks``, through
``beamid._core``), so a deck fails the same way in both and both write the
same files; f90nml only writes decks (:func:`write_deck`).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import f90nml

from . import _check, fe
from . import load_histories as _lh
from .errors import _write_text
from .fit_decks import FIT_TASKS, FitDeck, OutputPrefix, Published, _fit_deck, run_files
from .fit_decks import check_path as _check_path, load as _load, published as _published
from .fit_decks import run_fit_deck
from .dynamics import _point_name, work_names
from .loads import Load, RadialWire
from .model import Model, _core
from .history import deck_run
from .static import solve_static

__all__ = ["Deck", "Published", "read_deck", "write_deck", "run", "run_files",
           "history_columns", "FitDeck"]

#: defaults of the &fe group (docs/fe.md)
FE_DEFAULTS = {"elements_per_beam": 4, "moment_form": "eq78", "rotary_inertia": False,
               "point_masses": True, "steps": 0, "tol": 0.0}
_PER_BEAM = {"l": "L{}", "ei": "EI{}", "ea": "EA{}", "rho": "rho{}", "c": "C{}",
             "thick": "thick{}"}
_PER_POINT = {"m": "m_{}", "j": "J_{}", "mu": "mu_{}", "c_drag": "c_{}"}
#: the model's global (not per beam, point or joint) parameters, from the core
_GLOBAL = tuple(n for n, g in zip(_core.param_names(1), _core.param_groups(1)) if g == "global")


@dataclass(frozen=True)
class Deck(OutputPrefix):
    """A parsed and validated deck."""

    path: Path
    task: str
    output: str
    model: Model
    load: Load
    wrt: tuple[str, ...] = ()
    shape_points: int = 101
    tol: float | None = None
    published: tuple[Published, ...] = field(default_factory=tuple)
    fe: dict = field(default_factory=lambda: dict(FE_DEFAULTS))
    #: task simulate: ``t_out`` (array) and the keyword arguments of beamid.simulate
    simulate: dict | None = None
    #: the deck as read once by the Fortran reader (beamid._core.DeckHandle);
    #: run goes through it. None for a Deck built by hand (run reads its path).
    handle: Any = field(default=None, repr=False, compare=False)


def read_deck(path: str | os.PathLike):
    """Read and validate a deck with the reader of ``beamid-batch``; raise
    InputError listing every problem (file, line, group, variable, value).

    Estimation decks (tasks fit, compare, diagnose, improve) are returned as
    :class:`beamid.fit_decks.FitDeck`; the others as :class:`Deck`. The deck
    file and each measurement file it names are opened once: the deck's
    ``handle`` holds them as read for its run (released with the deck)."""
    path = _check_path(path)
    handle = _core.DeckHandle(path)
    values = handle.values()
    if values["task"] in FIT_TASKS:
        return _fit_deck(path, values, handle=handle)
    model = Model(values["nbeams"], values["params"])
    names = model.names()
    load = _load(*values["load"])
    simulate = None
    if values["task"] == "simulate":
        simulate = {"t_out": values["t_out"], **values["simulate"]}
        spec, tab = _core.deck_histories(handle)
        if spec.shape[1]:        # the &history groups (docs/loads.md)
            simulate["loads"] = _lh.from_columns(spec[1:], tab)
    return Deck(path=path, task=values["task"], output=values["output"], model=model,
                load=load, wrt=tuple(names[i] for i in values["wrt"]),
                shape_points=values["shape_points"], tol=values["tol"] or None,
                published=_published(values), fe=values["fe"], simulate=simulate,
                handle=handle)


def write_deck(deck: Deck, path: str | os.PathLike) -> None:
    """Write a deck that reads back to the same model, load and options."""
    _check.instance("deck", deck, Deck, "a beamid.Deck (beamid.read_deck)")
    path = _check.path("path", path)
    model = deck.model
    nb = model.nbeams
    p = model.params
    groups: dict[str, dict[str, Any]] = {
        "beamid": {"task": deck.task, "output": deck.output, "nbeams": nb},
        "model": {
            **{var: [p[fmt.format(k)] for k in range(1, nb + 1)]
               for var, fmt in _PER_BEAM.items()},
            **{var: [p[fmt.format(_point_name(nb, k))] for k in range(1, nb + 1)]
               for var, fmt in _PER_POINT.items()},
            **({"joint_flex": [p[f"{_point_name(nb, k)}_flex"] for k in range(1, nb)]}
               if nb > 1 else {}),
            **{g: p[g] for g in _GLOBAL},
        },
    }
    if isinstance(deck.load, RadialWire):
        groups["load"] = {"kind": "wire", "wire_length": deck.load.Lw}
    else:
        groups["load"] = {"kind": "tip", "fx": deck.load.fx, "fy": deck.load.fy,
                          "moment": deck.load.moment}
    static: dict[str, Any] = {"shape_points": deck.shape_points}
    if deck.wrt:
        static["wrt"] = list(deck.wrt)
    if deck.tol:
        static["tol"] = deck.tol
    groups["static"] = static
    nml = f90nml.Namelist(groups)
    nml.float_format = ".17g"
    _write_text(path, str(nml) + "\n")


def history_columns(nbeams: int, run=None) -> tuple[str, ...]:
    """Columns of ``<output>_history.csv`` (task simulate), as beamid-batch
    writes them: time, tip, energies, each work line, their sum, the
    numerical line E - E0 - work, the motor torque. With ``run``, the work
    lines of its load histories follow the chain's (docs/loads.md)."""
    base = work_names(nbeams)
    extra = () if run is None else tuple(
        k for k in run.ledger if k not in base and k not in ("kinetic", "potential", "total",
                                                              "numerical"))
    return ("t", "tip_u", "tip_w", "tip_angle", "energy", "kinetic", "potential",
            *base, *extra, "work", "numerical", "motor_torque")


def run(deck: Deck | str | os.PathLike):
    """Run a deck as ``beamid-batch`` does and write the same CSV files.

    The files are written by the same Fortran routines as ``beamid-batch``
    (static decks ``<output>_summary.csv`` and ``_shape.csv``, dynamic decks
    ``_history.csv``, finite element and estimation decks the files listed in
    docs/decks.md); a :class:`Deck` runs the file it was read from. Returns
    the result object of the task (a :class:`beamid.Run` for simulate, a
    :class:`StaticResult` for static, ...), computed through the Python API.
    """
    if not isinstance(deck, (Deck, FitDeck)):
        deck = read_deck(_check_path(deck, "deck"))
    if isinstance(deck, FitDeck):   # (improve: its ladder runs once, for files and result)
        return run_fit_deck(deck, plots=False)[2]
    run_files(deck)
    if deck.task == "fe_static":
        opts = deck.fe
        return fe.fe_static(deck.model, deck.load, int(opts["elements_per_beam"]),
                            moment_form=str(opts["moment_form"]), steps=int(opts["steps"]),
                            tol=float(opts["tol"]))
    if deck.task == "fe_modes":
        return fe.modes(deck.model, int(deck.fe["elements_per_beam"]),
                        rotary_inertia=bool(deck.fe["rotary_inertia"]))
    if deck.task == "simulate":
        return deck_run(deck)
    return solve_static(deck.model, deck.load, wrt=deck.wrt, tol=deck.tol)
