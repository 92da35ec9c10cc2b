"""Logger files and sensors: from a rig's wide CSV to :class:`Measurements`.

A data logger writes a time column and one column per channel::

    t,gauge_root,acc_tip
    0.000,1.21e-3,0.157
    0.002,1.20e-3,0.161

A channel is named by its observation (``strain@1:0.05``, ``x_tip``; see
:mod:`beamid.observations`) or by a sensor of a sensor table that says
which observation it is and its sigma (:class:`Sensor`).
:func:`read_channels` turns the file (or a pandas DataFrame of the same
shape) into the long table ``experiment,t,quantity,value,sigma`` that every
fit, compare and diagnosis takes.
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from . import _check, observations
from .errors import InputError
from .measurements import Measurements

__all__ = ["Sensor", "read_channels", "as_frame_columns"]

#: Accepted names of the time column (the first column).
TIME_HEADERS = ("t", "time", "time_s", "t_s")


@dataclass(frozen=True)
class Sensor:
    """A channel of the rig: its name in the logger file, the observation it
    makes (``strain@1:0.05``, ``accel_n@2:0.714``, ``x_tip`` ...) and the
    standard deviation of one reading (None: the ``sigma`` of
    :func:`read_channels`)."""

    name: str
    observation: str
    sigma: float | None = None

    def __post_init__(self) -> None:
        _check.text("Sensor: name", self.name)
        if not self.name.strip():
            _check.fail("Sensor: name", self.name, "a channel name")
        _check.text(f"Sensor {self.name!r}: observation", self.observation)
        try:
            observations.parse(self.observation)
        except InputError as exc:
            raise InputError(f"Sensor {self.name!r}: observation = {self.observation!r}: "
                             f"{str(exc).split(': ', 1)[-1]}") from None
        _check.real(f"Sensor {self.name!r}: sigma", self.sigma, above=0.0, none=True)


def _is_frame(x: Any) -> bool:
    return type(x).__name__ == "DataFrame" and hasattr(x, "columns")


def as_frame_columns(frame: Any) -> tuple[list[str], list[np.ndarray]]:
    """The column names and columns of a pandas DataFrame (pandas itself is
    not imported: any object with ``columns`` and ``[name]`` will do)."""
    names = [str(c) for c in frame.columns]
    columns = []
    for c in frame.columns:
        try:
            columns.append(np.asarray(frame[c], dtype=float))
        except (TypeError, ValueError):
            raise InputError(f"<DataFrame>: column {c!r} holds {_check.show(list(frame[c]))}, "
                             "expected numbers") from None
    return names, columns


def _read_wide(path: Path) -> tuple[list[str], list[list[str]], list[int]]:
    """Header, rows and their source lines of a wide CSV (# comments and
    blank lines skipped)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise InputError(f"cannot open logger file {path}: no such file") from None
    except OSError as exc:
        raise InputError(f"cannot read logger file {path}: {exc.strerror}") from None
    header: list[str] | None = None
    hline = 0
    rows, lines = [], []
    for k, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = [f.strip() for f in next(csv.reader([line]))]
        if header is None:
            header, hline = fields, k
            continue
        if len(fields) != len(header):
            raise InputError(f"{path}, line {k}: expected {len(header)} fields "
                             f"({','.join(header)}), got {len(fields)}")
        rows.append(fields)
        lines.append(k)
    if header is None:
        raise InputError(f"{path}: no header line (a time column, then one column per "
                         "channel)")
    return header, rows, [hline] + lines


def read_channels(source: str | os.PathLike | Any, experiment: str, *,
                  sigma: float | Mapping[str, float] | None = None,
                  sensors: Sequence[Sensor] = (), t_offset: float = 0.0) -> Measurements:
    """Read a logger's wide CSV (or a pandas DataFrame) into Measurements.

    Parameters
    ----------
    source:
        A CSV file whose first column is the time (``t`` or ``time``, in s)
        and every other column a channel; or a DataFrame of that shape.
    experiment:
        The experiment every row belongs to (e.g. ``'free'``).
    sigma:
        The standard deviation of a reading: one number for every channel,
        or a mapping channel -> sigma. A sensor's own sigma comes first.
    sensors:
        The sensor table: :class:`Sensor` entries naming channels. A
        channel that is no sensor must be an observation name itself.
    t_offset:
        Added to every time (a record that starts before the release).

    Raises
    ------
    InputError
        Naming the file, line and field: a header matching no sensor and no
        observation, a non-numeric or missing value, a channel without sigma.
    """
    experiment = _check.text("read_channels: experiment", experiment)
    t_offset = _check.real("read_channels: t_offset", t_offset)
    if isinstance(sigma, Mapping):
        sigma = _check.mapping("read_channels: sigma", sigma)
    else:
        sigma = _check.real("read_channels: sigma", sigma, above=0.0, none=True,
                            expected="a number > 0, a mapping channel -> sigma or None")
    if isinstance(sensors, (str, bytes, Sensor)) or not isinstance(sensors, Sequence):
        _check.fail("read_channels: sensors", sensors, "a sequence of beamid.Sensor")
    table = {}
    for s in sensors:
        _check.instance("read_channels: sensors[]", s, Sensor, "beamid.Sensor")
        table[s.name] = s
    if _is_frame(source):
        where = "<DataFrame>"
        header, columns = as_frame_columns(source)
        lines = list(range(1, len(columns[0]) + 1)) if columns else []
        first_line = 0
    else:
        if not isinstance(source, (str, os.PathLike)):
            _check.fail("read_channels: source", source, "a file path or a pandas DataFrame")
        path = _check.path("read_channels: source", source)
        where = str(path)
        header, rows, lines = _read_wide(path)
        first_line, lines = lines[0], lines[1:]
        columns = []
        for j, name in enumerate(header):
            col = np.empty(len(rows))
            for i, row in enumerate(rows):
                try:
                    col[i] = float(row[j]) if row[j] else math.nan
                except ValueError:
                    raise InputError(f"{where}, line {lines[i]}: field {name} = {row[j]!r}, "
                                     "expected a number") from None
            columns.append(col)
    hw = f"{where}, line {first_line}" if first_line else where
    if not header or header[0].lower() not in TIME_HEADERS:
        raise InputError(f"{hw}: the first column is {header[0] if header else ''!r}, "
                         f"expected the time ({' or '.join(TIME_HEADERS[:2])})")
    if len(header) < 2:
        raise InputError(f"{hw}: no channel column after the time")
    quantities, sigmas = [], []
    for name in header[1:]:
        if name in table:
            q, sig = table[name].observation, table[name].sigma
        else:
            try:
                observations.parse(name)
            except InputError:
                known = ", ".join(table) or "none"
                raise InputError(f"{hw}: channel header {name!r} matches no sensor (sensors: "
                                 f"{known}) and is no observation (kind or kind@beam:s)"
                                 ) from None
            q, sig = name, None
        if sig is None:
            sig = sigma.get(name) if isinstance(sigma, Mapping) else sigma
        if sig is None:
            raise InputError(f"{hw}: channel {name!r} has no sigma: give sigma= or a "
                             "Sensor with one")
        quantities.append(q)
        sigmas.append(_check.real(f"{hw}: sigma of channel {name!r}", sig, above=0.0))
    t = columns[0] + float(t_offset)
    exps, ts, qs, vs, ss, ls = [], [], [], [], [], []
    for i in range(t.size):
        for c, q in enumerate(quantities):
            v = columns[c + 1][i]
            if math.isnan(v):
                continue          # a channel not sampled at this time
            exps.append(experiment)
            ts.append(t[i])
            qs.append(q)
            vs.append(v)
            ss.append(sigmas[c])
            ls.append(lines[i] if i < len(lines) else 0)
    return Measurements(tuple(exps), np.array(ts), tuple(qs), np.array(vs), np.array(ss),
                        source=where, lines=tuple(ls))
