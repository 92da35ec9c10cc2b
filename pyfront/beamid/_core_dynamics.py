"""The only module that calls the dynamics part of the extension
(``beamid._ext.beamid_api_dynamics``), through :func:`beamid._core._call`:
status codes become :class:`beamid.InputError` /
:class:`beamid.ConvergenceError`."""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from . import _ext
from ._core import _call, _floats, _text
from .progress import watch

_api = _ext.beamid_api_dynamics


def work_names(nbeams: int) -> tuple[str, ...]:
    """Names of the ledger's work lines of a chain of ``nbeams`` beams, in order."""
    return tuple(_text(_call(_api.api_work_names, nbeams)).split())


def sizes(nbeams: int, params: np.ndarray, nepb: int, gain: float) -> tuple[int, int, int]:
    """(nfree, nstate, nwork) of the dynamic system."""
    nfree, nstate, nwork = _call(_api.api_dyn_sizes, nbeams, _floats(params), nepb, float(gain))
    return int(nfree), int(nstate), int(nwork)


def _with_room_for_events(run: Callable[[int, Any], tuple], t_end: float, maxev: int):
    """Call ``run(maxev, slot)`` under a progress watch until the events fit:
    a run whose info[5] (the number of friction switches) exceeds ``maxev``
    is repeated with room for all of them. Returns its results with info as
    ints and the events cut to their number."""
    while True:
        with watch(t_end, desc="simulate") as slot:
            states, tip, torque, ledger, work, info, events, *rest = run(maxev, slot)
        if int(info[5]) <= maxev:
            break
        maxev = int(info[5])
    nev = int(info[5])
    return (np.array(states), np.array(tip), np.array(torque), np.array(ledger),
            np.array(work), tuple(int(v) for v in info), np.array(events[:, :nev]),
            *(np.array(r) for r in rest))


def simulate(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, gain: float,
             method: int, law: int, vslip: float, dt: float, rtol: float, atol: float,
             h0: float, y_init: np.ndarray | None, t_out: np.ndarray, nstate: int,
             nwork: int, modes: np.ndarray | None = None, maxev: int = 4096):
    """Run the integrator; returns (states, tip, torque, ledger, work, info,
    events). ``modes``: 1-based numbers of the retained linear modes (truncated
    modal model, Eq. 127), None for the full model. ``events``: (7, nev) array
    of the friction switches (time, component, kind, mode before, after,
    force before, after); run again with room for all of them when there were
    more than ``maxev``."""
    use_init = 0 if y_init is None else 1
    y = np.zeros(nstate) if y_init is None else _floats(y_init)
    mode_arr = np.zeros(0, dtype=np.int32) if modes is None else np.asarray(modes, np.int32)
    t_out = np.ascontiguousarray(t_out, dtype=float)
    return _with_room_for_events(
        lambda room, slot: _call(
            _api.api_dyn_simulate_modal, nbeams, _floats(params), nepb, _floats(loads),
            float(gain), int(method), int(law), float(vslip), float(dt), float(rtol),
            float(atol), float(h0), use_init, y, t_out, nwork, mode_arr, int(room), slot),
        t_out[-1] if t_out.size else 0.0, maxev)


def system(nbeams: int, params: np.ndarray, nepb: int, gain: float, law: int, vslip: float,
           q: np.ndarray, v: np.ndarray, x: float, nx: int, nwork: int,
           modes: np.ndarray | None = None) -> dict:
    """Generalized force, work rates, Jacobians K = -dF/dq, C = -dF/dv, M(q);
    with ``modes`` (1-based numbers of the retained linear modes) the
    projected ones of the truncated modal model (Eq. 127: q, v are then the
    modal coordinates, and there is no ``torque`` entry)."""
    head = (nbeams, _floats(params), nepb, float(gain), int(law), float(vslip))
    tail = (_floats(q), _floats(v), np.array([x], dtype=float), nwork)
    if modes is None:
        force, power, torque, *rest = _call(_api.api_dyn_system, *head, nx, *tail)
        extra = {"torque": float(torque)}
    else:
        force, power, *rest = _call(_api.api_dyn_system_modal, *head,
                                    np.asarray(modes, dtype=np.int32), nx, *tail)
        extra = {}
    kmat, cmat, mass, b, p, d, e = rest
    return {"force": np.array(force), "power": np.array(power), **extra, "K": np.array(kmat),
            "C": np.array(cmat), "M": np.array(mass), "b": np.array(b), "p": np.array(p),
            "d": np.array(d), "e": float(e)}


def profile(nbeams: int, params: np.ndarray, nepb: int, q: np.ndarray, npts: int):
    """(s, x, y) of the deformed chain at npts points (npts = nel*nsub + 1)."""
    s, x, y = _call(_api.api_dyn_profile, nbeams, _floats(params), nepb, _floats(q), npts)
    return np.array(s), np.array(x), np.array(y)


def quantity_names() -> tuple[str, ...]:
    """Names of the exported quantities of a release (Fortran beamid_release QTY_*)."""
    _, nq = _api.api_dyn_quantity_name(1)
    return tuple(_text(_api.api_dyn_quantity_name(k)[0]) for k in range(1, nq + 1))


def wrt_names(nbeams: int, nparams: int) -> tuple[str, ...]:
    """Names of the sensitivity indices 1..nparams + nload: the parameters,
    then load_fx, load_fy, load_moment (Fortran release_wrt_name)."""
    _, nload = _api.api_dyn_wrt_name(nbeams, 1)
    return tuple(_text(_api.api_dyn_wrt_name(nbeams, k)[0])
                 for k in range(1, nparams + nload + 1))


def load_names(spec: np.ndarray, tab: np.ndarray) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Work-line names and parameter names of the load histories of the columns
    ``spec`` (9, nld) and table rows ``tab`` (2, ntab) (Fortran beamid_loads)."""
    works, pnames = _call(_api.api_dyn_load_names, np.asfortranarray(spec, dtype=float),
                          np.asfortranarray(tab, dtype=float))
    return tuple(_text(works).split()), tuple(_text(pnames).split())


def forced(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, gain: float,
           method: int, law: int, vslip: float, dt: float, rtol: float, atol: float,
           h0: float, y_init: np.ndarray | None, t_out: np.ndarray, nstate: int, nwork: int,
           modes: np.ndarray | None, wrt: np.ndarray, spec: np.ndarray, tab: np.ndarray,
           maxev: int = 4096):
    """A dynamic experiment with load histories (``spec``, ``tab``: beamid_loads
    columns): (states, tip, torque, ledger, work, info, events, y, dy, ds), as
    :func:`release`; ``wrt`` may be empty."""
    nq = len(quantity_names())
    use_init = 0 if y_init is None else 1
    y = np.zeros(nstate) if y_init is None else _floats(y_init)
    mode_arr = np.zeros(0, dtype=np.int32) if modes is None else np.asarray(modes, np.int32)
    w = np.ascontiguousarray(wrt, dtype=np.int32)
    t_out = np.ascontiguousarray(t_out, dtype=float)
    return _with_room_for_events(
        lambda room, slot: _call(
            _api.api_dyn_forced, nbeams, _floats(params), nepb, _floats(loads), float(gain),
            int(method), int(law), float(vslip), float(dt), float(rtol), float(atol),
            float(h0), use_init, y, t_out, nwork, mode_arr, w, nq, int(room),
            np.asfortranarray(spec, dtype=float), np.asfortranarray(tab, dtype=float), slot),
        t_out[-1] if t_out.size else 0.0, maxev)


def release(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, gain: float,
            method: int, law: int, vslip: float, dt: float, rtol: float, atol: float,
            h0: float, t_out: np.ndarray, nstate: int, nwork: int, wrt: np.ndarray,
            maxev: int = 4096):
    """A release with sensitivities: (states, tip, torque, ledger, work, info,
    events, y, dy, ds); ``wrt`` 1-based indices (parameters, then the load's
    fx, fy, moment); y (nq, nt), dy (nq, nt, nwrt), ds (nstate, nt, nwrt)."""
    nq = len(quantity_names())
    w = np.ascontiguousarray(wrt, dtype=np.int32)
    t_out = np.ascontiguousarray(t_out, dtype=float)
    return _with_room_for_events(
        lambda room, slot: _call(
            _api.api_dyn_release, nbeams, _floats(params), nepb, _floats(loads), float(gain),
            int(method), int(law), float(vslip), float(dt), float(rtol), float(atol),
            float(h0), nstate, t_out, nwork, w, nq, int(room), slot),
        t_out[-1] if t_out.size else 0.0, maxev)
