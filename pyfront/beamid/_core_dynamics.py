"""The only module that calls the dynamics part of the extension
(``beamid._ext.beamid_api_dynamics``); status codes become
:class:`beamid.InputError` / :class:`beamid.ConvergenceError`."""
from __future__ import annotations

import numpy as np

from . import _ext
from .errors import raise_for_status

_api = _ext.beamid_api_dynamics


def sizes(nbeams: int, params: np.ndarray, nepb: int, gain: float) -> tuple[int, int, int]:
    """(nfree, nstate, nwork) of the dynamic system."""
    nfree, nstate, nwork, code, message = _api.api_dyn_sizes(
        nbeams, np.asarray(params, dtype=float), nepb, float(gain))
    raise_for_status(int(code), message)
    return int(nfree), int(nstate), int(nwork)


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
    y = np.zeros(nstate) if y_init is None else np.asarray(y_init, dtype=float)
    mode_arr = np.zeros(0, dtype=np.int32) if modes is None else np.asarray(modes, np.int32)
    while True:
        (states, tip, torque, ledger, work, info, events, code,
         message) = _api.api_dyn_simulate_modal(
            nbeams, np.asarray(params, dtype=float), nepb, np.asarray(loads, dtype=float),
            float(gain), int(method), int(law), float(vslip), float(dt), float(rtol),
            float(atol), float(h0), use_init, y, np.ascontiguousarray(t_out, dtype=float),
            nwork, mode_arr, int(maxev))
        raise_for_status(int(code), message)
        if int(info[5]) <= maxev:
            break
        maxev = int(info[5])
    nev = int(info[5])
    return (np.array(states), np.array(tip), np.array(torque), np.array(ledger),
            np.array(work), tuple(int(v) for v in info), np.array(events[:, :nev]))


def system(nbeams: int, params: np.ndarray, nepb: int, gain: float, law: int, vslip: float,
           q: np.ndarray, v: np.ndarray, x: float, nx: int, nwork: int) -> dict:
    """Generalized force, work rates, Jacobians K = -dF/dq, C = -dF/dv, M(q)."""
    (force, power, torque, kmat, cmat, mass, b, p, d, e, code,
     message) = _api.api_dyn_system(
        nbeams, np.asarray(params, dtype=float), nepb, float(gain), int(law), float(vslip),
        nx, np.asarray(q, dtype=float), np.asarray(v, dtype=float),
        np.array([x], dtype=float), nwork)
    raise_for_status(int(code), message)
    return {"force": np.array(force), "power": np.array(power), "torque": float(torque),
            "K": np.array(kmat), "C": np.array(cmat), "M": np.array(mass),
            "b": np.array(b), "p": np.array(p), "d": np.array(d), "e": float(e)}


def profile(nbeams: int, params: np.ndarray, nepb: int, q: np.ndarray, npts: int):
    """(s, x, y) of the deformed chain at npts points (npts = nel*nsub + 1)."""
    s, x, y, code, message = _api.api_dyn_profile(
        nbeams, np.asarray(params, dtype=float), nepb, np.asarray(q, dtype=float), npts)
    raise_for_status(int(code), message)
    return np.array(s), np.array(x), np.array(y)


def band_solve(kl: int, ku: int, a: np.ndarray, b_imag: np.ndarray, rhs: np.ndarray,
               rhs_imag: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Check of the integrators' band LU kernels: x = A^-1 rhs and
    z = (A + i B)^-1 (rhs + i rhs_imag), A and B dense with band (kl, ku)."""
    a = np.asfortranarray(a, dtype=float)
    x, zr, zi, code, message = _api.api_dyn_band_solve(
        int(kl), int(ku), a, np.asfortranarray(b_imag, dtype=float),
        np.asarray(rhs, dtype=float), np.asarray(rhs_imag, dtype=float))
    raise_for_status(int(code), message)
    return np.array(x), np.array(zr) + 1j * np.array(zi)


def ldlt_solve(k: int, a: np.ndarray, b_imag: np.ndarray, rhs: np.ndarray,
               rhs_imag: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Check of the integrators' symmetric band kernels (half-bandwidth k):
    x = A^-1 rhs and z = (A + i B)^-1 (rhs + i rhs_imag) by L D L^T without
    pivoting, and the band products A rhs and (A + i B)(rhs + i rhs_imag).
    A and B dense, symmetric, positive definite; only their band is read."""
    x, zr, zi, ax, azr, azi, code, message = _api.api_dyn_ldlt_solve(
        int(k), np.asfortranarray(a, dtype=float), np.asfortranarray(b_imag, dtype=float),
        np.asarray(rhs, dtype=float), np.asarray(rhs_imag, dtype=float))
    raise_for_status(int(code), message)
    return (np.array(x), np.array(zr) + 1j * np.array(zi), np.array(ax),
            np.array(azr) + 1j * np.array(azi))


def system_modal(nbeams: int, params: np.ndarray, nepb: int, gain: float, law: int,
                 vslip: float, modes: np.ndarray, eta: np.ndarray, etad: np.ndarray,
                 x: float, nx: int, nwork: int) -> dict:
    """Projected force, Jacobians and mass of a truncated modal model (Eq. 127)."""
    (force, power, kmat, cmat, mass, b, p, d, e, code,
     message) = _api.api_dyn_system_modal(
        nbeams, np.asarray(params, dtype=float), nepb, float(gain), int(law), float(vslip),
        np.asarray(modes, dtype=np.int32), nx, np.asarray(eta, dtype=float),
        np.asarray(etad, dtype=float), np.array([x], dtype=float), nwork)
    raise_for_status(int(code), message)
    return {"force": np.array(force), "power": np.array(power), "K": np.array(kmat),
            "C": np.array(cmat), "M": np.array(mass), "b": np.array(b), "p": np.array(p),
            "d": np.array(d), "e": float(e)}


def quantity_names() -> tuple[str, ...]:
    """Names of the exported quantities of a release (Fortran beamid_release QTY_*)."""
    _, nq = _api.api_dyn_quantity_name(1)
    return tuple(_api.api_dyn_quantity_name(k)[0].decode().strip() for k in range(1, nq + 1))


def wrt_names(nbeams: int, nparams: int) -> tuple[str, ...]:
    """Names of the sensitivity indices 1..nparams + nload: the parameters,
    then load_fx, load_fy, load_moment (Fortran release_wrt_name)."""
    _, nload = _api.api_dyn_wrt_name(nbeams, 1)
    return tuple(_api.api_dyn_wrt_name(nbeams, k)[0].decode().strip()
                 for k in range(1, nparams + nload + 1))


def release(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, gain: float,
            method: int, law: int, vslip: float, dt: float, rtol: float, atol: float,
            h0: float, t_out: np.ndarray, nstate: int, nwork: int, wrt: np.ndarray,
            maxev: int = 4096):
    """A release with sensitivities: (states, tip, torque, ledger, work, info,
    events, y, dy, ds); ``wrt`` 1-based indices (parameters, then the load's
    fx, fy, moment); y (nq, nt), dy (nq, nt, nwrt), ds (nstate, nt, nwrt)."""
    nq = len(quantity_names())
    w = np.ascontiguousarray(wrt, dtype=np.int32)
    while True:
        (states, tip, torque, ledger, work, info, events, y, dy, ds, code,
         message) = _api.api_dyn_release(
            nbeams, np.asarray(params, dtype=float), nepb, np.asarray(loads, dtype=float),
            float(gain), int(method), int(law), float(vslip), float(dt), float(rtol),
            float(atol), float(h0), nstate, np.ascontiguousarray(t_out, dtype=float), nwork,
            w, nq, int(maxev))
        raise_for_status(int(code), message)
        if int(info[5]) <= maxev:
            break
        maxev = int(info[5])
    nev = int(info[5])
    return (np.array(states), np.array(tip), np.array(torque), np.array(ledger),
            np.array(work), tuple(int(v) for v in info), np.array(events[:, :nev]),
            np.array(y), np.array(dy), np.array(ds))
