"""Observations: what an experiment can measure, read from the Fortran core.

The one table lives in ``fortran/inverse/beamid_observations.f90``; this module
reads it once through the binding (``api_observation_table``) and keeps no
copy of its own. An observation is a kind and its locus: ``x_tip`` (a fixed
point of the arm) or ``kind@beam:s`` for a station, ``s`` in metres from
that beam's root (``strain@1:0.05``). Names are parsed by the core
(:func:`parse`).

>>> from beamid import observations
>>> observations.unit("tip_angle")
'rad'
>>> observations.parse("x_tip").kind
'x_tip'
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from . import _check, _core
from .errors import InputError, raise_for_status

__all__ = ["Kind", "Observation", "kinds", "parse", "unit", "can_measure", "probe_kinds",
           "ordered"]


@dataclass(frozen=True)
class Kind:
    """One row of the core's observation table."""

    name: str
    unit: str
    families: frozenset          #: {"static", "release", "modal"}
    locus: str                   #: "none", "station" (beam, s), "mode" or "station+mode"
    needs: str                   #: "none", "wire" or "motor"
    sigma: float                 #: default sigma of a probe row
    probe_static: int            #: place in the static probe list (0: none)
    probe_release: int           #: place in the release probe list (0: none)
    twin: str                    #: the kind measuring the same in other coordinates
    about: str
    code: int                    #: the kind code (1-based position in the table)
    rate: bool = True            #: the core computes its rate (a clock offset's column)


@dataclass(frozen=True)
class Observation:
    """A parsed observation name: its kind and locus and its canonical name."""

    kind: str
    code: int
    beam: int
    s: float
    mode: int
    label: str


@lru_cache(maxsize=1)
def kinds() -> dict[str, Kind]:
    """The table, by kind name in code order."""
    out = {}
    text = _core._text(_core._deck_api.api_observation_table())
    for code, line in enumerate((x for x in text.split("\n") if x.strip()), start=1):
        f = line.split(";", 10)
        out[f[0]] = Kind(f[0], f[1], frozenset(f[2].split("+")), f[3], f[4], float(f[5]),
                         int(f[6]), int(f[7]), f[8], f[10], code, f[9] == "rate")
    return out


def parse(name: str) -> Observation:
    """Parse an observation name (the core's parser); InputError saying what
    is wrong (unknown kind, malformed station)."""
    if not isinstance(name, str) or not name.isascii():
        _check.fail("observation", name, "a name (ASCII) such as 'x_tip' or 'strain@1:0.05'")
    return _parse(name)


@lru_cache(maxsize=4096)
def _parse(name: str) -> Observation:
    kind, beam, s, mode, label, code, message = _core._deck_api.api_observation_parse(name)
    if code != 0:
        raise_for_status(int(code), _core._text(message))
    k = list(kinds())[int(kind) - 1]
    return Observation(k, int(kind), int(beam), float(s), int(mode), _core._text(label))


#: A modal observation crosses the binding's kind array as kind + MODE_STRIDE *
#: mode (beamid_observations MODE_STRIDE)
MODE_STRIDE = 1000


def binding_code(o: Observation) -> int:
    """The kind code of ``o`` as the binding's observation arrays take it (the
    mode folded in, beamid_observations MODE_STRIDE)."""
    return o.code + MODE_STRIDE * o.mode


def unit(name: str) -> str:
    """The unit of an observation (``m``, ``rad``, ``N``, ``N m``, ...)."""
    return kinds()[parse(name).kind].unit


def can_measure(name: str, family: str, *, has_wire: bool = False,
                has_motor: bool = False) -> str:
    """'' when an experiment of ``family`` ("static" or "release") can make
    observation ``name``, else the reason: "family", "wire" or "motor"."""
    family = _check.choice("family", family, ("static", "release", "modal"))
    k = kinds()[parse(name).kind]
    if family not in k.families:
        return "family"
    if k.needs == "wire" and not has_wire:
        return "wire"
    if k.needs == "motor" and not has_motor:
        return "motor"
    return ""


def probe_kinds(family: str) -> tuple[str, ...]:
    """The kinds of a family's probe list, in probe order."""
    family = _check.choice("family", family, ("static", "release"))
    attr = "probe_static" if family == "static" else "probe_release"
    ks = [k for k in kinds().values() if getattr(k, attr) > 0]
    return tuple(k.name for k in sorted(ks, key=lambda k: getattr(k, attr)))


def ordered(names) -> tuple[str, ...]:
    """The distinct observation names of ``names`` (canonical, as
    :func:`parse` labels them) in the core's order: by kind code, then beam,
    arc length and mode. An estimation problem's observation list is in
    this order, so the measurement chain's channels (beamid.chain) are
    numbered alike on both sides.

    >>> ordered(["w_tip", "x@1:0.3", "u_tip", "x@1:0.10", "w_tip"])
    ('u_tip', 'w_tip', 'x@1:0.1', 'x@1:0.3')
    """
    parsed = {o.label: o for o in (parse(n) for n in names)}
    return tuple(sorted(parsed, key=lambda n: _order_key(parsed[n])))


def sort_key(name: str) -> tuple:
    """The place of observation ``name`` in :func:`ordered`."""
    return _order_key(parse(name))


def _order_key(o: Observation) -> tuple:
    return (o.code, o.beam, o.s, o.mode)
