"""The only module that calls the compiled extension ``beamid._ext``.

Functions here take and return numpy arrays and plain numbers and turn the
Fortran status codes into :class:`beamid.InputError` or
:class:`beamid.ConvergenceError`.
"""
from __future__ import annotations

import os
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


# ---------------------------------------------------------------- decks, data, tasks
# beamid_api_deck: the deck and measurement readers and the task runners of
# beamid-batch, so both fronts read, validate and write alike.
_deck_api = _ext.beamid_api_deck


def _text(value) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "surrogateescape")
    return str(value).rstrip("\x00 ")


def _path(path) -> bytes:
    """A file path for Fortran: its bytes (f2py refuses non-ASCII str)."""
    return os.fsencode(str(path))


def _raise(code: int, message) -> None:
    if code:
        raise_for_status(int(code), _text(message))


def read_deck(path: str) -> dict:
    """Read and validate a deck with the Fortran reader (beamid_deck); every
    problem found is in the InputError's message, one per line."""
    sizes, reals, text, code, message = _deck_api.api_deck_sizes(_path(path))
    _raise(code, message)
    (nbeams, nparams, nwrt, nt, nexp, nfree, nprior, ncand, ndata, has_load, shape_points,
     fe_epb, fe_form, fe_rotary, fe_masses, fe_steps, sim_epb, sim_integrator, sim_friction,
     max_iter, load_kind) = (int(v) for v in sizes)
    (params, wrt, t_out, exp_kind, exp_values, free, prior_index, prior_mean, prior_sigma,
     code, message) = _deck_api.api_deck_arrays(_path(path), nparams, nwrt, nt, nexp, nfree,
                                                 nprior)
    _raise(code, message)
    lines = _text(text).split("\n")
    names = lines[3:3 + nexp]
    return {
        "nbeams": nbeams, "task": lines[0], "output": lines[1], "data_path": lines[2],
        "params": np.array(params, dtype=float), "wrt": [int(i) - 1 for i in wrt],
        "t_out": np.array(t_out, dtype=float), "has_load": bool(has_load),
        "load": (int(load_kind), [float(x) for x in reals[:4]]),
        "shape_points": shape_points, "tol": float(reals[4]),
        "fe": {"elements_per_beam": fe_epb, "moment_form": ("eq78", "exact")[fe_form],
               "rotary_inertia": bool(fe_rotary), "point_masses": bool(fe_masses),
               "steps": fe_steps, "tol": float(reals[5])},
        "simulate": {"elements_per_beam": sim_epb,
                     "integrator": ("rk4", "implicit")[sim_integrator],
                     "friction": ("sign", "smooth", "sign_literal")[sim_friction],
                     "dt": float(reals[6]) or None, "rtol": float(reals[7]) or None,
                     "atol": float(reals[8]) or None, "motor_gain": float(reals[9]),
                     "friction_velocity": float(reals[10]) or None},
        "experiments": [(n, int(k), [float(x) for x in v])
                        for n, k, v in zip(names, exp_kind, np.array(exp_values).T)],
        "free": [int(i) - 1 for i in free],
        "prior": [(int(i) - 1, float(m), float(s))
                  for i, m, s in zip(prior_index, prior_mean, prior_sigma)],
        "candidates": lines[3 + nexp:3 + nexp + ncand], "alpha": float(reals[11]),
        "max_iter": max_iter, "ndata": ndata,
        "published": _published_groups(lines[3 + nexp + ncand:]),
    }


def _published_groups(lines: list[str]) -> list[dict]:
    """The &published groups from the reader's lines ('P table row note',
    'Q quantity value digits', 'D deviation'; tab separated)."""
    groups: list[dict] = []
    for line in lines:
        kind, *fields = line.split("\t")
        if kind == "P":
            groups.append({"table": fields[0], "row": fields[1], "note": fields[2],
                           "values": {}, "deviations": []})
        elif kind == "Q":
            groups[-1]["values"][fields[0]] = (float(fields[1]), int(fields[2]))
        elif kind == "D":
            groups[-1]["deviations"].append(fields[0])
    return groups


def run_deck(path: str, task: str = "") -> list[str]:
    """Run a deck's task (or `task`, an estimation task for an estimation
    deck) as beamid-batch does (beamid_tasks); the files written."""
    written, code, message = _deck_api.api_run_deck(_path(path), task)
    _raise(code, message)
    return [line for line in _text(written).split("\n") if line]


@lru_cache(maxsize=None)
def quantity_labels() -> tuple[str, ...]:
    """Names of the measurable quantities, in code order (1-based codes)."""
    return tuple(q for q in _text(_deck_api.api_quantity_labels()).split("\n") if q)


def read_measurements(path: str):
    """Rows of a measurement CSV, validated by beamid_measurements: experiment
    names, t, quantity names, value, sigma, source lines."""
    nrow, code, message = _deck_api.api_measurements_size(_path(path))
    _raise(code, message)
    t, value, sigma, line, quantity, exp_index, names, code, message = \
        _deck_api.api_measurements_read(_path(path), int(nrow))
    _raise(code, message)
    exps = _text(names).split("\n")
    labels = quantity_labels()
    return (tuple(exps[int(k) - 1] for k in exp_index), np.array(t, dtype=float),
            tuple(labels[int(q) - 1] for q in quantity), np.array(value, dtype=float),
            np.array(sigma, dtype=float), tuple(int(x) for x in line))


def exit_code(code: int) -> int:
    """Exit code of a status code (the one table in beamid_status)."""
    return int(_deck_api.api_exit_code(int(code)))
