"""Beam chain models addressed by parameter name.

A :class:`Model` is an immutable chain of ``nbeams`` beams clamped at the root
with point masses at the joints and the tip. Its parameters have fixed names
(see :func:`Model.names`): per beam ``L1 EI1 EA1 rho1 C1`` ..., per mass point
``m_elbow J_elbow mu_elbow c_elbow`` (joint 1; ``m_joint2`` ... for longer
chains; ``m_joint1`` is accepted for ``m_elbow``) and ``m_tip J_tip mu_tip
c_tip``, the joint compliances ``elbow_flex`` (``joint2_flex`` ...), the
globals ``axial_coupling root_flex eta r_motor tau_motor``, and per beam the strip
thickness ``thick1`` ... (m; only the gauge strain kappa t/2 reads it; after the
globals, so every earlier position is unchanged).
"""
from __future__ import annotations

import difflib
from typing import Any, Iterable, Mapping

import numpy as np

from . import _check, _core
from .errors import InputError

#: Strip thickness of the PACE beams (Section 4.1.4): EA = 12 EI / t^2; the
#: default of every beam's ``thick<i>``.
PACE_THICKNESS = 0.00315976


def _canonical(nbeams: int, name: str) -> str:
    """Accept the joint-1 aliases (m_joint1 -> m_elbow, joint1_flex -> elbow_flex)."""
    if nbeams >= 2:
        if name.endswith("_joint1"):
            return name[: -len("joint1")] + "elbow"
        if name == "joint1_flex":
            return "elbow_flex"
    return name


#: most beams of a chain (the bound of the deck reader, beamid_deck)
MAX_BEAMS = 1000

class Model:
    """A validated beam chain. Use :func:`pace` or :func:`cantilever` to make one.

    Parameters
    ----------
    nbeams:
        Number of beams in the chain (>= 1).
    values:
        Parameter vector in the order of :meth:`names`.
    """

    __slots__ = ("_nbeams", "_values", "_index", "_wrt_cache")

    def __init__(self, nbeams: int, values: Iterable[float]):
        nbeams = _check.count("nbeams", nbeams, min=1, max=MAX_BEAMS)
        # NaN and infinities are named per parameter by the core's check below
        vec = _check.reals("values", values, finite=False)
        names = _core.param_names(nbeams)
        if vec.shape != (len(names),):
            raise InputError(f"parameter vector has {vec.size} values, expected "
                             f"{len(names)} for {nbeams} beams")
        _core.check_params(nbeams, vec)
        vec.setflags(write=False)
        self._nbeams = nbeams
        self._values = vec
        self._index = {n: i for i, n in enumerate(names)}
        self._wrt_cache: dict[tuple[str, ...], np.ndarray] = {}

    # -- naming -------------------------------------------------------------
    @property
    def nbeams(self) -> int:
        """Number of beams."""
        return self._nbeams

    def names(self) -> tuple[str, ...]:
        """Parameter names in vector order."""
        return _core.param_names(self._nbeams)

    def index(self, name: str) -> int:
        """Position of a named parameter in the vector (InputError if unknown)."""
        key = _canonical(self._nbeams, str(name))
        try:
            return self._index[key]
        except KeyError:
            close = difflib.get_close_matches(key, self._index, n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise InputError(f"unknown parameter name {name!r} for a {self._nbeams}-beam "
                             f"chain{hint}") from None

    def indices(self, names: tuple[str, ...]) -> np.ndarray:
        """1-based positions of named parameters as the Fortran core takes them
        (InputError for an unknown name); remembered per tuple of names."""
        return self._checked_indices("names", names)[1]

    def _checked_indices(self, what: str, names: Any) -> tuple[tuple[str, ...], np.ndarray]:
        """``names`` (a name or a sequence of names; InputError naming ``what``
        otherwise, or for an unknown name) as a tuple, and their 1-based
        positions (:meth:`indices`). A tuple met before was checked then: it is
        answered from the cache (solve_static's per-call cost)."""
        try:
            found = self._wrt_cache.get(names) if type(names) is tuple else None
        except TypeError:
            found = None
        if found is not None:
            return names, found
        names = _check.names(what, names)
        found = self._wrt_cache.get(names)
        if found is None:
            found = np.array([self.index(n) + 1 for n in names], dtype=np.int32)
            found.setflags(write=False)
            self._wrt_cache[names] = found
        return names, found

    # -- values -------------------------------------------------------------
    @property
    def params(self) -> dict[str, float]:
        """Every named parameter and its value (a fresh dict)."""
        return {n: float(v) for n, v in zip(self.names(), self._values)}

    def vector(self) -> np.ndarray:
        """The parameter vector (read-only array)."""
        return self._values

    def __getitem__(self, name: str) -> float:
        return float(self._values[self.index(name)])

    @property
    def total_length(self) -> float:
        """Arc length of the whole chain (m)."""
        return float(sum(self[f"L{i + 1}"] for i in range(self._nbeams)))

    def replace(self, **overrides: float) -> "Model":
        """A copy with the named parameters changed (validated)."""
        return self.with_params(overrides)

    def with_params(self, overrides: Mapping[str, float]) -> "Model":
        """A copy with the parameters in ``overrides`` changed (validated)."""
        vec = np.array(self._values)
        for name, value in _check.mapping("overrides", overrides).items():
            # NaN is named by the core's parameter check (Model)
            vec[self.index(name)] = _check.real(name, value, finite=False,
                                                expected="a number")
        return Model(self._nbeams, vec)

    def __repr__(self) -> str:
        shown = ", ".join(f"{n}={v:g}" for n, v in self.params.items())
        return f"Model(nbeams={self._nbeams}, {shown})"

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, Model) and other._nbeams == self._nbeams
                and bool(np.array_equal(other._values, self._values)))

    def __hash__(self) -> int:
        return hash((self._nbeams, self._values.tobytes()))


def pace(**overrides: float) -> Model:
    """The PACE two-beam arm with the Table 1 values, effects off.

    ``axial_coupling`` defaults to 1 (exact elastica); pass ``axial_coupling=0``
    for the dissertation's shear-only form that produced Tables 2-5.

    >>> m = pace(C1=5.0, C2=20.0, axial_coupling=0.0)
    >>> m.params["EI1"]
    11.413
    """
    nbeams, values = _core.preset("pace")
    return Model(nbeams, values).with_params(overrides)


def cantilever(L: float = 0.776, EI: float = 11.413, C: float = 0.0, *,
               EA: float | None = None, rho: float = 0.532, **overrides: float) -> Model:
    """A single clamped beam without end masses.

    ``EA`` defaults to 12 EI / t^2 with the PACE strip thickness t.
    """
    nbeams, values = _core.preset("cantilever")
    base = Model(nbeams, values)
    EI = _check.real("EI", EI, finite=False, expected="a number")
    ea = 12.0 * EI / PACE_THICKNESS**2 if EA is None else EA
    return base.with_params({"L1": L, "EI1": EI, "C1": C, "EA1": ea, "rho1": rho, **overrides})
