"""Measurement tables: CSV files with rows ``experiment,t,quantity,value,sigma``.

>>> import beamid, io, pathlib, tempfile
>>> p = pathlib.Path(tempfile.mkdtemp()) / "d.csv"
>>> _ = p.write_text("# tip deflection\\nexperiment,t,quantity,value,sigma\\nF3,0,y_tip,0.2763,0.001\\n")
>>> beamid.read_measurements(p).value
array([0.2763])

``t`` is 0 for static experiments; ``sigma`` > 0 is the standard deviation of
the row; an empty ``sigma`` (NaN) is not given: :func:`beamid.fit` then
estimates it (``estimate_sigma``) or refuses the row. Every row is validated; a bad one raises :class:`beamid.InputError`
naming the file, the line and the field.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields
from typing import Iterable, Mapping, Sequence

import numpy as np

from . import _check, _core, observations
from .errors import InputError, _write_text
from .loads import RadialWire, family

#: Observation kinds, in code order (the Fortran table, beamid_observations);
#: u_tip = x_tip - (L1 + L2), w_tip = y_tip. A station kind is written
#: ``kind@beam:s`` (beamid.observations).
QUANTITIES = _core.quantity_labels()


def quantity_unit(quantity: str) -> str:
    """The unit of a measured quantity (``m``, ``rad``, ``N``, ``N m``, ...):
    the core's observation table (beamid.observations); a name that is no
    observation is read by its words (angle: rad, moment or torque: N m,
    force: N, else m)."""
    try:
        return observations.unit(quantity)
    except InputError:
        pass
    q = quantity.lower()
    if "angle" in q:
        return "rad"
    if "moment" in q or "torque" in q:
        return "N m"
    if "force" in q:
        return "N"
    return "m"
HEADER = ("experiment", "t", "quantity", "value", "sigma")


def _needs(name: str) -> str:
    """What an experiment needs to make observation ``name`` (the core's
    table: "none", "wire" or "motor")."""
    return observations.kinds()[observations.parse(name).kind].needs


def _canonical(name: str) -> str:
    """The core's name of an observation (x@2:0.7140 and x@2:0.714 are one)."""
    return name if name in QUANTITIES else observations.parse(name).label


@dataclass(frozen=True)
class Measurements:
    """A validated table of measurements (one entry per row, in file order).

    ``lines`` holds the source line of each row (0 for rows made in Python),
    so later checks (an experiment a deck does not define) can name it.
    """

    experiment: tuple[str, ...]
    t: np.ndarray
    quantity: tuple[str, ...]
    value: np.ndarray
    sigma: np.ndarray
    source: str = "<python>"
    lines: tuple[int, ...] = field(default=())

    def __repr__(self) -> str:
        # a summary, not every row (``rows()`` and the fields hold them)
        exps = list(dict.fromkeys(self.experiment))
        qs = list(dict.fromkeys(self.quantity))
        return (f"<Measurements: {len(self.experiment)} rows from {self.source}; "
                f"experiments {', '.join(exps[:6])}{' ...' if len(exps) > 6 else ''}; "
                f"quantities {', '.join(qs[:6])}{' ...' if len(qs) > 6 else ''}>")

    def __post_init__(self) -> None:
        object.__setattr__(self, "experiment",
                           _check.names("measurements: experiment", self.experiment))
        object.__setattr__(self, "quantity",
                           _check.names("measurements: quantity", self.quantity))
        _check.text("measurements: source", self.source)
        n = len(self.experiment)
        for name in ("t", "value", "sigma"):
            # non-finite entries are named by row below; a NaN sigma is not given
            value, missing = getattr(self, name), None
            if name == "sigma" and isinstance(value, (np.ndarray, list, tuple)):
                try:
                    value = np.array(value, dtype=np.float64)
                except (TypeError, ValueError):
                    pass
                else:
                    missing = np.isnan(value) if value.ndim == 1 else None
                    if missing is not None:
                        value = np.where(missing, 1.0, value)
            arr = _check.reals(f"measurements: {name}", value, finite=False)
            if missing is not None:
                arr[missing] = math.nan
            if arr.shape != (n,):
                raise InputError(f"measurements: {name} has {arr.size} entries for {n} rows")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        lines = self.lines
        if isinstance(lines, (str, bytes)) or not isinstance(lines, (tuple, list)) or \
                not all(_check.is_int(k) and k >= 0 for k in lines):
            _check.fail("measurements: lines", lines, "a tuple of source line numbers >= 0")
        object.__setattr__(self, "lines", tuple(int(k) for k in lines))
        if len(self.quantity) != n:
            raise InputError(f"measurements: quantity has {len(self.quantity)} entries for "
                             f"{n} rows")
        if not self.lines:
            object.__setattr__(self, "lines", (0,) * n)
        seen: dict[tuple[str, float, str], int] = {}
        for i in range(n):
            where = self._where(i)
            if self.quantity[i] not in QUANTITIES:
                try:
                    observations.parse(self.quantity[i])
                except InputError as exc:
                    if "unknown observation kind" in str(exc):
                        raise InputError(f"{where}: field quantity = {self.quantity[i]!r}, "
                                         f"expected one of {', '.join(QUANTITIES)}") from None
                    raise InputError(f"{where}: field quantity = {self.quantity[i]!r}: "
                                     f"{str(exc).split(': ', 1)[-1]}") from None
            for name in ("t", "value", "sigma"):
                v = float(getattr(self, name)[i])
                if not math.isfinite(v) and not (name == "sigma" and math.isnan(v)):
                    raise InputError(f"{where}: field {name} = {v}, expected a finite number")
            if not self.sigma[i] > 0.0 and not math.isnan(self.sigma[i]):
                raise InputError(f"{where}: field sigma = {self.sigma[i]:g}, expected "
                                 "sigma > 0 (the standard deviation of the row)")
            if self.t[i] < 0.0:
                raise InputError(f"{where}: field t = {self.t[i]:g}, expected t >= 0")
            key = (self.experiment[i], float(self.t[i]), _canonical(self.quantity[i]))
            if key in seen:
                raise InputError(f"{where}: duplicate row: experiment {key[0]!r}, t = "
                                 f"{key[1]:g}, quantity {key[2]!r} already given "
                                 f"({self._where(seen[key])})")
            seen[key] = i

    def _where(self, i: int) -> str:
        line = self.lines[i] if i < len(self.lines) else 0
        return f"{self.source}, line {line}" if line else f"{self.source}, row {i + 1}"

    def __len__(self) -> int:
        return len(self.experiment)

    @classmethod
    def from_rows(cls, rows: Iterable[Sequence], source: str = "<python>") -> "Measurements":
        """Build from ``(experiment, t, quantity, value, sigma)`` tuples
        (sigma None: not given, NaN)."""
        _check.text("source", source)
        if isinstance(rows, (str, bytes, Mapping)) or not isinstance(rows, Iterable):
            _check.fail("rows", rows, "an iterable of (experiment, t, quantity, value, sigma)")
        rows = list(rows)
        for k, row in enumerate(rows, start=1):
            if isinstance(row, (str, bytes)) or not isinstance(row, Sequence) or len(row) != 5:
                raise InputError(f"{source}, row {k}: expected 5 fields "
                                 f"({','.join(HEADER)}), got {_check.show(row)}")
            for j in (0, 2):
                _check.text(f"{source}, row {k}: field {HEADER[j]}", row[j])
            for j in (1, 3, 4):    # NaN and infinities are named by Measurements
                if j == 4 and row[4] is None:    # sigma not given (NaN)
                    continue
                _check.real(f"{source}, row {k}: field {HEADER[j]}", row[j], finite=False,
                            expected="a number")
        return cls(experiment=tuple(str(r[0]) for r in rows),
                   t=np.array([float(r[1]) for r in rows]),
                   quantity=tuple(str(r[2]) for r in rows),
                   value=np.array([float(r[3]) for r in rows]),
                   sigma=np.array([math.nan if r[4] is None else float(r[4]) for r in rows]),
                   source=source)

    @classmethod
    def from_frame(cls, frame, source: str = "<DataFrame>") -> "Measurements":
        """Build from a pandas DataFrame with the columns experiment, t,
        quantity, value, sigma (the long format; pandas itself is not
        imported here)."""
        source = _check.text("from_frame: source", source)
        try:
            cols = [str(c) for c in getattr(frame, "columns", ())]
        except TypeError:
            _check.fail("from_frame: frame", frame, "a pandas DataFrame")
        missing = [h for h in HEADER if h not in cols]
        if missing:
            raise InputError(f"{source}: columns {cols}, expected {', '.join(HEADER)} "
                             f"(missing {', '.join(missing)})")
        try:
            return cls(experiment=tuple(str(e) for e in frame["experiment"]),
                       t=np.asarray(frame["t"], float),
                       quantity=tuple(str(q) for q in frame["quantity"]),
                       value=np.asarray(frame["value"], float),
                       sigma=np.asarray(frame["sigma"], float), source=source)
        except (TypeError, ValueError, KeyError) as exc:
            raise InputError(f"{source}: the columns t, value and sigma must hold numbers "
                             f"({exc})") from None

    def to_frame(self):
        """The table as a pandas DataFrame (pandas must be installed)."""
        try:
            import pandas as pd
        except ImportError:
            raise InputError("to_frame needs pandas: pip install pandas") from None
        return pd.DataFrame({"experiment": list(self.experiment), "t": self.t,
                             "quantity": list(self.quantity), "value": self.value,
                             "sigma": self.sigma})

    def rows(self) -> list[tuple[str, float, str, float, float]]:
        """The rows as tuples."""
        return [(e, float(t), q, float(v), float(s)) for e, t, q, v, s in
                zip(self.experiment, self.t, self.quantity, self.value, self.sigma)]

    def with_values(self, value: Sequence[float]) -> "Measurements":
        """Same rows with new values (e.g. noisy copies)."""
        value = _check.reals("value", value, finite=False)   # NaN: named by row
        if value.shape == (len(self),) and np.isfinite(value).all():
            # only the values are new and they are valid: the rows were checked
            # when this table was built (consistency makes a table a replicate)
            new = object.__new__(Measurements)
            for f in fields(self):
                object.__setattr__(new, f.name, getattr(self, f.name))
            value = np.array(value, dtype=np.float64)
            value.setflags(write=False)
            object.__setattr__(new, "value", value)
            return new
        return Measurements(self.experiment, self.t, self.quantity, value,
                            self.sigma, self.source, self.lines)

    def merge(self, other: "Measurements") -> "Measurements":
        """This table followed by the rows of ``other`` (e.g. simulated rows of
        a planned experiment). A row of ``other`` with the same (experiment,
        t, quantity) as a row here is an InputError naming both."""
        if not isinstance(other, Measurements):
            raise InputError(f"merge: expected beamid.Measurements, got {type(other).__name__}")
        here = {(e, float(t), q): i for i, (e, t, q) in
                enumerate(zip(self.experiment, self.t, self.quantity))}
        for j, key in enumerate(zip(other.experiment, other.t, other.quantity)):
            i = here.get((key[0], float(key[1]), key[2]))
            if i is not None:
                raise InputError(f"merge: duplicate row: experiment {key[0]!r}, t = "
                                 f"{key[1]:g}, quantity {key[2]!r} is in both "
                                 f"{self._where(i)} and {other._where(j)}")
        source = self.source if self.source == other.source else \
            f"{self.source} + {other.source}"
        return Measurements(self.experiment + other.experiment,
                            np.concatenate([self.t, other.t]),
                            self.quantity + other.quantity,
                            np.concatenate([self.value, other.value]),
                            np.concatenate([self.sigma, other.sigma]), source,
                            tuple(self.lines) + tuple(other.lines))

    def check_experiments(self, experiments: Mapping[str, object]) -> None:
        """Raise InputError, naming the row, for a row the experiments cannot
        predict: an experiment that is not defined; and where the experiment
        is one of beamid's (TipForce, TipMoment, RadialWire, Release): a
        static experiment's row at t != 0, motor_torque of a static experiment
        or of a release without a motor, wire_force of a release or of a load
        without a wire. The same rules and messages as beamid-batch's reader
        of estimation decks (beamid_measurements::check_static_rows)."""
        experiments = _check.mapping("experiments", experiments)
        for i, name in enumerate(self.experiment):
            if name not in experiments:
                known = ", ".join(experiments) or "none"
                raise InputError(f"{self._where(i)}: field experiment = {name!r} is not "
                                 f"defined (experiments: {known})")
        # what an experiment can measure is its core family's (loads.family)
        fams = {e: getattr(family(x), "name", "") for e, x in experiments.items()}
        for i, (e, q) in enumerate(zip(self.experiment, self.quantity)):
            x = experiments[e]
            but = f"{self._where(i)}: field quantity = {q!r}, but experiment {e!r}"
            fam = fams[e]
            if fam == "modal":
                if observations.can_measure(q, "modal"):
                    raise InputError(f"{but} is a modal test (it measures freq[k], "
                                     "damping[k] and shape_*@b:s[k])")
                if self.t[i] != 0.0:
                    raise InputError(f"{self._where(i)}: field t = {self.t[i]:g}, expected 0 "
                                     f"for the modal experiment {e!r}")
                continue
            if fam == "release":
                why = observations.can_measure(q, "release", has_motor=x.has_motor)
                if why == "family" and _needs(q) == "wire":
                    raise InputError(f"{but} is a release (no wire)")
                if why == "family" and not observations.can_measure(q, "modal"):
                    raise InputError(f"{but} is a release (only a modal experiment "
                                     f"measures {observations.parse(q).kind})")
                if why == "family":
                    raise InputError(f"{but} is a release (only a static experiment "
                                     f"measures {observations.parse(q).kind})")
                if why == "motor":
                    raise InputError(f"{but} has no motor (motor_gain = 0)")
            elif fam == "static":
                why = observations.can_measure(q, "static",
                                               has_wire=isinstance(x, RadialWire))
                if why == "family" and _needs(q) == "motor":
                    raise InputError(f"{but} is static (no motor)")
                if why == "family" and not observations.can_measure(q, "modal"):
                    raise InputError(f"{but} is static (only a modal experiment measures "
                                     f"{observations.parse(q).kind})")
                if why == "family":
                    raise InputError(f"{but} is static (only a release experiment measures "
                                     f"{observations.parse(q).kind})")
                if self.t[i] != 0.0:
                    raise InputError(f"{self._where(i)}: field t = {self.t[i]:g}, expected 0 "
                                     f"for the static experiment {e!r}")
                if why == "wire":
                    raise InputError(f"{but} has no wire")

    def write(self, path: str | os.PathLike, comment: str = "") -> None:
        """Write the table as CSV (readable by read_measurements and beamid-batch)."""
        path = _check.path("path", path)
        comment = _check.text("comment", comment, empty=True)
        lines = [f"# {c}" for c in comment.splitlines()] + [",".join(HEADER)]
        lines += [f"{e},{t:.17g},{q},{v:.17g},{'' if math.isnan(s) else f'{s:.17g}'}"
                  for e, t, q, v, s in self.rows()]
        _write_text(path, "\n".join(lines) + "\n")


def read_measurements(path: str | os.PathLike,
                      experiments: Mapping[str, object] | None = None) -> Measurements:
    """Read and validate a measurement CSV file (with the Fortran reader of
    beamid-batch, ``beamid_measurements``, so both fronts accept and refuse
    the same files with the same message).

    Parameters
    ----------
    path:
        CSV file: ``#`` comments and blank lines, then the header
        ``experiment,t,quantity,value,sigma``, then one row per measurement.
    experiments:
        Optional mapping of the defined experiment names to their experiments
        (a dict of loads and releases, as ``fit`` takes): a row naming another
        experiment is an error, and so is a row the experiment cannot produce
        (``Measurements.check_experiments``: a static experiment's row at
        t != 0, motor_torque without a motor, wire_force without a wire).

    Raises
    ------
    InputError
        Missing file or header, wrong field count, unknown quantity,
        non-numeric or non-finite value or t, t < 0, sigma <= 0, duplicate row,
        undefined experiment, a row its experiment cannot produce: the message
        names the file, the line and the field; a
        path that is not a str or os.PathLike names the argument.
    """
    if type(path).__name__ == "DataFrame" and hasattr(path, "columns"):
        data = Measurements.from_frame(path)
        if experiments is not None:
            data.check_experiments(experiments)
        return data
    path = _check.path("read_measurements: path", path)
    if path.is_dir():
        raise InputError(f"cannot read measurement file {path}: it is a directory")
    names, t, quantity, value, sigma, lines = _core.read_measurements(str(path))
    data = Measurements(names, t, quantity, value, sigma, source=str(path), lines=lines)
    if experiments is not None:
        data.check_experiments(experiments)
    return data
