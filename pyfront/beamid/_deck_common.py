"""What decks.py and fit_decks.py share: the values of the Fortran deck reader
turned into Python objects, and the Fortran task runner (one direction of
imports: decks -> fit_decks -> _deck_common)."""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from . import _core
from .errors import InputError
from .loads import LOAD_WIRE, Load, RadialWire, TipLoad


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


def published(values: dict) -> tuple[Published, ...]:
    """The &published groups as read by the Fortran reader."""
    return tuple(Published(table=g["table"], row=g["row"], values=g["values"],
                           deviations=tuple(g["deviations"]), note=g["note"])
                 for g in values["published"])


def load(kind: int, values: list[float]) -> Load:
    """A load from the reader's (kind, [fx, fy, moment, wire_length])."""
    if kind == LOAD_WIRE:
        return RadialWire(values[3])
    return TipLoad(values[0], values[1], values[2])


def check_path(path: Any, what: str = "path") -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"read_deck: {what} = {path!r}, expected a deck file path "
                         "(str or os.PathLike)")
    return Path(path)


def run_files(deck: Any) -> list[Path]:
    """Run a deck's task with the runners of ``beamid-batch`` (the same
    Fortran, so the same bytes) and return the files written (all or none).
    A deck object runs its file with its ``task`` (so a FitDeck whose task was
    replaced runs that task, as ``beamid fit|compare|diagnose|improve DECK``)."""
    if hasattr(deck, "path"):
        return [Path(p) for p in _core.run_deck(str(deck.path), deck.task)]
    return [Path(p) for p in _core.run_deck(str(check_path(deck, "deck")))]
