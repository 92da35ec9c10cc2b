"""Modal analysis about a static equilibrium, its sensitivities and mode pairing
(issue 27; docs/modal.md).

The arm held by a tip load (none, a tip force, a tip moment) is linearized about
its finite element equilibrium, M x'' + C x' + K_T x = 0, with every effect the
FE model carries: root and joint compliances, the cubic law, rotary inertia of
the point masses, viscous drag and Kelvin-Voigt damping. The result gives the
natural frequencies (Hz), damping ratios (damped models), the mode shapes
sampled at stations, and their derivatives with respect to model parameters,
including the movement of the equilibrium with the parameter::

    r = beamid.modal_analysis(beamid.pace(), beamid.TipForce(fy=3.0), nmodes=4,
                              wrt=("EI1", "rho1"), stations=("shape_n@1:0.4",))
    r.freq, r.dfreq                       # Hz, d f / d p
    r.shape(1), r.dshape(1)               # unit-normalized shape and its derivative
    beamid.pair_modes(f_measured, s_measured, r.freq, r.shapes)

Coulomb friction has no linearization about rest and is left out (mu has a
zero column); the tip moment of Eq. 78 (not conservative) is refused. A
radial wire holds the tip on its circle during the test (the constrained
eigenproblem about the wire's equilibrium; ``tension`` and ``dtension``).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from . import _check, _core
from .errors import InputError
from .fe import _load_components, _mesh
from .loads import RadialWire
from .plotting import _axes

__all__ = ["ModalResult", "ModePairing", "modal_analysis", "mac", "pair_modes", "plot_mac",
           "SHAPE_KINDS", "parse_station", "normalize_shape", "modal_rows"]

#: Station quantities of a mode shape and their codes in the core (beamid_modal
#: SHAPE_*): displacement along the local normal and tangent, change of the
#: tangent angle, change of the gauge strain, displacement along x and y.
SHAPE_KINDS = {"shape_n": 1, "shape_t": 2, "shape_psi": 3, "shape_strain": 4,
               "shape_x": 5, "shape_y": 6}

_STATION = re.compile(r"^\s*(shape_[a-z]+)@(\d+):([^\[\]\s]+)\s*$")


def parse_station(name: Any) -> tuple[str, int, float]:
    """``(kind, beam, s)`` of a station name such as ``shape_n@1:0.4`` (a
    tuple ``(kind, beam, s)`` passes through, checked)."""
    if isinstance(name, (tuple, list)) and len(name) == 3:
        kind, beam, s = name
    else:
        text = _check.text("station", name)
        found = _STATION.match(text)
        if not found:
            raise InputError(f"station = {text!r}, expected kind@beam:s with a kind of "
                             f"{', '.join(SHAPE_KINDS)} (e.g. shape_n@1:0.4)")
        kind, beam, s = found.group(1), found.group(2), found.group(3)
        try:
            s = float(s)
        except ValueError:
            raise InputError(f"station = {text!r}: arc length {s!r} is not a number") from None
        beam = int(beam)
    kind = _check.choice("station kind", kind, SHAPE_KINDS)
    beam = _check.count("station beam", beam, min=1)
    s = _check.real("station s", s, min=0.0)
    return kind, beam, s


def _unit(v: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(v / |v| signed so that its largest entry is positive, the sign, |v|)."""
    norm = float(np.linalg.norm(v))
    if norm == 0.0:
        return v.copy(), 1.0, 0.0
    sign = 1.0 if v[int(np.argmax(np.abs(v)))] >= 0.0 else -1.0
    return sign * v / norm, sign, norm


def normalize_shape(values: Any) -> np.ndarray:
    """A measured mode shape (its entries at the stations of one mode) scaled as
    the modal experiment predicts it: unit 2-norm, the largest entry positive."""
    v = _check.reals("values", values, min_size=1)
    if not np.any(v):
        raise InputError("values: every entry is 0, expected a mode shape that moves")
    return _unit(v)[0]


@dataclass(frozen=True, repr=False)
class ModalResult:
    """Modes of the arm about its static equilibrium (``modal_analysis``).

    Mode arrays are in ascending frequency order, mode k (1-based) at index
    k - 1. ``phi`` holds mass-normalized shapes over the free unknowns;
    ``shapes`` (stations x modes) are those shapes sampled at the stations
    (raw scale); ``shape(k)`` unit-normalizes them. Derivative arrays carry
    one last axis per name of ``wrt``.
    """

    freq: np.ndarray
    zeta: np.ndarray
    damped: bool
    q: np.ndarray
    phi: np.ndarray
    stations: tuple[str, ...]
    shapes: np.ndarray
    wrt: tuple[str, ...]
    dq: np.ndarray
    dfreq: np.ndarray
    dzeta: np.ndarray
    dphi: np.ndarray
    dshapes: np.ndarray
    nmodes_model: int
    elements_per_beam: int
    load: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0))
    spin_rate: float = 0.0
    #: a radial wire's length (m; 0: none), its tension at the equilibrium (N)
    #: and the tension's derivatives (one per name of ``wrt``)
    wire_length: float = 0.0
    tension: float = 0.0
    dtension: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __repr__(self) -> str:
        f = ", ".join(f"{x:.4g}" for x in self.freq[:6])
        more = ", ..." if self.freq.size > 6 else ""
        return (f"ModalResult({self.freq.size} modes: [{f}{more}] Hz, "
                f"{'damped' if self.damped else 'undamped'}, {len(self.stations)} stations, "
                f"wrt {list(self.wrt)})")

    def _mode(self, k: Any) -> int:
        k = _check.count("mode", k, min=1)
        if k > self.freq.size:
            raise InputError(f"mode = {k}, expected 1..{self.freq.size} (the modes computed; "
                             f"the model has {self.nmodes_model})")
        return k - 1

    def shape(self, k: int) -> np.ndarray:
        """Mode k sampled at the stations, unit 2-norm, its largest entry positive
        (empty without stations)."""
        i = self._mode(k)
        return _unit(self.shapes[:, i])[0]     # empty without stations

    def dshape(self, k: int) -> np.ndarray:
        """Derivative of ``shape(k)`` (stations x wrt)."""
        i = self._mode(k)
        u, sign, norm = _unit(self.shapes[:, i])
        if norm == 0.0:
            return np.zeros((len(self.stations), len(self.wrt)))
        d = self.dshapes[:, i, :]
        return sign * (d - np.outer(u * sign, (u * sign) @ d)) / norm


def modal_analysis(model: Any, load: Any = None, *, nmodes: int = 6,
                   elements_per_beam: int = 4, wrt: Sequence[str] = (),
                   stations: Sequence[Any] = (), spin_rate: float = 0.0,
                   coriolis: bool = True) -> ModalResult:
    """Modes of ``model`` linearized about its FE equilibrium under ``load``.

    ``load``: None (the straight arm), a ``TipForce``, a ``TipMoment`` (its
    exact virtual work; the Eq. 78 form is not conservative), their sum, or a
    ``RadialWire`` left on during the test (inextensible and taut: the tip
    moves on the wire's circle, so the model has one mode fewer; the result
    carries the wire's ``tension`` and ``dtension``). ``nmodes``: how many
    of the lowest modes to return (at most the model's count, its free
    unknowns, one fewer with a wire). ``wrt``: parameter names for the sensitivities (lengths and
    compliances at 0 are refused; friction, axial_coupling and the motor have
    zero columns). ``stations``: where the shapes are sampled, names such as
    ``shape_n@1:0.4`` (kinds in ``SHAPE_KINDS``) or tuples (kind, beam, s).
    ``spin_rate`` (rad/s): the modes about a steady hub spin at that rate, in
    the hub frame (the equilibrium under the centrifugal load, its geometric
    stiffening and centrifugal softening; a clamped root, locked joints and no
    rotary inertia, as the hub requires; no ``wrt``). ``coriolis``: keep the
    Coriolis coupling of axial and in-plane motion (a gyroscopic
    eigenproblem); False gives the classic uncoupled in-plane model.
    """
    wire_length = 0.0
    if isinstance(load, RadialWire):
        wire_length = float(load.Lw)
        comps = np.zeros(3)
    else:
        comps = np.zeros(3) if load is None else _load_components(load)
    nbeams, params, _, nfree = _mesh(model, elements_per_beam, hinged=True)
    nmodes = _check.count("nmodes", nmodes, min=1)
    nmodel = nfree - 1 if wire_length > 0.0 else nfree
    if nmodes > nmodel:
        raise InputError(f"nmodes = {nmodes}: the model of {elements_per_beam} elements per "
                         f"beam has {nmodel} modes")
    spin_rate = _check.real("spin_rate", spin_rate)
    coriolis = _check.flag("coriolis", coriolis)
    wrt = _check.names("wrt", wrt)
    windex = model.indices(wrt) if wrt else np.zeros(0, dtype=np.int32)
    if isinstance(stations, str):
        stations = (stations,)
    if not isinstance(stations, (list, tuple)):
        _check.fail("stations", stations, "a sequence of station names such as "
                    "('shape_n@1:0.4',)")
    parsed = [parse_station(s) for s in stations]
    for kind, beam, s in parsed:
        if beam > nbeams:
            raise InputError(f"station {kind}@{beam}:{s:g}: beam = {beam}, expected 1..{nbeams}")
        if s > model[f"L{beam}"] * (1 + 1e-12):
            raise InputError(f"station {kind}@{beam}:{s:g}: s = {s:g}, expected at most "
                             f"L{beam} = {model[f'L{beam}']:g}")
    kinds = np.array([SHAPE_KINDS[k] for k, _, _ in parsed], dtype=np.int32)
    beams = np.array([b for _, b, _ in parsed], dtype=np.int32)
    svals = np.array([s for _, _, s in parsed], dtype=np.float64)
    loads = np.array([*comps, 1.0], dtype=np.float64)
    (freq, zeta, damped, q, phi, dq, dfreq, dzeta, dphi, shapes, dshapes, tension,
     dtension) = _core.modal(
        nbeams, params, int(elements_per_beam), loads, nmodes, np.asarray(windex, np.int32),
        kinds, beams, svals, nfree, spin=(spin_rate, bool(coriolis)), wire_length=wire_length)
    names = tuple(f"{k}@{b}:{s:g}" for k, b, s in parsed)
    return ModalResult(freq=np.array(freq), zeta=np.array(zeta), damped=bool(damped),
                       q=np.array(q), phi=np.array(phi), stations=names,
                       shapes=np.array(shapes).reshape(len(parsed), nmodes), wrt=tuple(wrt),
                       dq=np.array(dq), dfreq=np.array(dfreq), dzeta=np.array(dzeta),
                       dphi=np.array(dphi),
                       dshapes=np.array(dshapes).reshape(len(parsed), nmodes, len(wrt)),
                       nmodes_model=int(nmodel), elements_per_beam=int(elements_per_beam),
                       load=tuple(float(c) for c in comps), spin_rate=spin_rate,
                       wire_length=wire_length, tension=float(tension),
                       dtension=np.array(dtension).reshape(len(wrt)))


# ---------------------------------------------------------------- MAC and pairing

def mac(a: Any, b: Any) -> np.ndarray:
    """Modal assurance criterion MAC(i, j) = |a_i . b_j|^2 / ((a_i . a_i)(b_j . b_j))
    of the columns of ``a`` (stations x na) and ``b`` (stations x nb): (na, nb)."""
    a = _check.reals("a", a, ndim=2, min_size=1)
    b = _check.reals("b", b, ndim=2, min_size=1)
    if a.shape[0] != b.shape[0]:
        raise InputError(f"a has {a.shape[0]} stations (rows), b has {b.shape[0]}: "
                         "expected the same stations")
    na = np.einsum("ij,ij->j", a, a)
    nb = np.einsum("ij,ij->j", b, b)
    den = np.outer(na, nb)
    num = (a.T @ b) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)
    return out


@dataclass(frozen=True)
class ModePairing:
    """Measured modes paired with model modes (``pair_modes``).

    ``pairs``: (measured index, model mode, MAC, relative frequency difference),
    measured index and model mode 1-based; ``unpaired_measured`` and
    ``unpaired_model`` the modes left without a partner (never forced);
    ``mac`` the matrix (measured x model; zeros without shapes).
    """

    pairs: tuple[tuple[int, int, float, float], ...]
    unpaired_measured: tuple[int, ...]
    unpaired_model: tuple[int, ...]
    mac: np.ndarray
    measured_freq: np.ndarray
    model_freq: np.ndarray

    def model_mode(self, measured: int) -> int | None:
        """The model mode paired with measured mode ``measured`` (1-based), or None."""
        measured = _check.count("measured", measured, min=1)
        for i, j, _, _ in self.pairs:
            if i == measured:
                return j
        return None

    def changes(self, other: "ModePairing") -> list[str]:
        """What differs between this pairing and ``other`` (e.g. the pairing at the
        start and at the end of a fit): a model mode that moved across a
        measured one shows up as a measured mode paired differently."""
        _check.instance("other", other, ModePairing, "a ModePairing")
        out = []
        mine = {i: j for i, j, _, _ in self.pairs}
        theirs = {i: j for i, j, _, _ in other.pairs}
        for i in sorted(set(mine) | set(theirs)):
            if mine.get(i) != theirs.get(i):
                out.append(f"measured mode {i}: model mode {mine.get(i)} -> {theirs.get(i)}")
        return out

    def report(self) -> str:
        """The pairing as text, one line per measured mode."""
        lines = []
        by_measured = {i: (j, m, d) for i, j, m, d in self.pairs}
        for i in range(1, self.measured_freq.size + 1):
            f = self.measured_freq[i - 1]
            if i in by_measured:
                j, m, d = by_measured[i]
                lines.append(f"measured {i} ({f:.4g} Hz) -> model {j} "
                             f"({self.model_freq[j - 1]:.4g} Hz), MAC {m:.3f}, "
                             f"df/f {d:+.3f}")
            else:
                lines.append(f"measured {i} ({f:.4g} Hz) -> no partner")
        if self.unpaired_model:
            lines.append("model modes without partner: "
                         + ", ".join(str(j) for j in self.unpaired_model))
        return "\n".join(lines)


def pair_modes(measured_freq: Any, measured_shapes: Any, model_freq: Any, model_shapes: Any,
               *, min_mac: float = 0.6, freq_tol: float = 0.3) -> ModePairing:
    """Pair measured and model modes by MAC with a frequency term.

    A pair needs MAC >= ``min_mac`` (when shapes are given; None for either
    side pairs by frequency alone) and a relative frequency difference
    |f_model - f_measured| / f_measured <= ``freq_tol``; its score is MAC (1 -
    difference / freq_tol). Pairs are taken by descending score, each mode at
    most once; counts may differ, and a mode without an acceptable partner
    stays unpaired.
    """
    fm = _check.reals("measured_freq", measured_freq, min_size=1, min=0.0)
    fa = _check.reals("model_freq", model_freq, min_size=1, min=0.0)
    min_mac = _check.real("min_mac", min_mac, min=0.0, max=1.0)
    freq_tol = _check.real("freq_tol", freq_tol, above=0.0)
    if measured_shapes is None or model_shapes is None:
        m = np.ones((fm.size, fa.size))
        shown = np.zeros((fm.size, fa.size))
    else:
        sm = _check.reals("measured_shapes", measured_shapes, ndim=2, min_size=1)
        sa = _check.reals("model_shapes", model_shapes, ndim=2, min_size=1)
        if sm.shape[1] != fm.size or sa.shape[1] != fa.size:
            raise InputError(f"shapes have {sm.shape[1]} and {sa.shape[1]} columns, expected "
                             f"one per frequency ({fm.size} measured, {fa.size} model)")
        m = mac(sm, sa)
        shown = m
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = (fa[None, :] - fm[:, None]) / np.where(fm[:, None] > 0, fm[:, None], np.inf)
    score = m * (1.0 - np.abs(rel) / freq_tol)
    ok = (m >= min_mac) & (np.abs(rel) <= freq_tol)
    pairs = []
    used_i: set[int] = set()
    used_j: set[int] = set()
    order = np.dstack(np.unravel_index(np.argsort(-score, axis=None), score.shape))[0]
    for i, j in order:
        if not ok[i, j] or i in used_i or j in used_j:
            continue
        used_i.add(int(i))
        used_j.add(int(j))
        pairs.append((int(i) + 1, int(j) + 1, float(m[i, j]), float(rel[i, j])))
    pairs.sort()
    return ModePairing(pairs=tuple(pairs),
                       unpaired_measured=tuple(i + 1 for i in range(fm.size) if i not in used_i),
                       unpaired_model=tuple(j + 1 for j in range(fa.size) if j not in used_j),
                       mac=shown, measured_freq=fm.copy(), model_freq=fa.copy())


def plot_mac(pairing: Any, ax: Any = None, *, title: str = "MAC, measured vs model modes") -> Any:
    """The MAC matrix of a ``ModePairing`` (or a matrix, measured x model) as an
    image, pairs outlined; returns the Axes."""
    matrix = pairing.mac if isinstance(pairing, ModePairing) else _check.reals(
        "pairing", pairing, ndim=2, min_size=1)
    ax = _axes(_check.axes("ax", ax))
    im = ax.imshow(matrix, vmin=0.0, vmax=1.0, cmap="viridis", origin="upper")
    ax.figure.colorbar(im, ax=ax, label="MAC (-)")
    ax.set_xticks(range(matrix.shape[1]), [str(j + 1) for j in range(matrix.shape[1])])
    ax.set_yticks(range(matrix.shape[0]), [str(i + 1) for i in range(matrix.shape[0])])
    ax.set_xlabel("model mode")
    ax.set_ylabel("measured mode")
    if isinstance(pairing, ModePairing):
        from matplotlib.patches import Rectangle

        for i, j, _, _ in pairing.pairs:
            ax.add_patch(Rectangle((j - 1.5, i - 1.5), 1, 1, fill=False, edgecolor="red",
                                   linewidth=2))
    ax.set_title(title)
    return ax
