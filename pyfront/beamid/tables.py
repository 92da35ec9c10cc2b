"""Regression against the dissertation's published tables.

Every deck under ``inputs/seed/`` carries one or more ``&published`` groups
(table, row, quantities, values and their published decimal digits). Dynamic
decks (task simulate, Tables 8 and 13, Chapter V) name their quantities
``SERIES@TIME`` or ``max_abs_SERIES`` (:mod:`beamid.history`). A value
reproduces when it agrees with the published one to within one unit of the
last published digit; documented deviations (docs/deviations.md) are listed
but do not fail the run. Each deviation is classified (:attr:`Check.status`):

- ``last digit``: less than :data:`LAST_DIGIT_UNITS` units of the last
  published digit away (only the last printed digit differs, by one or two);
- ``formulation``: a different model, equation or algorithm, explained in the
  section of docs/deviations.md the deck's ``&published`` group names
  (``kind = 'formulation'``, ``section = '...'``);
- ``random draws``: the dissertation's estimates from its own noisy data,
  which cannot be redrawn: ours agree in character, not in digits;
- ``unexplained``: none of these (a deck without ``kind``, or
  ``kind = 'unexplained'``: a likely misprint).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Iterable

from . import _check
from .decks import Deck, read_deck
from .errors import InputError
from .estimation import fit
from .fe import evaluate_fe
from .history import deck_quantities
from .progress import progress
from .static import measurement_value, solve_static

#: a documented deviation less than this many units of the last published
#: digit away is a "last digit" difference (ours, rounded to the published
#: digits, is off by one or two in the last digit only)
LAST_DIGIT_UNITS = 3.0

#: the classes of a documented deviation, in the order of the final count
DEVIATION_CLASSES = ("last digit", "formulation", "random draws", "unexplained")


@dataclass(frozen=True)
class Check:
    """One published value against ours."""

    table: str
    row: str
    quantity: str
    published: float
    ours: float
    digits: int
    deviation: bool  # documented in docs/deviations.md
    #: the deck's class of the deviation ("formulation", "random draws",
    #: "unexplained" or "") and the heading of docs/deviations.md explaining it
    kind: str = ""
    section: str = ""

    @property
    def difference(self) -> float:
        return self.ours - self.published

    @property
    def ok(self) -> bool:
        """Within one unit of the last published digit."""
        return abs(self.difference) <= 10.0 ** (-self.digits) * (1 + 1e-9)

    @property
    def deviation_class(self) -> str | None:
        """None when the value reproduces or is not documented (a failure),
        else one of :data:`DEVIATION_CLASSES`."""
        if self.ok or not self.deviation:
            return None
        if abs(self.difference) < LAST_DIGIT_UNITS * 10.0 ** (-self.digits):
            return "last digit"
        return self.kind if self.kind in DEVIATION_CLASSES else "unexplained"

    @property
    def status(self) -> str:
        """"ok", "FAIL", or "deviation: " and its class (with the section of
        docs/deviations.md for a formulation)."""
        if self.ok:
            return "ok"
        cls = self.deviation_class
        if cls is None:
            return "FAIL"
        if cls == "formulation" and self.section:
            return f"deviation: formulation ({self.section})"
        if cls == "random draws":
            return "deviation: random draws (in character)"
        return f"deviation: {cls}"


def inputs_dir(sub: str) -> Path:
    """A folder of the bundled inputs: ``seed`` (published tables) or ``demo``."""
    # a source checkout (also an editable install) has the decks beside the package
    source = Path(__file__).resolve().parents[2] / "inputs" / sub
    if source.is_dir():
        return source
    # an installed copy ships them as package data
    return Path(str(resources.files("beamid") / "data" / "inputs" / sub))


def _all_seed_decks() -> list[Deck]:
    decks = [read_deck(p) for p in sorted(inputs_dir("seed").glob("*.nml"))]
    return [d for d in decks if d.published]


def _table_key(name: str) -> tuple[int, str]:
    return (0, f"{int(name):04d}") if name.isdigit() else (1, name)


def table_names() -> list[str]:
    """The names of the published tables the bundled decks check, in order
    (``2``, ``3``, ... then ``V`` and ``circle``): what ``beamid reproduce`` takes."""
    names = {p.table for d in _all_seed_decks() for p in d.published}
    return sorted(names, key=_table_key)


def seed_decks(tables: Iterable[str] = ()) -> list[Deck]:
    """The bundled decks, optionally only those of the named tables
    (``"2"``, ``"table2"``, ``"Table 2"`` and ``"circle"`` all work); an
    unknown table name is an :class:`InputError` listing the valid names."""
    if isinstance(tables, (str, int)) and not isinstance(tables, bool):
        tables = (tables,)
    if isinstance(tables, (bytes, dict)) or not hasattr(tables, "__iter__"):
        _check.fail("tables", tables, "table names ('2', 'circle', ...)")
    tables = list(tables)
    for t in tables:
        if isinstance(t, bool) or not isinstance(t, (str, int)):
            _check.fail("tables", tables, f"table names ('2', 'circle', ...), not "
                        f"{_check.show(t)}")
    tables = [str(t) for t in tables]
    decks = _all_seed_decks()
    if not tables:
        return decks
    known = {_norm(p.table) for d in decks for p in d.published}
    unknown = [t for t in tables if _norm(t) not in known]
    if unknown:
        names = sorted({p.table for d in decks for p in d.published}, key=_table_key)
        raise InputError(f"unknown table {', '.join(repr(t) for t in unknown)}, expected "
                         f"one of: {' '.join(names)}")
    wanted = {_norm(t) for t in tables}
    return [d for d in decks if any(_norm(p.table) in wanted for p in d.published)]


def _norm(table: str) -> str:
    t = str(table).lower().replace("table", "").replace(" ", "").replace("_", "")
    return t.lstrip("0") or t


def check_deck(deck: Deck) -> list[Check]:
    """Solve a deck and compare with its published values."""
    wanted = [q for pub in deck.published for q in pub.values]
    if deck.task == "fit":
        result = fit(deck.model, deck.experiments, deck.data, free=deck.free,
                     prior=deck.prior, max_iter=deck.max_iter)
        # published quantities of a fit deck: parameter estimates, iterations,
        # and NAME@iterationK: an estimate after K iterations (Tables 14, 22)
        values = {**result.estimates, "iterations": float(result.iterations)}
        for entry in result.log:
            for name, v in entry.params.items():
                values[f"{name}@iteration{entry.iteration}"] = v
        ours_of = values.__getitem__
    elif deck.task == "simulate":
        # dynamic decks: SERIES@TIME or max_abs_SERIES (beamid.history)
        ours_of = deck_quantities(deck, wanted).__getitem__
    elif deck.task.startswith("fe_"):
        ours_of = evaluate_fe(deck.task, deck.model, deck.load, **deck.fe,
                              quantities=wanted).__getitem__
    else:
        result = solve_static(deck.model, deck.load, tol=deck.tol)
        ours_of = lambda q: _quantity(result, q)  # noqa: E731
    return [Check(pub.table, pub.row, quantity, value, ours_of(quantity), digits,
                  quantity in pub.deviations, pub.kind, pub.section)
            for pub in deck.published for quantity, (value, digits) in pub.values.items()]


def _quantity(result, quantity: str) -> float:
    # Table 11/12 columns: w = y, dw = sin(psi), u = x - L, du = cos(psi) - 1
    if quantity == "dw_tip":
        return math.sin(result.tip_angle)
    if quantity == "du_tip":
        return math.cos(result.tip_angle) - 1.0
    return measurement_value(result, quantity)


def reproduce(tables: Iterable[str] = (), progress_bar: bool | None = None) -> list[Check]:
    """All checks of the bundled decks (optionally of some tables only; an
    unknown table name raises :class:`InputError` listing the valid ones).
    ``progress_bar``: a bar over the decks on standard error (None: only
    when it is a terminal, :func:`beamid.progress.progress`)."""
    checks: list[Check] = []
    if progress_bar is not None:
        _check.flag("progress_bar", progress_bar)
    decks = seed_decks(tables)
    for deck in progress(decks, total=len(decks), desc="reproduce", enabled=progress_bar):
        checks.extend(check_deck(deck))
    return checks


def format_checks(checks: list[Check]) -> str:
    """A table: table, row, quantity, published, ours, difference, status."""
    qw = max([11] + [len(c.quantity) for c in checks])  # dynamic decks: tip_w@2.6 ...
    head = f"{'table':<8} {'row':<14} {'quantity':<{qw}} {'published':>13} {'ours':>15} " \
           f"{'difference':>11}  status"
    lines = [head, "-" * len(head)]
    for c in checks:
        lines.append(f"{c.table:<8} {c.row:<14} {c.quantity:<{qw}} "
                     f"{c.published:>13.{c.digits}f} {c.ours:>15.{c.digits + 2}f} "
                     f"{c.difference:>11.2e}  {c.status}")
    failed = sum(1 for c in checks if c.status == "FAIL")
    classes = [c.deviation_class for c in checks if c.deviation_class]
    counts = ", ".join(f"{classes.count(k)} {k}" for k in DEVIATION_CLASSES if k in classes)
    lines.append(f"{len(checks) - failed - len(classes)} reproduced, {len(classes)} documented "
                 f"deviations{f' ({counts})' if counts else ''}, {failed} failed")
    return "\n".join(lines)
