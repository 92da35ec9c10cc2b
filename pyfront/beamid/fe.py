"""Nonlinear finite element chain (Chapter IV of McVay 1996).

Epstein-Murray beam elements with cubic Hermite u and w (Eq. 76), the Green
axial strain (Eq. 70) and the modified curvature (Eq. 72), assembled in band
storage over a chain of any number of beams (locked joints, clamped root; a
joint with ``elbow_flex``/``joint<k>_flex`` > 0 is a hinge with a rotational
spring, ``root_flex`` > 0 a hinge spring at the clamp; docs/theory_fe.md).

    r = beamid.fe_static(model, beamid.TipForce(fy=8.0), elements_per_beam=16)
    r.tip["w"], r.tip["dw"], r.tip["u"], r.tip["du"]    # Table 11/12 columns
    r.nodes["w"]                                         # per node: s, u, du, w, dw
    r.outboard["dw"], r.kink                             # slopes past a hinge, its angle
    md = beamid.modes(model, elements_per_beam=4)
    md.transverse, md.axial                              # rad/s, ascending (Tables 9-10)

"8 elements" in the dissertation's tables is 4 elements per beam of the
two-beam PACE arm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from . import _check, _core
from .errors import InputError, check_memory
from .model import Model

__all__ = [
    "FEStatic", "FEPath", "FEBuckling", "FEModes", "ModalCost",
    "fe_static", "fe_path", "buckling_load", "modes", "axial_modes_linear",
    "fe_system", "free_vector", "NODE_FIELDS", "OUTBOARD_FIELDS",
    "MOMENT_FORMS",
]

#: Rows of a node table, in order: undeformed arc length, u, u', w, w'
#: (the slopes of the element inboard of the node).
NODE_FIELDS = ("s", "u", "du", "w", "dw")
#: Rows of an outboard table: u', w' of the element outboard of each node
#: (different from the node table's only at a hinged joint).
OUTBOARD_FIELDS = ("du", "dw")
#: Tip-moment virtual work: Eq. 78 as printed (what produced Table 11), or exact.
MOMENT_FORMS = {"eq78": 0, "exact": 1}


def _model_args(model: Any) -> tuple[int, np.ndarray]:
    if not isinstance(model, Model):
        raise InputError(f"model must be a beamid Model, got {type(model).__name__}")
    return model.nbeams, np.ascontiguousarray(model.vector(), dtype=np.float64)


def _mesh_size(nbeams: int, elements_per_beam: int) -> tuple[int, int]:
    elements_per_beam = _check.count("elements_per_beam", elements_per_beam, min=1)
    nnode = nbeams * int(elements_per_beam) + 1
    # the bound of the deck reader (beamid_deck check_mesh_size): about 40
    # numbers per unknown in the banded solvers
    check_memory(8 * 40 * 4 * nnode, f"elements_per_beam = {elements_per_beam}: the mesh")
    return nnode, 4 * nnode - 3


def _hinges(model: Any, elements_per_beam: int) -> tuple[tuple[int, ...], bool]:
    """(0-based nodes of the hinged joints, whether the root is a hinge)."""
    names = [n for n in model.names() if n.endswith("_flex") and n != "root_flex"]
    epb = int(elements_per_beam)
    nodes = tuple((k + 1) * epb for k, n in enumerate(names) if model[n] > 0.0)
    return nodes, bool(model["root_flex"] > 0.0)


def _mesh(model: Any, elements_per_beam: int,
          hinged: bool = False) -> tuple[int, np.ndarray, int, int]:
    """(nbeams, parameters, nnode, nfree) of the model's mesh, the arguments
    checked; with ``hinged`` nfree grows by 2 per hinged joint and by 1 with a
    root hinge (api_fe_mesh_sizes), else it is the locked chain's."""
    nbeams, params = _model_args(model)
    nnode, nfree = _mesh_size(nbeams, elements_per_beam)
    if hinged:
        nnode, nfree, _, _ = _core.fe_mesh_sizes(nbeams, params, int(elements_per_beam))
    return nbeams, params, int(nnode), int(nfree)


def _moment_form(form: str) -> int:
    return MOMENT_FORMS[_check.choice("moment_form", form, MOMENT_FORMS)]


def _load_components(load: Any) -> np.ndarray:
    """(fx, fy, moment) of a tip load: TipForce, TipMoment (a TipLoad), or a list."""
    if isinstance(load, (list, tuple)):
        total = np.zeros(3)
        for item in load:
            total += _load_components(item)
        return total
    if all(hasattr(load, name) for name in ("fx", "fy", "moment")):
        comps = np.array([float(load.fx), float(load.fy), float(load.moment)])
        if not np.all(np.isfinite(comps)):
            raise InputError(f"tip load {comps} is not finite")
        return comps
    raise InputError(
        f"load {type(load).__name__} is not supported by the finite element chain "
        "(expected TipForce, TipMoment, their sum, or a list of them)")


def _outboard_table(start: Any, table: np.ndarray, name: str = "start") -> np.ndarray:
    """(2, nnode) outboard slopes (u'+, w'+) of `start` (a result with an
    `outboard` table, or a pair (nodes, outboard)); else rows u', w' of table."""
    out = getattr(start, "outboard", None)
    if isinstance(start, tuple) and len(start) == 2:
        out = start[1]
    if out is None:
        return np.asfortranarray(table[[2, 4]])
    arr = _numbers(out, f"{name}: outboard slopes", "a structured table (du, dw) or a "
                   "(2, nnode) array", OUTBOARD_FIELDS)
    nnode = table.shape[1]
    if arr.shape == (nnode, 2) and arr.shape != (2, nnode):
        arr = arr.T
    if arr.shape != (2, nnode) or not np.all(np.isfinite(arr)):
        raise InputError(f"{name}: outboard slopes have shape {arr.shape}, expected finite "
                         f"(2, {nnode})")
    return np.asfortranarray(arr)


def _numbers(value: Any, name: str, expected: str, fields: tuple[str, ...]) -> np.ndarray:
    """A float array from a structured table (its ``fields``) or an array of numbers."""
    if isinstance(value, (str, bytes)):
        _check.fail(name, value, expected)
    try:
        arr = np.asarray(value)
        if arr.dtype.names is not None:
            arr = np.stack([arr[field] for field in fields])
        return np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError, KeyError, OverflowError):
        _check.fail(name, value, expected)


def _node_tables(start: Any, nnode: int,
                 name: str = "start") -> tuple[np.ndarray, np.ndarray]:
    """Node table and outboard table of a starting shape (None: the straight
    chain at rest, zeros)."""
    if start is None:
        return np.zeros((5, nnode), order="F"), np.zeros((2, nnode), order="F")
    table = _node_table(start, nnode, name)
    return table, _outboard_table(start, table, name)


def _node_table(start: Any, nnode: int, name: str = "start") -> np.ndarray:
    """A (5, nnode) Fortran-ordered table from a result, structured nodes or an array."""
    if isinstance(start, tuple) and len(start) == 2:
        start = start[0]
    if isinstance(start, (FEStatic, FEBuckling)):
        start = start.nodes
    arr = _numbers(start, name, "an FEStatic, FEBuckling, a structured node "
                   "table or a (5, nnode) array", NODE_FIELDS)
    # a (nnode, 5) array is taken node by node, unless it is already (5, nnode)
    # (nnode = 5: two beams of two elements; structured input is stacked above)
    if arr.shape == (nnode, 5) and arr.shape != (5, nnode):
        arr = arr.T
    if arr.shape != (5, nnode):
        raise InputError(f"{name} (a shape) has shape {arr.shape}, expected (5, {nnode}) "
                         "or a result of the same mesh")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} (a shape) is not finite")
    return np.asfortranarray(arr)


def _structured(table: np.ndarray, fields: tuple[str, ...] = NODE_FIELDS) -> np.ndarray:
    """A structured array (float64 fields ``fields``, one per row of ``table``)
    over the other axes of ``table``."""
    out = np.empty(table.shape[1:], dtype=[(name, np.float64) for name in fields])
    for i, name in enumerate(fields):
        out[name] = table[i]
    return out


def free_vector(nodes: np.ndarray, outboard: np.ndarray | None = None, *,
                hinges: Sequence[int] = (), root_hinge: bool = False) -> np.ndarray:
    """Free unknown vector q (the order of fe_system) from structured nodes.

    For a chain with compliant joints pass the outboard slopes (structured,
    fields du, dw), the 0-based nodes of the hinges and whether the root is a
    hinge: a hinge node contributes [w'-, u'-, w, u, w'+, u'+], every other
    node [w, w', u, u']; the clamp removes w, u (and w' without a root hinge)
    of node 0.
    """
    hinges = set(int(h) for h in hinges)
    values = []
    for k in range(len(nodes)):
        w, dw, u, du = (float(nodes[name][k]) for name in ("w", "dw", "u", "du"))
        if k in hinges:
            if outboard is None:
                raise InputError("free_vector: a chain with hinges needs the outboard slopes")
            values += [dw, du, w, u, float(outboard["dw"][k]), float(outboard["du"][k])]
        elif k == 0:
            values += [dw, du] if root_hinge else [du]
        else:
            values += [w, dw, u, du]
    return np.array(values)


def _tip(nodes: np.ndarray) -> dict[str, float]:
    return {name: float(nodes[name][-1]) for name in NODE_FIELDS}


@dataclass
class FEStatic:
    """A static equilibrium of the finite element chain."""

    nodes: np.ndarray           #: structured array, fields s, u, du, w, dw per node
    tip: dict[str, float]       #: tip values: w, dw, u, du (Tables 11, 12) and s
    energy: float               #: strain energy V (Eq. 87), N m
    reactions: np.ndarray       #: root multipliers of Eq. 105 on (w, w', u)
    residual: float             #: final |NLT - Q|_inf
    iterations: int             #: Newton iterations
    steps: int                  #: accepted load steps
    elements_per_beam: int
    load: np.ndarray            #: (fx, fy, moment)
    #: slopes du, dw of the element outboard of each node (structured); equal
    #: to nodes["du"], nodes["dw"] except at a hinged joint
    outboard: np.ndarray | None = None
    hinges: tuple[int, ...] = ()          #: 0-based nodes of the hinged joints
    root_hinge: bool = False    #: the root is a hinge spring (root_flex > 0)
    #: negative eigenvalues of the tangent at this equilibrium (Sylvester's
    #: inertia of its L D L^T): 0 stable, >= 1 unstable
    negative_eigenvalues: int = 0

    @property
    def stable(self) -> bool:
        """False when the tangent has a negative eigenvalue: e.g. the straight
        chain under a compressive tip force beyond the buckling load."""
        return self.negative_eigenvalues == 0

    @property
    def q(self) -> np.ndarray:
        """Free unknown vector in the order of fe_system (see free_vector)."""
        return free_vector(self.nodes, self.outboard, hinges=self.hinges,
                           root_hinge=self.root_hinge)

    @property
    def kink(self) -> np.ndarray:
        """Relative rotation psi+ - psi- across each node (rad): the hinge
        angle f M at a compliant joint, zero elsewhere."""
        if self.outboard is None:
            return np.zeros(len(self.nodes))
        tm = (1.0 + self.nodes["du"], self.nodes["dw"])
        tp = (1.0 + self.outboard["du"], self.outboard["dw"])
        return np.arctan2(tm[0] * tp[1] - tm[1] * tp[0], tm[0] * tp[0] + tm[1] * tp[1])

    @property
    def x(self) -> np.ndarray:
        """Deformed x = s + u of the nodes (Eq. 62)."""
        return self.nodes["s"] + self.nodes["u"]

    @property
    def y(self) -> np.ndarray:
        """Deformed y = w of the nodes (Eq. 62)."""
        return self.nodes["w"].copy()

    @property
    def angle(self) -> np.ndarray:
        """Tangent angle Psi = atan2(w', 1 + u') at the nodes."""
        return np.arctan2(self.nodes["dw"], 1.0 + self.nodes["du"])

    @property
    def strain(self) -> np.ndarray:
        """Green axial strain e = u' + (u'^2 + w'^2)/2 at the nodes (Eq. 70)."""
        du, dw = self.nodes["du"], self.nodes["dw"]
        return du + 0.5 * (du * du + dw * dw)


def fe_static(model: Any, load: Any, elements_per_beam: int = 8, *, start: Any = None,
              steps: int = 0, tol: float = 0.0, moment_form: str = "eq78") -> FEStatic:
    """Static equilibrium under a tip load (Newton, Eq. 84-85).

    Without `start` the load is stepped up from the straight chain (``steps``
    initial steps, halved on failure). With `start` (an FEStatic, FEBuckling
    or node table of the same mesh) Newton runs at the full load from that
    shape, which selects among several equilibria above the buckling load.
    """
    nbeams, params, nnode, _ = _mesh(model, elements_per_beam)
    comps = _load_components(load)
    loads = np.array([*comps, _moment_form(moment_form)], dtype=np.float64)
    guess, guess_out = _node_tables(start, nnode)
    steps = _check.count("steps", steps, min=0)
    tol = _check.real("tol", tol, min=0.0)
    nodes, nodes_out, energy, reactions, residual, info = _core.fe_static(
        nbeams, params, int(elements_per_beam), loads, int(start is not None), int(steps),
        float(tol), guess, guess_out)
    table = _structured(np.asarray(nodes))
    hinges, root_hinge = _hinges(model, elements_per_beam)
    return FEStatic(nodes=table, tip=_tip(table), energy=float(energy),
                    reactions=np.array(reactions), residual=float(residual),
                    iterations=int(info[0]), steps=int(info[1]),
                    elements_per_beam=int(elements_per_beam), load=comps,
                    outboard=_structured(np.asarray(nodes_out), OUTBOARD_FIELDS), hinges=hinges,
                    root_hinge=root_hinge, negative_eigenvalues=int(info[2]))


@dataclass
class FEPath:
    """Equilibria along load0 + lam * dload from pseudo-arc-length continuation."""

    lam: np.ndarray                 #: load parameter at each point
    nodes: np.ndarray               #: (npts, nnode) structured node tables
    load0: np.ndarray
    dload: np.ndarray
    elements_per_beam: int
    outboard: np.ndarray | None = None  #: (npts, nnode) outboard slopes du, dw

    @property
    def tip(self) -> dict[str, np.ndarray]:
        """Tip values along the path: dict of arrays w, dw, u, du."""
        return {name: self.nodes[name][:, -1].copy() for name in NODE_FIELDS}

    def limit_points(self) -> list[int]:
        """Indices i where lam turns (lam[i] is a local extremum): limit points."""
        d = np.diff(self.lam)
        return [i + 1 for i in range(len(d) - 1) if d[i] * d[i + 1] < 0]

    def crossings(self, value: float) -> list[int]:
        """Indices i with lam[i] and lam[i+1] on either side of `value`."""
        s = self.lam - _check.real("value", value)
        return [i for i in range(len(s) - 1) if s[i] == 0 or s[i] * s[i + 1] < 0]


def fe_path(model: Any, load0: Any, dload: Any, elements_per_beam: int = 8, *, start: Any = None,
            lam0: float = 0.0, ds: float = 0.05, ds_max: float = 0.5, direction: int = 1,
            lam_range: tuple[float, float] = (-1e3, 1e3), max_points: int = 200,
            tol: float = 0.0, moment_form: str = "eq78") -> FEPath:
    """Follow equilibria under ``load0 + lam * dload`` past limit points.

    `start` is a shape near the equilibrium at lam0 (default: the straight
    chain, right for lam0 = 0 and load0 = 0). `ds` is the first arc-length step
    in the (q, lam) space, `direction` the sign of the first change of lam.
    """
    nbeams, params, nnode, _ = _mesh(model, elements_per_beam)
    c0 = _load_components(load0) if load0 is not None else np.zeros(3)
    dc = _load_components(dload)
    loads = np.array([*c0, _moment_form(moment_form)], dtype=np.float64)
    guess, guess_out = _node_tables(start, nnode)
    max_points = _check.count("max_points", max_points, min=1)
    lam0 = _check.real("lam0", lam0)
    ds = _check.real("ds", ds, above=0.0)
    ds_max = _check.real("ds_max", ds_max, above=0.0)
    if not _check.is_int(direction) or int(direction) not in (1, -1):
        _check.fail("direction", direction, "1 or -1 (the sign of the first change of lam)")
    lam_range = _check.reals("lam_range", lam_range, shape=(2,))
    if not lam_range[0] < lam_range[1]:
        _check.fail("lam_range", lam_range, "(lam_min, lam_max) with lam_min < lam_max")
    tol = _check.real("tol", tol, min=0.0)
    check_memory(8 * 7 * nnode * int(max_points), f"max_points = {max_points}: the path")
    npts, lam, nodes, nodes_out = _core.fe_path(
        nbeams, params, int(elements_per_beam), loads, dc, guess, guess_out,
        float(lam0), float(ds), float(ds_max), int(direction), float(lam_range[0]),
        float(lam_range[1]), float(tol), int(max_points))
    npts = int(npts)    # tables (npts, nnode) from (field, nnode, point)
    table = _structured(np.asarray(nodes)[:, :, :npts].transpose(0, 2, 1))
    out = _structured(np.asarray(nodes_out)[:, :, :npts].transpose(0, 2, 1), OUTBOARD_FIELDS)
    return FEPath(lam=np.array(lam[:npts]), nodes=table, load0=c0, dload=dc,
                  elements_per_beam=int(elements_per_beam), outboard=out)


@dataclass
class FEBuckling:
    """Linear buckling of the straight chain under a compressive tip force."""

    load: float             #: critical compressive tip force P_cr, N
    nodes: np.ndarray       #: buckled mode (structured node table), tip w = 1
    elements_per_beam: int
    outboard: np.ndarray | None = None   #: outboard slopes du, dw of the mode


def buckling_load(model: Any, elements_per_beam: int = 8) -> FEBuckling:
    """Critical compressive tip load: least P with K0 phi = P G phi."""
    nbeams, params, _, _ = _mesh(model, elements_per_beam)
    pcr, mode, mode_out = _core.fe_buckling(nbeams, params, int(elements_per_beam))
    return FEBuckling(load=float(pcr), nodes=_structured(np.asarray(mode)),
                      elements_per_beam=int(elements_per_beam),
                      outboard=_structured(np.asarray(mode_out), OUTBOARD_FIELDS))


@dataclass
class ModalCost:
    """Skelton's modal cost (Eq. 128) of a linear free vibration, per mode."""

    omega: np.ndarray       #: frequencies (rad/s), ascending
    eta: np.ndarray         #: modal coordinates Phi^T M q0
    kinetic: np.ndarray     #: int eta'^2 dt over [0, t]
    potential: np.ndarray   #: int omega^2 eta^2 dt over [0, t]
    is_axial: np.ndarray

    @property
    def cost(self) -> np.ndarray:
        """Total cost per mode (Eq. 128)."""
        return self.kinetic + self.potential

    def ranking(self) -> list[int]:
        """1-based mode numbers, most costly first."""
        return list(np.argsort(-self.cost, kind="stable") + 1)

    def select(self, fraction: float = 0.999) -> list[int]:
        """Smallest set of modes (1-based, ascending) holding `fraction` of the cost."""
        fraction = _check.real("fraction", fraction, above=0.0, max=1.0)
        order = np.argsort(-self.cost, kind="stable")
        share = np.cumsum(self.cost[order]) / np.sum(self.cost)
        count = int(np.searchsorted(share, fraction) + 1)
        return sorted(int(i) + 1 for i in order[:count])


@dataclass
class FEModes:
    """Linear natural modes at the straight chain (Eq. 124-126)."""

    omega: np.ndarray        #: all frequencies, rad/s, ascending
    phi: np.ndarray          #: mass-normalized shapes, columns over the free unknowns
    is_axial: np.ndarray     #: True for u (axial) modes
    #: (nfree, 2): node (1-based) and component 1..4 = w, w', u, u' (5, 6 = the
    #: outboard w'+, u'+ of a hinged joint)
    dofs: np.ndarray
    elements_per_beam: int
    rotary_inertia: bool
    _model: Any = field(default=None, repr=False)

    @property
    def transverse(self) -> np.ndarray:
        """Frequencies of the w modes (Table 9), rad/s ascending."""
        return self.omega[~self.is_axial]

    @property
    def axial(self) -> np.ndarray:
        """Frequencies of the u modes (Table 10), rad/s ascending."""
        return self.omega[self.is_axial]

    def shape(self, i: int) -> np.ndarray:
        """Structured node table of mode i (1-based, in ascending order)."""
        return self._tables(i)[0]

    def shape_outboard(self, i: int) -> np.ndarray:
        """Outboard slopes (structured du, dw) of mode i: at a hinge the slopes
        of the outboard beam, elsewhere the node's own."""
        return self._tables(i)[1]

    def _tables(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.omega)
        i = _check.count("mode i", i, min=1, max=n, expected=f"a mode number 1..{n} (1-based, "
                         "ascending frequency)")
        nnode = int(self.dofs[:, 0].max())
        table = np.zeros((5, nnode))
        out = np.zeros((2, nnode))
        rows = {1: 3, 2: 4, 3: 1, 4: 2}
        hinge = np.zeros(nnode, dtype=bool)
        for k, (node, comp) in enumerate(self.dofs):
            value = self.phi[k, i - 1]
            if int(comp) == 5:
                out[1, node - 1] = value
                hinge[node - 1] = True
            elif int(comp) == 6:
                out[0, node - 1] = value
            else:
                table[rows[int(comp)], node - 1] = value
        out[:, ~hinge] = table[[2, 4]][:, ~hinge]
        return _structured(table), _structured(out, OUTBOARD_FIELDS)

    def modal_cost(self, shape: Any, velocity: Any = None, t: float | None = None) -> ModalCost:
        """Skelton's modal cost (Eq. 127-129) of the linear free vibration that
        starts from `shape` (FEStatic or node table) with `velocity` over [0, t]
        (default: the period of the first mode)."""
        nbeams, params, nnode, nfree = _mesh(self._model, self.elements_per_beam, hinged=True)
        t = _check.real("t", t, above=0.0, none=True)
        q0 = _node_table(shape, nnode, "shape")     # a shape is needed (None: no zeros)
        q0_out = _outboard_table(shape, q0, "shape")
        v0, v0_out = _node_tables(velocity, nnode, "velocity")
        span = 2 * np.pi / self.omega[0] if t is None else float(t)
        omega, eta, kin, pot = _core.fe_modal_cost(
            nbeams, params, int(self.elements_per_beam),
            int(self.rotary_inertia), nfree, q0, q0_out, v0, v0_out, span)
        return ModalCost(omega=np.array(omega), eta=np.array(eta), kinetic=np.array(kin),
                         potential=np.array(pot), is_axial=self.is_axial.copy())


def modes(model: Any, elements_per_beam: int = 4, *, rotary_inertia: bool = False) -> FEModes:
    """Linear modes K phi = omega^2 M phi (LAPACK dsygv), split into transverse
    (w) and axial (u) families. Rotary inertia of the end masses (Eq. 130-132)
    is off by default, as in the dissertation's tables."""
    nbeams, params, _, nfree = _mesh(model, elements_per_beam, hinged=True)
    rotary_inertia = _check.flag("rotary_inertia", rotary_inertia)
    check_memory(8 * 3 * nfree**2, f"elements_per_beam = {elements_per_beam}: the modes "
                 f"(dense eigenproblem of {nfree} unknowns)")
    omega, phi, axial, dofs = _core.fe_modes(nbeams, params, int(elements_per_beam),
                                             int(bool(rotary_inertia)), nfree)
    return FEModes(omega=np.array(omega), phi=np.array(phi), is_axial=np.array(axial) != 0,
                   dofs=np.array(dofs).T.copy(), elements_per_beam=int(elements_per_beam),
                   rotary_inertia=bool(rotary_inertia), _model=model)


def axial_modes_linear(model: Any, elements_per_beam: int = 4, *,
                       point_masses: bool = True) -> np.ndarray:
    """Axial frequencies of the linear-u verification model (Eq. 114). Table 7's
    axial column is this model without point masses, from its 2nd frequency."""
    nbeams, params, _, _ = _mesh(model, elements_per_beam)
    point_masses = _check.flag("point_masses", point_masses)
    omega = _core.fe_axial_linear(nbeams, params, int(elements_per_beam),
                                  int(bool(point_masses)))
    return np.array(omega)


def fe_system(model: Any, q: np.ndarray, load: Any = None, elements_per_beam: int = 2, *,
              rotary_inertia: bool = False, moment_form: str = "eq78") -> dict[str, Any]:
    """Dense energy, internal force, Newton matrix d(NLT - Q)/dq, mass and tip
    load vector at the free unknown vector q (for checks and small studies)."""
    nbeams, params, _, nfree = _mesh(model, elements_per_beam, hinged=True)
    q = np.ascontiguousarray(q, dtype=np.float64)
    if q.shape != (nfree,):
        raise InputError(f"q has shape {q.shape}, expected ({nfree},)")
    comps = np.zeros(3) if load is None else _load_components(load)
    loads = np.array([*comps, _moment_form(moment_form)], dtype=np.float64)
    energy, force, jac, mass, qload = _core.fe_system(
        nbeams, params, int(elements_per_beam), int(bool(rotary_inertia)), q, loads)
    return {"energy": float(energy), "force": np.array(force), "jacobian": np.array(jac),
            "mass": np.array(mass), "load": np.array(qload)}


# --- decks ----------------------------------------------------------------------------
#: Deck tasks of the FE chain and the quantities each can report (docs/fe.md).
FE_TASKS = ("fe_static", "fe_modes")
#: Variables of the deck group &fe.
FE_GROUP = ("elements_per_beam", "moment_form", "rotary_inertia", "point_masses", "steps",
            "tol")


def fe_quantity_names(task: str) -> tuple[str, ...]:
    """Quantity names a deck of `task` may publish (i = 1, 2, ... for the modes)."""
    if task == "fe_static":
        return ("w_tip", "dw_tip", "u_tip", "du_tip", "du_root", "energy", "x_tip", "y_tip")
    if task == "fe_modes":
        return ("omega_w<i>", "omega_u<i>", "omega_w_last", "omega_u_last",
                "omega_u_linear<i>", "omega_u_linear_last", "buckling_load")
    raise InputError(f"task = {task!r}, expected one of {FE_TASKS}")


def evaluate_fe(task: str, model: Any, load: Any = None, *, elements_per_beam: int = 4,
                moment_form: str = "eq78", rotary_inertia: bool = False,
                point_masses: bool = True, steps: int = 0, tol: float = 0.0,
                quantities: Sequence[str] = ()) -> dict[str, float]:
    """Solve an FE deck task and return {quantity: value} for `quantities`.

    fe_static: w_tip, dw_tip, u_tip, du_tip (Tables 11, 12), du_root (the root
    strain u', Table 6), energy, x_tip, y_tip. fe_modes: omega_w<i>, omega_u<i>
    (i-th transverse / axial frequency, Tables 9, 10), omega_w_last,
    omega_u_last, omega_u_linear<i> / omega_u_linear_last (linear-u model of
    Eq. 114 with or without `point_masses`, Table 7) and buckling_load.
    """
    out = {}
    if task == "fe_static":
        r = fe_static(model, load, elements_per_beam, moment_form=moment_form, steps=steps,
                      tol=tol)
        table = {"w_tip": r.tip["w"], "dw_tip": r.tip["dw"], "u_tip": r.tip["u"],
                 "du_tip": r.tip["du"], "du_root": float(r.nodes["du"][0]),
                 "energy": r.energy, "x_tip": float(r.x[-1]), "y_tip": float(r.y[-1])}
        for q in quantities:
            if q not in table:
                raise InputError(f"quantity {q!r} is not an fe_static output "
                                   f"({', '.join(table)})")
            out[q] = float(table[q])
        return out
    if task != "fe_modes":
        raise InputError(f"task = {task!r}, expected one of {FE_TASKS}")
    md = modes(model, elements_per_beam, rotary_inertia=rotary_inertia)
    linear = None
    for q in quantities:
        family, index = _mode_quantity(q)
        if family == "buckling_load":
            out[q] = buckling_load(model, elements_per_beam).load
            continue
        if family == "u_linear":
            if linear is None:
                linear = axial_modes_linear(model, elements_per_beam,
                                            point_masses=point_masses)
            values = linear
        else:
            values = md.transverse if family == "w" else md.axial
        if index is None:
            out[q] = float(values[-1])
        elif 1 <= index <= values.size:
            out[q] = float(values[index - 1])
        else:
            raise InputError(f"quantity {q!r}: the model has {values.size} such modes")
    return out


def _mode_quantity(name: str) -> tuple[str, int | None]:
    """('w' | 'u' | 'u_linear' | 'buckling_load', index or None for last)."""
    if name == "buckling_load":
        return name, None
    for family in ("u_linear", "w", "u"):
        prefix = f"omega_{family}"
        if name.startswith(prefix):
            rest = name[len(prefix):]
            if rest == "_last":
                return family, None
            if rest.isdigit():
                return family, int(rest)
    raise InputError(f"quantity {name!r} is not an fe_modes output (omega_w<i>, "
                       "omega_u<i>, omega_u_linear<i>, *_last, buckling_load)")
