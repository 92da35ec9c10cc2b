"""Nonlinear finite element dynamics: free and forced response (Chapter IV-V).

    run = beamid.simulate(beamid.pace(J_elbow=0, J_tip=0), beamid.TipForce(fy=8.0),
                          t_out=np.linspace(0, 2.6, 27), elements_per_beam=4)
    run.tip_w, run.tip_u, run.tip_angle      # arrays over t_out
    run.energy, run.work, run.ledger         # energy balance (Table 13)
    run.motor_torque                         # Eq. 150 (0 without motor)
    run.profiles([0.0, 0.65])                # beam shapes (Figure 22)

The initial state is the static equilibrium under ``release`` (a TipForce,
TipMoment or their sum), released at rest. Effects are model parameters,
each off at its null value: ``mu_elbow mu_tip`` (Coulomb friction, Eq.
100-102), ``c_elbow c_tip`` (viscous drag), ``eta`` (Kelvin-Voigt damping),
``J_elbow J_tip`` (rotary inertia, Eq. 130-132; the preset carries the Table 1
values, the dissertation's runs set them to 0), ``r_motor tau_motor`` with
``motor_gain`` (tip motor, Eq. 150-159, with a current-loop lag).

Integrators: ``"implicit"`` (default; Radau IIA order 5 with error control,
tolerance ``rtol`` = ``atol`` = 1e-9 by default, in metres for the
displacements: 1e-6 m on the tip of the dissertation's runs) and ``"rk4"``
(fixed step ``dt``, 1e-5 s by default, the dissertation's). Friction laws:
``"sign"`` (default of both: Eq. 101 with its switches as events, located on
the step's interpolant, and sticking while the other forces stay below mu N;
``run.events`` lists them), ``"smooth"`` (mu N v / sqrt(v^2 + vs^2),
``friction_velocity`` vs) and ``"sign_literal"`` (the literal Fortran
SIGN(1, v), +1 at rest, no events); ``run.friction`` says which law a run
used.

``modes=`` runs the truncated modal model of Section 4.1.4 (Eq. 127) instead of
the full one: ``k`` lowest modes, ``"transverse"`` or mode numbers
(docs/dynamics.md shows why truncation does not pay for this model).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from . import _check, _core_dynamics as _cd
from . import load_histories as _lh
from .errors import InputError, check_memory
from .fe import _mesh_size, _model_args, modes as fe_modes

__all__ = ["Run", "FrictionEvent", "simulate", "SENSITIVITY_QUANTITIES", "FRICTION_LAWS",
           "INTEGRATORS", "DEFAULT_RTOL", "DEFAULT_FRICTION", "DEFAULT_DT", "DEFAULT_FRICTION_VELOCITY", "work_names", "dynamic_system"]

#: Friction laws and their codes in the Fortran core.
FRICTION_LAWS = {"sign": 0, "smooth": 1, "sign_literal": 2}
#: Integrators and their codes.
INTEGRATORS = {"rk4": 0, "implicit": 1}
#: Default relative (and absolute) tolerance of the implicit integrator.
DEFAULT_RTOL = 1.0e-9
#: Default RK4 step (s): the dissertation's (Section 4.1.4).
DEFAULT_DT = 1.0e-5
#: Default friction law of both integrators: Eq. 101's sign, switched as events.
DEFAULT_FRICTION = "sign"
#: Default regularization velocity of the smooth friction law (m/s).
DEFAULT_FRICTION_VELOCITY = 1.0e-4


def _point_name(nbeams: int, k: int) -> str:
    if k == nbeams:
        return "tip"
    return "elbow" if k == 1 else f"joint{k}"


def work_names(nbeams: int) -> tuple[str, ...]:
    """Names of the work lines of the ledger of a chain of ``nbeams`` beams, in the
    order of the work vector (read from the core, as the parameter names):
    friction and drag per mass point, damping, motor."""
    return _cd.work_names(nbeams)


def _warn_chirp(model, nepb: int, loads) -> None:
    """Warn when a chirp sweeps above the mesh's highest frequency (the
    model cannot respond there)."""
    top = _lh.highest_chirp(loads)
    if top <= 0:
        return
    fmax = float(np.max(fe_modes(model, nepb).omega)) / (2 * np.pi)
    if top > fmax:
        warnings.warn(f"loads: a chirp reaches {top:g} Hz, above the highest frequency "
                      f"of the mesh ({fmax:.6g} Hz at elements_per_beam = {nepb}): the "
                      "response there is the mesh's, not the arm's", stacklevel=3)


def _release_loads(release) -> np.ndarray:
    if release is None:
        return np.zeros(4)
    if all(hasattr(release, a) for a in ("fx", "fy", "moment")):
        return np.array([*(_check.real(f"release {a}", getattr(release, a))
                            for a in ("fx", "fy", "moment")), 0.0])
    raise InputError(f"release must be a TipForce, TipMoment or their sum, got "
                     f"{type(release).__name__}")


#: Kinds of friction events (the codes of the Fortran core).
EVENT_KINDS = {0: "start", 1: "zero_velocity", 2: "unstick"}


@dataclass(frozen=True)
class FrictionEvent:
    """A friction switch of the sign law (Eq. 101-102 as events).

    ``kind``: ``"start"`` (the decision at t = 0 for components at rest),
    ``"zero_velocity"`` (a sliding component's velocity reached zero: it
    reverses or sticks), ``"unstick"`` (a sticking component's constraint
    force reached mu N). ``before``/``after``: +1 or -1 sliding (friction
    -mu N sign), 0 sticking. ``force_before``/``force_after``: the friction
    force on the component (N; a sticking one's constraint force)."""

    t: float
    point: str          #: "elbow", "tip" (or "joint<k>")
    component: str      #: "u" or "w"
    kind: str
    before: int
    after: int
    force_before: float
    force_after: float


def _events(nbeams: int, evs: np.ndarray) -> tuple[FrictionEvent, ...]:
    out = []
    for col in np.asarray(evs).T:
        j = int(round(col[1]))
        out.append(FrictionEvent(t=float(col[0]), point=_point_name(nbeams, (j + 1) // 2),
                                 component="u" if j % 2 == 1 else "w",
                                 kind=EVENT_KINDS[int(round(col[2]))],
                                 before=int(round(col[3])), after=int(round(col[4])),
                                 force_before=float(col[5]), force_after=float(col[6])))
    return tuple(out)


@dataclass
class Run:
    """A simulated time history at the output times ``t``."""

    t: np.ndarray                 #: output times (s)
    tip_u: np.ndarray             #: tip axial displacement u (m)
    tip_w: np.ndarray             #: tip transverse displacement w (m)
    tip_angle: np.ndarray         #: tip angle atan2(w', 1 + u') (rad)
    energy: np.ndarray            #: total mechanical energy T + V (N m)
    work: np.ndarray              #: total work of the nonconservative effects (N m)
    motor_torque: np.ndarray      #: motor torque (N m), 0 without motor
    ledger: dict                  #: kinetic, potential, each work line, numerical
    states: np.ndarray            #: (nstate, nt): q, v (and the motor torque state)
    integrator: str
    friction: str                 #: friction law the run used
    elements_per_beam: int
    info: dict                    #: steps, rejected, fevals, jevals, newton
    nfree: int
    #: retained mode numbers of a truncated modal run (1-based), None: full model
    modes: tuple[int, ...] | None = None
    #: friction switches of the sign law (events), in time order
    events: tuple["FrictionEvent", ...] = ()
    #: forward sensitivities (``wrt=``): ``d[quantity][parameter]`` arrays over
    #: ``t`` (quantities as :data:`SENSITIVITY_QUANTITIES`, parameters by name,
    #: the release load's components as ``load_fx``, ``load_fy``, ``load_moment``)
    d: dict = field(default_factory=dict)
    #: state sensitivities: ``dstates[parameter]`` is (nstate, nt)
    dstates: dict = field(default_factory=dict)
    _model: object = field(repr=False, default=None)

    @property
    def q(self) -> np.ndarray:
        """Free unknowns (nfree, nt) in the order of beamid.fe.fe_system."""
        return self.states[: self.nfree]

    @property
    def v(self) -> np.ndarray:
        """Their rates (nfree, nt)."""
        return self.states[self.nfree: 2 * self.nfree]

    @property
    def energy_change(self) -> np.ndarray:
        """E(t) - E(0) (Table 13's Delta Energy)."""
        return self.energy - self.energy[0]

    def __repr__(self) -> str:
        # a summary, not every array (the arrays are the fields)
        end = f"{self.t[-1]:g} s" if self.t.size else "no times"
        tip = f"; tip w at the end {self.tip_w[-1]:.7g} m" if self.tip_w.size else ""
        sens = f"; sensitivities to {', '.join(self.dstates)}" if self.dstates else ""
        return (f"<Run: {self.t.size} output times to {end} ({self.integrator}, friction "
                f"{self.friction}), {self.elements_per_beam} elements per beam{tip}{sens}>")

    def profiles(self, times: Sequence[float] | float, points_per_element: int = 8):
        """Beam shapes at the given output times: a list of (x, y) arrays
        (x = s + u, y = w). Each time must be one of ``run.t``."""
        times = _check.reals("times", times, scalar=True)
        nbeams, params = _model_args(self._model)
        nel = nbeams * self.elements_per_beam
        points_per_element = _check.count("points_per_element", points_per_element, min=1)
        check_memory(8 * 3 * nel * points_per_element,
                     f"points_per_element = {points_per_element}: the profiles", ".2g")
        npts = nel * int(points_per_element) + 1
        out = []
        for tt in times:
            k = int(np.argmin(np.abs(self.t - tt)))
            if abs(self.t[k] - tt) > 1e-9 * max(1.0, abs(tt)):
                raise InputError(f"time {tt} is not an output time of this run")
            _, x, y = _cd.profile(nbeams, params, self.elements_per_beam, self.q[:, k], npts)
            out.append((x, y))
        return out


def _mode_numbers(model, nepb: int, nfree: int, modes) -> tuple[int, ...] | None:
    """The 1-based mode numbers that ``modes`` selects (None: full model)."""
    if modes is None:
        return None
    if isinstance(modes, str):
        if modes != "transverse":
            raise InputError(f"modes = {modes!r}, expected an integer, 'transverse' or a "
                             "sequence of mode numbers")
        rotary = any(v != 0.0 for k, v in model.params.items() if k.startswith("J_"))
        md = fe_modes(model, nepb, rotary_inertia=rotary)
        return tuple(int(i) + 1 for i in np.flatnonzero(~md.is_axial))
    if isinstance(modes, (bool, np.bool_)):
        raise InputError(f"modes = {modes!r}, expected an integer or mode numbers")
    if isinstance(modes, (int, np.integer)):
        if not 1 <= int(modes) <= nfree:
            raise InputError(f"modes = {modes}, expected 1..{nfree} (the model has {nfree} "
                             "modes)")
        return tuple(range(1, int(modes) + 1))
    try:
        nums = [int(m) for m in modes]
    except (TypeError, ValueError, OverflowError) as exc:
        raise InputError(f"modes = {_check.show(modes)}, expected integers") from exc
    if any(float(m) != int(m) for m in modes):
        raise InputError(f"modes = {modes!r}, expected integer mode numbers")
    bad = [m for m in nums if not 1 <= m <= nfree]
    if not nums or bad or len(set(nums)) != len(nums):
        raise InputError(f"modes = {list(modes)!r}: expected distinct mode numbers in "
                         f"1..{nfree}")
    return tuple(sorted(nums))


def simulate(model, release=None, t_out=None, elements_per_beam: int = 4,
             integrator: str = "implicit", motor_gain: float = 0.0,
             dt: float | None = None, rtol: float | None = None, *,
             friction: str | None = None, friction_velocity: float | None = None,
             atol: float | None = None, h0: float | None = None,
             initial_state: np.ndarray | None = None,
             modes: int | str | Sequence[int] | None = None,
             wrt: Sequence[str] | str | None = None,
             loads=None) -> Run:
    """Release the chain from rest at the static shape under ``release`` and
    integrate M q'' + NLT(q) = Q(q, q') (Eq. 98-107) to the times ``t_out``.

    Parameters
    ----------
    model: a :class:`beamid.Model` (effects are its named parameters).
    release: the static tip load held before the release (t = 0).
    t_out: ascending output times (s), starting at or after 0.
    elements_per_beam: mesh ("8 elements" in the dissertation = 4 per beam).
    integrator: ``"implicit"`` (default) or ``"rk4"``.
    motor_gain: gain g of the tip motor, T = -r_motor g Psidot_tip (Eq. 150, 158).
    dt: RK4 step (default 1e-5 s).
    rtol: implicit tolerance per step (default 1e-9; absolute tolerance ``atol``
        = rtol, in m for displacements and rad for slopes; velocity errors count
        as the displacement they cause over the step). The default gives 1e-6 m
        on the tip of the dissertation's runs with the sign law.
    friction: ``"sign"`` (default: Eq. 101 with events and sticking),
        ``"smooth"`` or ``"sign_literal"``.
    friction_velocity: regularization velocity of the smooth law (1e-4 m/s).
    initial_state: a state vector (q, v[, T]) to start from instead of the release.
    modes: truncated modal model (Section 4.1.4, Eq. 127): ``k`` keeps the k
        lowest linear modes, ``"transverse"`` all transverse (w) modes, or a
        sequence of mode numbers (1-based, ascending frequency, as
        :func:`beamid.modes` and the dissertation's #1..#33). The nonlinear
        force is projected on the retained modes; the initial state is
        projected too (eta = Phi^T M q). None (default): the full model.
    wrt: parameter names (and ``"load_fx"``, ``"load_fy"``, ``"load_moment"``
        for the release load) to differentiate with respect to: the forward
        sensitivities (Eq. 135-140; docs/dynamics.md) come back in ``run.d``,
        e.g. ``run.d["tip_w"]["rho1"]``. Full model only; the released shape's
        sensitivity comes from the static equilibrium.
    loads: load histories acting from t = 0 (docs/loads.md): a mapping from
        target (``"tip_fx"``, ``"tip_fy"``, ``"tip_torque"``, ``"motor_open"``) to a
        :class:`beamid.HalfSine`, :class:`beamid.Step`, :class:`beamid.Chirp` or
        :class:`beamid.Table`, or a sequence of (target, history) pairs. Each
        adds a work line to the ledger and its parameters to ``wrt``
        (``tip_fy_amplitude``, ``tip_fy_duration``, ...). With ``release=None``
        the arm starts at rest, undeformed.
    """
    histories = loads
    nbeams, params = _model_args(model)
    _check.choice("integrator", integrator, INTEGRATORS)
    if friction is None:
        friction = DEFAULT_FRICTION
    _check.choice("friction", friction, FRICTION_LAWS)
    _mesh_size(nbeams, elements_per_beam)
    if t_out is None:
        raise InputError("t_out is required (ascending output times in s)")
    t = np.ascontiguousarray(_check.reals("t_out", t_out, scalar=True, min_size=1))
    dt, rtol, atol, h0, friction_velocity = (
        _check.real(name, value, above=0.0, none=True, expected="a positive number")
        for name, value in (("dt", dt), ("rtol", rtol), ("atol", atol), ("h0", h0),
                            ("friction_velocity", friction_velocity)))
    gain = _check.real("motor_gain", motor_gain, min=0.0)
    loads = _release_loads(release)
    nfree, nstate, nwork = _cd.sizes(nbeams, params, int(elements_per_beam), gain)
    # the history arrays (input validation, issue 16)
    check_memory(8 * (nstate + nwork + 8) * t.size, f"t_out has {t.size} times: the history",
                 ".1f")
    if initial_state is not None:
        initial_state = _check.reals("initial_state", initial_state, shape=(nstate,))
    vslip = DEFAULT_FRICTION_VELOCITY if friction_velocity is None else friction_velocity
    kept = _mode_numbers(model, int(elements_per_beam), nfree, modes)
    lspec = ltab = None
    lwork: tuple[str, ...] = ()
    lpars: tuple[str, ...] = ()
    if histories is not None:
        lspec, ltab = _lh.columns(histories)
        lwork, lpars = _cd.load_names(lspec, ltab)
        nwork += len(lwork)
        _warn_chirp(model, int(elements_per_beam), histories)
    wrt_list = _wrt_indices(nbeams, params.size, wrt, lpars)
    d: dict = {}
    dstates: dict = {}
    common = (nbeams, params, int(elements_per_beam), loads, gain, INTEGRATORS[integrator],
              FRICTION_LAWS[friction], vslip, dt or 0.0, rtol or 0.0, atol or 0.0, h0 or 0.0)
    if lspec is not None:
        if wrt_list and kept is not None:
            raise InputError("wrt= (sensitivities) needs the full model: drop modes=")
        if wrt_list and initial_state is not None:
            raise InputError("wrt= (sensitivities) starts from the release: drop "
                             "initial_state=")
        (states, tip, torque, ledger, work, info, evs, yq, dy, ds) = _cd.forced(
            *common, initial_state, t, nstate, nwork,
            None if kept is None else np.array(kept),
            np.array([i for _, i in wrt_list], dtype=np.int32), lspec, ltab)
        if wrt_list:
            qnames = _cd.quantity_names()
            for iq, qn in enumerate(qnames):
                d[qn] = {name: dy[iq, :, j] for j, (name, _) in enumerate(wrt_list)}
            for alias, qn in _QUANTITY_ALIASES.items():
                d[alias] = d[qn]
            dstates = {name: ds[:, :, j] for j, (name, _) in enumerate(wrt_list)}
    elif wrt_list:
        if kept is not None:
            raise InputError("wrt= (sensitivities) needs the full model: drop modes=")
        if initial_state is not None:
            raise InputError("wrt= (sensitivities) starts from the release: drop "
                             "initial_state=")
        (states, tip, torque, ledger, work, info, evs, yq, dy, ds) = _cd.release(
            *common, t, nstate, nwork, np.array([i for _, i in wrt_list]))
        qnames = _cd.quantity_names()
        for iq, qn in enumerate(qnames):
            d[qn] = {name: dy[iq, :, j] for j, (name, _) in enumerate(wrt_list)}
        for alias, qn in _QUANTITY_ALIASES.items():
            d[alias] = d[qn]
        dstates = {name: ds[:, :, j] for j, (name, _) in enumerate(wrt_list)}
    else:
        states, tip, torque, ledger, work, info, evs = _cd.simulate(
            *common, initial_state, t, nstate, nwork, None if kept is None else np.array(kept))
    led = {"kinetic": ledger[0], "potential": ledger[1], "total": ledger[2],
           **dict(zip(work_names(nbeams) + lwork, work)), "numerical": ledger[3]}
    return Run(t=t, tip_u=tip[0], tip_w=tip[1], tip_angle=tip[2], energy=ledger[2],
               work=work.sum(axis=0), motor_torque=torque, ledger=led, states=states,
               integrator=integrator, friction=friction,
               elements_per_beam=int(elements_per_beam),
               info=dict(zip(("steps", "rejected", "fevals", "jevals", "newton", "events",
                              "event_steps"), info)),
               nfree=nfree, modes=kept, events=_events(nbeams, evs), d=d, dstates=dstates,
               _model=model)


#: Quantities of ``Run.d`` (the Fortran table beamid_release QTY_*) ...
SENSITIVITY_QUANTITIES = _cd.quantity_names()
#: ... and the names of Run's own arrays for the same quantities.
_QUANTITY_ALIASES = {"tip_u": "u_tip", "tip_w": "w_tip"}


def _wrt_indices(nbeams: int, nparams: int, wrt,
                 extra: Sequence[str] = ()) -> list[tuple[str, int]]:
    """(name, 1-based Fortran index) of each requested sensitivity; ``extra``:
    the load histories' parameter names, after the release load's."""
    wrt = _check.names("wrt", wrt, none=True)
    if wrt is None:
        return []
    names = _cd.wrt_names(nbeams, nparams) + tuple(extra)
    index = {n: i + 1 for i, n in enumerate(names)}
    for comp in ("fx", "fy", "moment"):
        index[comp] = index[f"load_{comp}"]
    out = []
    for name in wrt:
        if not isinstance(name, str) or name not in index:
            raise InputError(f"wrt: unknown parameter {name!r}; expected one of "
                             f"{', '.join(names)}")
        if any(n == name for n, _ in out):
            raise InputError(f"wrt: {name!r} given twice")
        out.append((name, index[name]))
    return out


def dynamic_system(model, q, v, elements_per_beam: int = 2, *, motor_gain: float = 0.0,
                   friction: str = "smooth", friction_velocity: float = 1e-4,
                   torque_state: float = 0.0,
                   modes: int | str | Sequence[int] | None = None) -> dict:
    """Generalized force F(q, v), work rates, the hand-coded Jacobians
    K = -dF/dq and C = -dF/dv (dense), the motor-lag couplings and M(q), for
    checks against finite differences. With ``modes`` (as in :func:`simulate`)
    q and v are modal coordinates eta, eta' and everything is projected
    (Eq. 127): F~ = Phi^T F(Phi eta, Phi eta'), K~ = -dF~/deta, M~ = Phi^T M Phi."""
    nbeams, params = _model_args(model)
    gain = float(motor_gain)
    nfree, nstate, nwork = _cd.sizes(nbeams, params, int(elements_per_beam), gain)
    kept = _mode_numbers(model, int(elements_per_beam), nfree, modes)
    return _cd.system(nbeams, params, int(elements_per_beam), gain, FRICTION_LAWS[friction],
                      friction_velocity, q, v, torque_state, nstate - 2 * nfree, nwork,
                      None if kept is None else np.array(kept))
