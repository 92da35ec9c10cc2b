"""Named quantities of a dynamic run, for ``&published`` rows of dynamic decks
(task simulate) and for anyone who wants a number out of a :class:`beamid.Run`.

A quantity is either

- ``SERIES@T``: the value of a series at output time ``T`` (s), e.g.
  ``tip_w@1.0`` (Table 8), ``energy_change@2.6`` and ``work@2.6`` (Table 13),
  ``energy@0``; ``T`` must be one of the run's output times, or
- ``max_abs_SERIES``: the largest magnitude over the output times, e.g.
  ``max_abs_motor_torque`` (Chapter V's peak torque).

Series: ``tip_u tip_w tip_angle energy energy_change kinetic potential work
numerical motor_torque`` and each work line (``friction_elbow``, ``motor``, ...
see :func:`beamid.dynamics.work_names`).

>>> import beamid
>>> run = beamid.simulate(beamid.pace(J_elbow=0, J_tip=0), beamid.TipForce(fy=8.0),
...                       [0.0, 0.05], elements_per_beam=2)
>>> round(run_quantity(run, "tip_w@0"), 6) == round(float(run.tip_w[0]), 6)
True
"""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np

from .dynamics import simulate
from .errors import InputError

__all__ = ["SERIES", "series", "run_quantity", "deck_run", "deck_quantities"]

#: Series of every run (the work lines depend on the number of beams).
SERIES = ("tip_u", "tip_w", "tip_angle", "energy", "energy_change", "kinetic", "potential",
          "work", "numerical", "motor_torque")


def series(run, name: str) -> np.ndarray:
    """The named series of a run over its output times ``run.t``."""
    if name in ("tip_u", "tip_w", "tip_angle", "energy", "energy_change", "work",
                "motor_torque"):
        return np.asarray(getattr(run, name), dtype=float)
    if name in run.ledger and name != "total":
        return np.asarray(run.ledger[name], dtype=float)
    known = list(SERIES) + [k for k in run.ledger if k not in SERIES and k != "total"]
    raise InputError(f"unknown series {name!r}, expected one of: {', '.join(known)}")


def run_quantity(run, quantity: str) -> float:
    """The value of ``SERIES@T`` or ``max_abs_SERIES`` (module docstring)."""
    quantity = str(quantity).strip()
    if quantity.startswith("max_abs_"):
        return float(np.max(np.abs(series(run, quantity[len("max_abs_"):]))))
    name, at, time_text = quantity.partition("@")
    if not at:
        raise InputError(f"quantity {quantity!r}: expected SERIES@TIME (e.g. tip_w@1.0) "
                         "or max_abs_SERIES")
    try:
        t = float(time_text)
    except ValueError:
        raise InputError(f"quantity {quantity!r}: {time_text!r} is not a time") from None
    values = series(run, name)
    k = int(np.argmin(np.abs(run.t - t)))
    if not math.isfinite(t) or abs(run.t[k] - t) > 1e-9 * max(1.0, abs(t)):
        raise InputError(f"quantity {quantity!r}: time {t:g} is not an output time of the "
                         "run (add it to &simulate t_out)")
    return float(values[k])


def deck_run(deck):
    """Run a dynamic deck (task simulate) without writing files."""
    if deck.task != "simulate" or not deck.simulate:
        raise InputError(f"{deck.path}: task {deck.task!r} is not a dynamic deck")
    opts = dict(deck.simulate)
    t_out = opts.pop("t_out")
    return simulate(deck.model, deck.load, t_out, **opts)


def deck_quantities(deck, quantities: Iterable[str]) -> dict[str, float]:
    """Run a dynamic deck once and evaluate the named quantities; an unknown
    quantity is an InputError naming the deck."""
    run = deck_run(deck)
    out = {}
    for q in quantities:
        try:
            out[q] = run_quantity(run, q)
        except InputError as exc:
            raise InputError(f"{deck.path}: &published {exc}") from None
    return out
