"""Arc-length static solver (Chapter III) from Python.

>>> import beamid
>>> m = beamid.pace(axial_coupling=0.0, C1=5.0, C2=20.0)
>>> r = beamid.solve_static(m, beamid.RadialWire(1.3), wrt=("EI1", "C2"))
>>> round(r.wire_force, 2)
66.0
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, NamedTuple

import numpy as np

from . import _check, _core
from .errors import InputError, check_memory
from .loads import Load, RadialWire, TipLoad
from .model import Model

#: Outputs of a static solve, in the order the Fortran core returns them.
OUTPUTS = ("tip_x", "tip_y", "tip_angle", "wire_force", "elbow_x", "elbow_y",
           "elbow_angle", "root_moment")
#: Measurement-style aliases (x_tip = tip_x ...), accepted as keys of ``d``.
ALIASES = {"x_tip": "tip_x", "y_tip": "tip_y", "x_elbow": "elbow_x", "y_elbow": "elbow_y"}


class Shape(NamedTuple):
    """Deformed shape on an arc-length grid: s, x, y, psi (rad), moment (N m)."""

    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    psi: np.ndarray
    moment: np.ndarray


def _output(name: str, doc: str) -> property:
    """A read-only float attribute of a :class:`StaticResult`: output ``name``."""
    i = OUTPUTS.index(name)

    def get(self: "StaticResult") -> float:
        return float(self._outputs[i])

    return property(get, doc=doc)


@dataclass(eq=False, repr=False, slots=True, init=False)
class StaticResult:
    """Converged static solution.

    ``d[output][param]`` is the sensitivity of an output to a parameter named
    in ``wrt``; outputs are those of :data:`OUTPUTS` (and the aliases
    ``x_tip``, ``y_tip``, ``x_elbow``, ``y_elbow``).
    """

    model: Model
    load: Load
    wrt: tuple[str, ...]
    _outputs: np.ndarray
    _doutputs: np.ndarray
    unknowns: np.ndarray
    newton_iterations: int = 0
    load_steps: int = 0
    tol: float = 0.0
    _d: dict[str, dict[str, float]] | None = field(default=None, init=False)

    def __init__(self, model: Model, load: Load, wrt: tuple[str, ...], outputs: np.ndarray,
                 doutputs: np.ndarray, unknowns: np.ndarray, newton_iterations: int = 0,
                 load_steps: int = 0, tol: float = 0.0) -> None:
        # the public keywords outputs/doutputs (the fields are private: the
        # properties outputs and d read them)
        self.model, self.load, self.wrt, self.unknowns = model, load, wrt, unknowns
        self._outputs, self._doutputs, self._d = outputs, doutputs, None
        self.newton_iterations, self.load_steps, self.tol = newton_iterations, load_steps, tol

    @property
    def outputs(self) -> dict[str, float]:
        """Every output by name (a fresh dict)."""
        return {name: float(v) for name, v in zip(OUTPUTS, self._outputs)}

    @property
    def d(self) -> dict[str, dict[str, float]]:
        """Sensitivities d[output][parameter] for the parameters in ``wrt``."""
        if self._d is None:
            d = {name: {p: float(self._doutputs[i, j]) for j, p in enumerate(self.wrt)}
                 for i, name in enumerate(OUTPUTS)}
            for alias, name in ALIASES.items():
                d[alias] = d[name]
            self._d = d
        return self._d

    def sensitivity_matrix(self) -> np.ndarray:
        """d outputs / d wrt as an array (len(OUTPUTS) x len(wrt))."""
        return np.array(self._doutputs)

    def __repr__(self) -> str:
        wire = "" if math.isnan(self.wire_force) else f", wire_force={self.wire_force:.6g}"
        return (f"StaticResult(tip_x={self.tip_x:.6g}, tip_y={self.tip_y:.6g}, "
                f"tip_angle={self.tip_angle:.6g}{wire})")

    tip_x = _output("tip_x", "Tip x (m).")
    tip_y = _output("tip_y", "Tip y (m).")
    tip_angle = _output("tip_angle", "Tangent angle at the tip from +x (rad).")
    wire_force = _output("wire_force", "Wire tension (N); nan without a wire.")
    elbow_x = _output("elbow_x", "Elbow x (m).")
    elbow_y = _output("elbow_y", "Elbow y (m).")
    root_moment = _output("root_moment", "Bending moment at the root (N m).")

    def shape(self, n: int = 101, s: Iterable[float] | None = None) -> Shape:
        """The shape at ``n`` equally spaced arc positions (or at the given ``s``)."""
        total = self.model.total_length
        if s is None:
            n = _check.count("shape n", n, min=2,
                             expected="an integer, at least 2 (points)")
            check_memory(5 * 8 * int(n), f"shape n = {n}: the shape", ".2g")
            grid = np.linspace(0.0, total, int(n))
        else:
            try:
                grid = np.asarray(list(np.atleast_1d(s)), dtype=float)
            except (TypeError, ValueError):
                raise InputError(f"shape s = {s!r}, expected arc positions (numbers)") from None
            bad = ~np.isfinite(grid) | (grid < 0.0) | (grid > total * (1 + 1e-12))
            if grid.ndim != 1 or bad.any():
                first = grid[bad][0] if bad.any() else grid
                raise InputError(f"shape s = {first}, expected finite arc positions in "
                                 f"[0, {total:g}] (the total length, m)")
        kind, values = self.load.encode()
        x, y, psi, moment = _core.static_shape(self.model.nbeams, self.model.vector(), kind,
                                               values, self.unknowns, grid, self.tol)
        return Shape(grid, x, y, psi, moment)


def solve_static(model: Model, load: Load, wrt: Iterable[str] = (),
                 tol: float | None = None) -> StaticResult:
    """Solve the static deformation of ``model`` under ``load``.

    Parameters
    ----------
    model:
        The beam chain (:func:`beamid.pace`, :func:`beamid.cantilever`).
    load:
        :func:`beamid.TipForce`, :func:`beamid.TipMoment`, their sum, or
        :class:`beamid.RadialWire`.
    wrt:
        Parameter names for the sensitivities ``result.d[output][name]``
        (implicit function theorem, Eq. 44-51).
    tol:
        Integration tolerance (default 1e-10).

    Raises
    ------
    InputError
        Unknown parameter name, bad load (e.g. a wire not shorter than the arm).
    ConvergenceError
        Newton and load continuation failed (the message names the load).
    """
    if not isinstance(model, Model):
        raise InputError(f"model must be a beamid.Model, got {type(model).__name__}")
    if not isinstance(load, (TipLoad, RadialWire)):
        raise InputError(f"load must be TipForce, TipMoment or RadialWire, got {load!r}")
    wrt, idx = model._checked_indices("wrt", wrt)
    if tol is not None:
        tol = _check.real("tol", tol, above=0.0, below=1e-2,
                          expected="a tolerance in (0, 1e-2)")
    kind, values = load.encode()
    outputs, doutputs, unknowns, info = _core.static_solve(
        model.nbeams, model.vector(), kind, values, idx, 0.0 if tol is None else float(tol))
    return StaticResult(model, load, wrt, outputs, doutputs, unknowns, info[0], info[1],
                        0.0 if tol is None else float(tol))


def measurement_value(result: StaticResult, quantity: str) -> float:
    """Value of a measurement quantity (x_tip, y_tip, tip_angle, wire_force,
    x_elbow, y_elbow, u_tip = x_tip - total length, w_tip = y_tip)."""
    if quantity == "u_tip":
        return result.tip_x - result.model.total_length
    if quantity == "w_tip":
        return result.tip_y
    key = ALIASES.get(quantity, quantity)
    if key not in OUTPUTS:
        raise InputError(f"unknown quantity {quantity!r}")
    value = float(result._outputs[OUTPUTS.index(key)])
    if math.isnan(value):
        raise InputError(f"quantity {quantity!r} is not defined for {result.load.describe()}")
    return value
