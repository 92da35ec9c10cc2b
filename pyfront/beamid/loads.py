"""Static load cases: fixed-direction tip force, tip moment, both, radial wire."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError

LOAD_TIP = 1
LOAD_WIRE = 2


def _finite(name: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} = {value!r}, expected a number") from None
    if not math.isfinite(v):
        raise InputError(f"{name} = {v}, expected a finite number")
    return v


@dataclass(frozen=True)
class TipLoad:
    """Fixed-direction tip force (fx, fy) in N plus a tip moment in N m
    (counter-clockwise). ``TipForce(...) + TipMoment(...)`` gives one."""

    fx: float = 0.0
    fy: float = 0.0
    moment: float = 0.0

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "moment"):
            object.__setattr__(self, name, _finite(name, getattr(self, name)))
        encoded = np.array([self.fx, self.fy, self.moment, 0.0])
        encoded.setflags(write=False)
        object.__setattr__(self, "_encoded", encoded)

    def encode(self) -> tuple[int, np.ndarray]:
        """(kind, [fx, fy, moment, Lw]) as the Fortran core takes it (read-only)."""
        return LOAD_TIP, self._encoded

    def __add__(self, other: "TipLoad") -> "TipLoad":
        if not isinstance(other, TipLoad):
            return NotImplemented
        return TipLoad(self.fx + other.fx, self.fy + other.fy, self.moment + other.moment)

    def scaled(self, factor: float) -> "TipLoad":
        return TipLoad(self.fx * factor, self.fy * factor, self.moment * factor)

    def describe(self) -> str:
        return f"tip force ({self.fx:g}, {self.fy:g}) N, moment {self.moment:g} N m"


def TipForce(fx: float = 0.0, fy: float = 0.0) -> TipLoad:
    """A fixed-direction tip force in N (global axes; the arm lies along +x)."""
    return TipLoad(fx=fx, fy=fy)


def TipMoment(moment: float) -> TipLoad:
    """A tip moment in N m, counter-clockwise positive (Figure 6)."""
    return TipLoad(moment=moment)


@dataclass(frozen=True)
class RadialWire:
    """A wire of length ``Lw`` (m) from the tip to the root (Eq. 22, Figure 8).

    Its tension is an output of the solve. Lw must be shorter than the arm.
    """

    Lw: float

    def __post_init__(self) -> None:
        v = _finite("Lw", self.Lw)
        if v <= 0.0:
            raise InputError(f"wire length Lw = {v:g}, expected a positive length")
        object.__setattr__(self, "Lw", v)
        encoded = np.array([0.0, 0.0, 0.0, v])
        encoded.setflags(write=False)
        object.__setattr__(self, "_encoded", encoded)

    def encode(self) -> tuple[int, np.ndarray]:
        """(kind, [0, 0, 0, Lw]) as the Fortran core takes it (read-only)."""
        return LOAD_WIRE, self._encoded

    def describe(self) -> str:
        return f"radial wire Lw = {self.Lw:g} m"


Load = TipLoad | RadialWire
