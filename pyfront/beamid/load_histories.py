"""Load histories of a dynamic experiment (issue 28): a scalar history g(t) --
a table, a half-sine impulse, a step or a linear chirp -- applied at the tip as
a force component, a torque, or the open-loop torque of the Chapter V motor.

Give them to :func:`beamid.simulate` as ``loads={"tip_fy": HalfSine(...)}`` (a
mapping from target to history) or a sequence of ``(target, history)`` pairs
(the same target twice adds up). Targets:

- ``"tip_fx"``, ``"tip_fy"``: a force (N) on the tip in the fixed x or y direction;
- ``"tip_torque"``: a torque (N m, counter-clockwise) on the tip's angle psi
  (generalized force tau grad psi, the exact moment of the static tip load);
- ``"motor_open"``: the open-loop torque of the tip motor, acting as the Chapter V
  motor does, T [(1 + u') dw' - w' du'] (Eq. 151-152), beside its feedback law;
- ``"hub"``: a prescribed hub rotation, a :class:`SpinUp` law or a :class:`Table` of
  the hub angle (rad; a natural cubic spline through the rows, so that the hub rate
  and its derivative are continuous; parameter ``hub_scale``).

Each history is one forcing of the core (``beamid_loads``), with its own work
line in the ledger (named by its target: ``tip_fy``, ``tip_fy_2``, ...) and its
parameters for sensitivities (``wrt=``): ``<name>_amplitude`` (a table's scale)
and, for the half-sine, ``<name>_duration``. Every history is right-continuous,
and the integrators step onto its breakpoints (a table's rows, a pulse's start
and end).
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from . import _check
from ._core_estimation import code_names
from .errors import InputError


def _codes(table: int) -> dict[str, int]:
    """Name -> code (from 1) of a code table of the core (api_code_names)."""
    return {name: index + 1 for index, name in code_names(table).items()}


#: Target names and their codes in the core (beamid_loads TARGET_NAMES, read
#: through api_code_names table 10).
TARGETS = _codes(10)
#: History kinds and their codes (beamid_loads HIST_NAMES, table 11).
_KIND = _codes(11)


def _num(name: str, value, positive: bool = False, nonneg: bool = False) -> float:
    """A finite number (> 0 with ``positive``, >= 0 with ``nonneg``), else an
    InputError naming ``name`` (the package's one checker)."""
    return _check.real(name, value, above=0.0 if positive else None,
                       min=0.0 if nonneg else None)


@dataclass(frozen=True)
class HalfSine:
    """``peak sin(pi (t - start)/duration)`` for start <= t < start + duration,
    else 0: an impact hammer's pulse (N or N m)."""
    peak: float
    duration: float
    start: float = 0.0

    def __post_init__(self):
        _num("HalfSine peak", self.peak)
        _num("HalfSine duration", self.duration, positive=True)
        _num("HalfSine start", self.start)

    def column(self) -> list[float]:
        return [_KIND["half_sine"], self.peak, self.start, self.duration, 0.0, 0.0]


@dataclass(frozen=True)
class Step:
    """``amplitude`` for t >= start, else 0."""
    amplitude: float
    start: float = 0.0

    def __post_init__(self):
        _num("Step amplitude", self.amplitude)
        _num("Step start", self.start)

    def column(self) -> list[float]:
        return [_KIND["step"], self.amplitude, self.start, 0.0, 0.0, 0.0]


@dataclass(frozen=True)
class Chirp:
    """A linear sweep ``amplitude sin(2 pi (f0 s + (f1 - f0) s^2 / (2 duration)))``,
    s = t - start, for 0 <= s < duration, else 0 (frequencies in Hz)."""
    amplitude: float
    f0: float
    f1: float
    duration: float
    start: float = 0.0

    def __post_init__(self):
        _num("Chirp amplitude", self.amplitude)
        _num("Chirp f0", self.f0, nonneg=True)
        _num("Chirp f1", self.f1, nonneg=True)
        _num("Chirp duration", self.duration, positive=True)
        _num("Chirp start", self.start)

    def column(self) -> list[float]:
        return [_KIND["chirp"], self.amplitude, self.start, self.duration, self.f0, self.f1]


@dataclass(frozen=True)
class Table:
    """Piecewise linear through the rows (t_i, scale v_i); the first value
    before the first row, the last after the last row. Times must increase."""
    times: tuple
    values: tuple
    scale: float = 1.0
    source: str = "table"

    def __post_init__(self):
        t = _check.reals(f"{self.source}: times", self.times, scalar=True)
        v = _check.reals(f"{self.source}: values", self.values, scalar=True)
        object.__setattr__(self, "times", tuple(t))
        object.__setattr__(self, "values", tuple(v))
        _num("Table scale", self.scale)
        if t.size == 0 or t.size != v.size:
            raise InputError(f"{self.source}: {t.size} times and {v.size} values, expected "
                             "the same number (at least one row)")
        for i in range(t.size):
            if not (math.isfinite(t[i]) and math.isfinite(v[i])):
                raise InputError(f"{self.source}: row {i + 1}: t = {t[i]}, value = {v[i]}, "
                                 "expected finite numbers")
            if i and not t[i] > t[i - 1]:
                raise InputError(f"{self.source}: row {i + 1}: t = {t[i]} is not after row "
                                 f"{i}'s t = {t[i - 1]} (times must increase)")

    @classmethod
    def from_csv(cls, path: str | Path, column: str, time: str = "t",
                 scale: float = 1.0) -> "Table":
        """The rows of a CSV file with a header: ``time`` and ``column``. A bad
        entry is named by file, line and field."""
        path = _check.path("Table.from_csv: path", path)
        column = _check.text("Table.from_csv: column", column)
        time = _check.text("Table.from_csv: time", time)
        try:
            text = path.read_text()
        except OSError as exc:
            raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
        rows = list(csv.reader(text.splitlines()))
        if not rows:
            raise InputError(f"{path}: empty, expected a header with {time!r} and {column!r}")
        head = [h.strip() for h in rows[0]]
        for name in (time, column):
            if name not in head:
                raise InputError(f"{path}: line 1: no column {name!r} (header: "
                                 f"{', '.join(head)})")
        it, iv = head.index(time), head.index(column)
        ts, vs = [], []
        for ln, row in enumerate(rows[1:], start=2):
            if not row or all(not c.strip() for c in row):
                continue
            for idx, name, out in ((it, time, ts), (iv, column, vs)):
                try:
                    out.append(float(row[idx]))
                except (ValueError, IndexError):
                    raise InputError(f"{path}: line {ln}: field {name!r} = "
                                     f"{row[idx] if idx < len(row) else ''!r}, expected a "
                                     "number") from None
            if len(ts) > 1 and not ts[-1] > ts[-2]:
                raise InputError(f"{path}: line {ln}: field {time!r} = {ts[-1]} is not after "
                                 f"the previous row's {ts[-2]} (times must increase)")
        return cls(tuple(ts), tuple(vs), scale, source=str(path))

    def column(self) -> list[float]:
        return [_KIND["table"], self.scale, 0.0, 0.0, 0.0, 0.0]


@dataclass(frozen=True)
class SpinUp:
    """The prescribed hub rotation of the spin-up law (target ``"hub"``):
    theta(t) = (w_s/T) [t^2/2 + (T/(2 pi))^2 (cos(2 pi t/T) - 1)] for t <= T, then
    w_s (t - T/2); the arm's equations in the hub frame (docs/loads.md)."""
    w_s: float
    T: float

    def __post_init__(self):
        _num("SpinUp w_s", self.w_s)
        _num("SpinUp T", self.T, positive=True)

    def column(self) -> list[float]:
        return [_KIND["spin_up"], self.w_s, 0.0, self.T, 0.0, 0.0]

    def angle(self, t) -> np.ndarray:
        """theta(t) (rad); a number for a number, an array for a sequence."""
        one = _check._is_real(t)
        t = _check.reals("SpinUp.angle: t", t, scalar=True)
        ws, T = self.w_s, self.T
        up = ws / T * (t**2 / 2 + (T / (2 * np.pi))**2 * (np.cos(2 * np.pi * t / T) - 1))
        theta = np.where(t <= T, up, ws * (t - T / 2))
        return float(theta[0]) if one else theta


History = HalfSine | Step | Chirp | Table | SpinUp


def _pairs(loads) -> list[tuple[str, History]]:
    if isinstance(loads, Mapping):
        items = list(loads.items())
    elif isinstance(loads, Sequence) and not isinstance(loads, str):
        items = list(loads)
    else:
        raise InputError(f"loads = {loads!r}, expected a mapping target -> history or a "
                         "sequence of (target, history) pairs")
    out = []
    for item in items:
        if not (isinstance(item, tuple) and len(item) == 2):
            raise InputError(f"loads: {item!r}, expected a (target, history) pair")
        target, hist = item
        if target not in TARGETS:
            raise InputError(f"loads: target {target!r}, expected one of "
                             f"{', '.join(TARGETS)}")
        if target == "hub":
            if not isinstance(hist, (SpinUp, Table)):
                raise InputError(f"loads['hub'] = {hist!r}, expected a SpinUp or a Table "
                                 "of the hub angle (rad)")
            if isinstance(hist, Table) and len(hist.times) < 2:
                raise InputError(f"{hist.source}: the hub angle table needs at least 2 rows")
        elif not isinstance(hist, (HalfSine, Step, Chirp, Table)):
            raise InputError(f"loads[{target!r}] = {hist!r}, expected a HalfSine, Step, "
                             "Chirp or Table")
        out.append((target, hist))
    return out


def read_loads_csv(path: str | Path) -> list[tuple[str, Table]]:
    """The load histories of a CSV file with a header: a column ``t`` and one
    column per target (``tip_fx``, ``tip_fy``, ``tip_torque``, ``motor_open``,
    ``hub``), each a :class:`Table` (``beamid simulate --loads``). A bad entry is
    named by file, line and field."""
    path = Path(path)
    try:
        head = path.read_text().splitlines()[:1]
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None
    names = [h.strip() for h in head[0].split(",")] if head else []
    if "t" not in names:
        raise InputError(f"{path}: line 1: no column 't' (header: {', '.join(names)})")
    targets = [n for n in names if n != "t"]
    for n in targets:
        if n not in TARGETS:
            raise InputError(f"{path}: line 1: column {n!r} is not a target; expected t and "
                             f"some of {', '.join(TARGETS)}")
    if not targets:
        raise InputError(f"{path}: line 1: no load column (expected some of "
                         f"{', '.join(TARGETS)})")
    return [(n, Table.from_csv(path, n)) for n in targets]


def columns(loads) -> tuple[np.ndarray, np.ndarray]:
    """The core's layout of ``loads``: spec (9, nld) and table rows (2, ntab)."""
    pairs = _pairs(loads)
    spec = np.zeros((9, max(1, len(pairs))), order="F")
    rows: list[tuple[float, float]] = []
    for j, (target, hist) in enumerate(pairs):
        kind, amp, start, dur, f0, f1 = hist.column()
        first, count = 0, 0
        if isinstance(hist, Table):
            first, count = len(rows) + 1, len(hist.times)
            rows.extend(zip(hist.times, hist.values))
        spec[:, j] = [TARGETS[target], kind, amp, start, dur, f0, f1, first, count]
    tab = np.zeros((2, max(1, len(rows))), order="F")
    if rows:
        tab[:, :] = np.array(rows, dtype=float).T
    return spec[:, :len(pairs)] if pairs else spec[:, :0], tab


def highest_chirp(loads) -> float:
    """The highest frequency (Hz) any chirp of ``loads`` reaches (0 without one)."""
    return max((max(h.f0, h.f1) for _, h in _pairs(loads) if isinstance(h, Chirp)),
               default=0.0)


def from_columns(spec, tab) -> list[tuple[str, History]]:
    """The (target, history) pairs of the core's columns: spec (9, n) in
    beamid_loads' layout (a deck's &history groups), table rows tab (2, :)."""
    spec = np.asarray(spec, dtype=float).reshape(9, -1)
    tab = np.asarray(tab, dtype=float).reshape(2, -1)
    names = {code: name for name, code in TARGETS.items()}
    out: list[tuple[str, History]] = []
    for target, kind, amp, start, dur, f0, f1, first, count in spec.T:
        kind, first, count = int(kind), int(first), int(count)
        if kind == _KIND["table"]:
            rows = tab[:, first - 1:first - 1 + count]
            hist: History = Table(tuple(rows[0]), tuple(rows[1]), scale=amp)
        elif kind == _KIND["half_sine"]:
            hist = HalfSine(amp, dur, start)
        elif kind == _KIND["step"]:
            hist = Step(amp, start)
        elif kind == _KIND["chirp"]:
            hist = Chirp(amp, f0, f1, dur, start)
        else:
            hist = SpinUp(amp, dur)
        out.append((names[int(target)], hist))
    return out
