"""The only module that calls the compiled extension ``beamid._ext``.

Functions here take and return numpy arrays and plain numbers and turn the
Fortran status codes into :class:`beamid.InputError` or
:class:`beamid.ConvergenceError`.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from . import _ext
from .errors import raise_for_status

_api = _ext.beamid_api_static


@lru_cache(maxsize=None)
def param_names(nbeams: int) -> tuple[str, ...]:
    """Names of the parameter vector of a chain of ``nbeams`` beams, in order."""
    names, code = _api.api_param_names(nbeams)
    raise_for_status(int(code), f"cannot name the parameters of {nbeams} beams")
    if isinstance(names, bytes):
        names = names.decode()
    return tuple(str(names).split())


def preset(name: str) -> tuple[int, np.ndarray]:
    """Number of beams and parameter vector of a built-in model."""
    nbeams, code, message = _api.api_preset_size(name)
    raise_for_status(int(code), message)
    nparams = len(param_names(int(nbeams)))
    values, code, message = _api.api_preset(name, nparams)
    raise_for_status(int(code), message)
    return int(nbeams), np.array(values, dtype=float)


def check_params(nbeams: int, params: np.ndarray) -> None:
    """Raise InputError naming the first bad parameter, if any."""
    code, message = _api.api_check_params(nbeams, np.asarray(params, dtype=float))
    raise_for_status(int(code), message)


def nout() -> int:
    return int(_api.api_nout())


def static_solve(nbeams: int, params: np.ndarray, load_kind: int, load_values: np.ndarray,
                 wrt: np.ndarray, tol: float = 0.0):
    """Arc-length static solve; returns outputs, doutputs (8 x nwrt), unknowns, info."""
    outputs, doutputs, unknowns, info, code, message = _api.api_static_solve(
        nbeams, params, load_kind, load_values, wrt, tol)
    if code:
        raise_for_status(int(code), message)
    return outputs, doutputs.reshape(8, len(wrt)), unknowns, (int(info[0]), int(info[1]))


def static_shape(nbeams: int, params: np.ndarray, load_kind: int, load_values: np.ndarray,
                 unknowns: np.ndarray, s: np.ndarray, tol: float = 0.0):
    """Shape (x, y, psi, moment) at arc positions s from converged unknowns."""
    s = np.ascontiguousarray(s, dtype=float)
    x, y, psi, moment, code, message = _api.api_static_shape(
        nbeams, np.asarray(params, dtype=float), load_kind,
        np.asarray(load_values, dtype=float), np.asarray(unknowns, dtype=float), float(tol), s)
    raise_for_status(int(code), message)
    return np.array(x), np.array(y), np.array(psi), np.array(moment)


def fe_call(name: str, *args):
    """Call ``beamid_api_fe.<name>``; raise on its trailing (code, message) and
    return the list of the remaining outputs."""
    *values, code, message = getattr(_ext.beamid_api_fe, name)(*args)
    raise_for_status(int(code), message)
    return values


def fe_call_plain(name: str, *args):
    """Call ``beamid_api_fe.<name>`` that returns no status."""
    return getattr(_ext.beamid_api_fe, name)(*args)
