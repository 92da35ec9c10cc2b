"""Static load cases: fixed-direction tip force, tip moment, both, radial wire."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import FRICTION_LAWS as _FRICTION_LAWS, INTEGRATORS as _INTEGRATORS
from . import _check, _core
from . import load_histories as _lh
from .errors import InputError

LOAD_TIP = 1
LOAD_WIRE = 2


def _finite(name: str, value: float) -> float:
    return _check.real(name, value)


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

    def spec(self) -> tuple[int, dict[str, float]]:
        """(kind, the experiment's spec by the core's key names)."""
        return LOAD_TIP, {"fx": self.fx, "fy": self.fy, "moment": self.moment}

    def __add__(self, other: "TipLoad") -> "TipLoad":
        if not isinstance(other, TipLoad):
            return NotImplemented
        return TipLoad(self.fx + other.fx, self.fy + other.fy, self.moment + other.moment)

    def scaled(self, factor: float) -> "TipLoad":
        factor = _check.real("factor", factor)
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

    def spec(self) -> tuple[int, dict[str, float]]:
        """(kind, the experiment's spec by the core's key names)."""
        return LOAD_WIRE, {"wire_length": self.Lw}

    def describe(self) -> str:
        return f"radial wire Lw = {self.Lw:g} m"


Load = TipLoad | RadialWire


LOAD_RELEASE = 3


@dataclass(frozen=True)
class Release:
    """A dynamic experiment (Chapter IV.2, V.2): the finite element model held
    in static equilibrium under the tip ``load`` (same mesh), released at rest
    at t = 0 and integrated as :func:`beamid.simulate` does, with the tip
    motor of Eq. 159 when ``motor_gain`` > 0 (torque -r_motor g Psidot_tip).

    Its data rows have t >= 0 (t = 0: the static shape before the release)
    and the quantities ``u_tip w_tip x_tip y_tip tip_angle x_elbow y_elbow``,
    and ``motor_torque`` with a motor. ``integrator`` ("implicit" or "rk4"),
    ``rtol``, ``dt`` and ``friction`` ("sign", "smooth", "sign_literal") as
    in :func:`beamid.simulate` (None: its defaults). ``friction_velocity``
    is the smooth law's regularization velocity vs in m/s (None: 1e-4 m/s,
    :data:`beamid.dynamics.DEFAULT_FRICTION_VELOCITY`); it is used by the
    smooth law only, so it is refused with another law. The friction
    homotopy of :func:`beamid.fit` (``homotopy=``) fits on the smooth law
    with a shrinking vs before the sign law.

    ``loads``: load histories acting from t = 0 as in :func:`beamid.simulate`
    (a mapping target -> history or (target, history) pairs; docs/loads.md):
    a forced-response experiment, e.g. a hammer test from rest with
    ``load=None`` (the arm at rest, undeformed) or a hub-driven arm with
    ``{"hub": beamid.SpinUp(w_s, T)}``. The fit, diagnose and improve run
    them as any release.
    """

    load: TipLoad | None
    elements_per_beam: int = 4
    motor_gain: float = 0.0
    integrator: str = "implicit"
    rtol: float | None = None
    dt: float | None = None
    friction: str | None = None
    friction_velocity: float | None = None
    loads: object = None

    def __post_init__(self) -> None:
        if self.load is None:
            object.__setattr__(self, "load", TipLoad())
        pairs = () if self.loads is None or (hasattr(self.loads, "__len__")
                                             and len(self.loads) == 0) \
            else tuple(_lh._pairs(self.loads))
        object.__setattr__(self, "loads", pairs)
        if not isinstance(self.load, TipLoad):
            raise InputError(f"Release: load = {self.load!r}, expected a TipForce / TipMoment "
                             "(the static load held before the release)")
        nepb = _check.count("Release: elements_per_beam", self.elements_per_beam, min=1)
        # the bound of the mesh (beamid.fe) for one beam; the chain's is checked by the fit
        _check.memory(8 * 40 * 4 * (nepb + 1), f"Release: elements_per_beam = {nepb}: the mesh")
        object.__setattr__(self, "elements_per_beam", nepb)
        gain = _check.real("Release: motor_gain", self.motor_gain, min=0.0)
        object.__setattr__(self, "motor_gain", gain)
        _check.choice("Release: integrator", self.integrator, _INTEGRATORS)
        friction = "sign" if self.friction is None else self.friction
        _check.choice("Release: friction", friction, _FRICTION_LAWS)
        for name in ("rtol", "dt"):
            v = _check.real(f"Release: {name}", getattr(self, name), above=0.0, none=True)
            object.__setattr__(self, name, v)
        vs = _check.real("Release: friction_velocity", self.friction_velocity, above=0.0,
                         none=True, expected="a regularization velocity > 0 (m/s)")
        if vs is not None and friction != "smooth":
            raise InputError(f"Release: friction_velocity = {vs:g} with friction = "
                             f"{friction!r}, expected friction='smooth' (the velocity "
                             "regularizes the smooth law only)")
        object.__setattr__(self, "friction_velocity", vs)
        spec = {"fx": self.load.fx, "fy": self.load.fy, "moment": self.load.moment,
                "elements_per_beam": float(nepb), "motor_gain": gain,
                "integrator": float(_INTEGRATORS[self.integrator]),
                "friction": float(_FRICTION_LAWS[friction]), "rtol": self.rtol or 0.0,
                "dt": self.dt or 0.0}
        if vs is not None:
            spec["v_slip"] = vs
        object.__setattr__(self, "_spec", spec)

    def encode(self) -> tuple[int, np.ndarray]:
        """(kind, the spec in the legacy positional form: a value column, rows
        from the core's key table, _core.spec_keys; :meth:`spec` gives it by
        name, the form the core takes)."""
        encoded = _core.spec_column(self._spec)
        encoded.setflags(write=False)
        return LOAD_RELEASE, encoded

    def spec(self) -> tuple[int, dict[str, float]]:
        """(kind, the experiment's spec by the core's key names)."""
        return LOAD_RELEASE, dict(self._spec)

    @classmethod
    def decode(cls, values) -> "Release":
        """The Release of a value column of the legacy positional form (as
        :meth:`encode` gives; rows from the core's key table)."""
        keys = _core.spec_keys()
        v = [float(x) for x in _check.reals("values", values,
                                           min_size=keys["dt"].row + 1)]
        for key, n in (("integrator", 2), ("friction", 3)):
            row = keys[key].row
            if v[row] not in (0.0, 1.0, 2.0)[:n]:
                _check.fail(f"values[{row}]", v[row], f"a code of the {key}")
        return cls.from_spec({k: x for k, x in _core.spec_from_column(v).items()
                              if "release" in keys[k].families})

    @classmethod
    def from_spec(cls, spec: dict) -> "Release":
        """The Release of a spec by the core's key names (a deck's experiment;
        keys not given take the core's defaults)."""
        keys = {k: sk for k, sk in _core.spec_keys().items() if "release" in sk.families}
        if not isinstance(spec, dict):
            raise InputError(f"Release.from_spec: spec = {spec!r}, expected a dict of the "
                             f"release's spec keys ({', '.join(keys)})")
        for k in spec:
            if k not in keys:
                raise InputError(f"Release.from_spec: key {k!r} is not a key of a release; "
                                 f"expected one of {', '.join(keys)}")
        v = {k: _check.real(f"Release.from_spec: {k}", spec.get(k, sk.default))
             for k, sk in keys.items()}
        for key, n in (("integrator", 2), ("friction", 3)):
            if v[key] not in (0.0, 1.0, 2.0)[:n]:
                _check.fail(f"Release.from_spec: {key}", v[key], f"a code of the {key}")
        integrators = {c: n for n, c in _INTEGRATORS.items()}
        laws = {c: n for n, c in _FRICTION_LAWS.items()}
        law = laws[int(round(v["friction"]))]
        vs = v.get("v_slip", 0.0)
        return cls(TipLoad(v["fx"], v["fy"], v["moment"]),
                   elements_per_beam=int(round(v["elements_per_beam"])),
                   motor_gain=v["motor_gain"], integrator=integrators[int(round(v["integrator"]))],
                   rtol=v["rtol"] or None, dt=v["dt"] or None, friction=law,
                   # the smooth law's velocity (0: the core's default; a deck's
                   # velocity beside another law is unused there)
                   friction_velocity=vs if vs > 0.0 and law == "smooth" else None)

    @property
    def has_motor(self) -> bool:
        return self.motor_gain > 0.0

    def describe(self) -> str:
        text = f"release from {self.load.describe()}, {self.elements_per_beam} elements per beam"
        if self.friction_velocity is not None:
            text += f", smooth friction vs = {self.friction_velocity:g} m/s"
        text += f", motor gain {self.motor_gain:g}" if self.has_motor else ""
        if self.loads:
            text += ", load histories " + ", ".join(
                f"{t} {type(h).__name__}" for t, h in self.loads)
        return text


LOAD_MODAL = 4


@dataclass(frozen=True)
class Modal:
    """A modal test (issue 27, docs/modal.md): the finite element model held in
    static equilibrium under the tip ``load`` (None: the straight arm; a
    TipForce, a TipMoment taken in its exact form, or their sum; or a
    RadialWire left on during the test, the tip then moving on the wire's
    circle), its modes about that equilibrium measured. Its data rows have t = 0 and the
    quantities ``freq[k]`` (Hz), ``damping[k]`` (damped models) and mode shape
    entries ``shape_n@b:s[k]`` (``shape_t``, ``shape_psi``, ``shape_strain``),
    k the k-th lowest mode of the model; the shape entries of one mode are
    unit-normalized together, the model's mode signed so that the mode's first
    shape row is positive (:func:`beamid.modal_rows` writes the largest
    measured entry first).
    """

    load: TipLoad | RadialWire | None = None
    elements_per_beam: int = 4

    def __post_init__(self) -> None:
        load = TipLoad() if self.load is None else self.load
        if not isinstance(load, (TipLoad, RadialWire)):
            raise InputError(f"Modal: load = {self.load!r}, expected None, a TipForce, a "
                             "TipMoment or a RadialWire")
        object.__setattr__(self, "load", load)
        nepb = _check.count("Modal: elements_per_beam", self.elements_per_beam, min=1)
        _check.memory(8 * 40 * 4 * (nepb + 1), f"Modal: elements_per_beam = {nepb}: the mesh")
        object.__setattr__(self, "elements_per_beam", nepb)

    def encode(self) -> tuple[int, np.ndarray]:
        """(kind, the spec in the legacy positional form, its first 12 values:
        rows from the core's key table; :meth:`spec` gives it by name, the
        form the core takes) (read-only)."""
        encoded = _core.spec_column(self.spec()[1])[:12]
        encoded.setflags(write=False)
        return LOAD_MODAL, encoded

    def spec(self) -> tuple[int, dict[str, float]]:
        """(kind, the experiment's spec by the core's key names)."""
        if isinstance(self.load, RadialWire):
            return LOAD_MODAL, {"wire_length": float(self.load.Lw),
                                "elements_per_beam": float(self.elements_per_beam)}
        return LOAD_MODAL, {"fx": float(self.load.fx), "fy": float(self.load.fy),
                            "moment": float(self.load.moment),
                            "elements_per_beam": float(self.elements_per_beam)}

    def describe(self) -> str:
        return (f"modal test about {self.load.describe()}, {self.elements_per_beam} elements "
                "per beam")


def family(load: object) -> "_core.Family | None":
    """The core's family of an experiment (``beamid.Release(...)`` ->
    the 'release' family: timed, meshed), None for an object that is not an
    experiment. Code that needs to know what an experiment is (records in
    time, a mesh of its own) asks this, not the experiment's class."""
    spec = getattr(load, "spec", None)
    if not callable(spec):
        return None
    try:
        kind, values = spec()
    except Exception:  # noqa: BLE001 - whatever its spec() does, it is no experiment
        return None
    if isinstance(kind, bool) or not isinstance(kind, (int, np.integer)) or \
            not isinstance(values, dict):
        return None
    return _core.family_of_kind(int(kind))


def timed(load: object) -> bool:
    """Whether ``load`` is an experiment whose rows are records in time (the
    core's family is timed: a release), as :func:`family` answers."""
    fam = family(load)
    return fam is not None and fam.timed
