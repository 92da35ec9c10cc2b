"""The only module that calls the compiled extension ``beamid._ext`` for the
model, the static solvers and the decks (``_core_estimation`` and
``_core_dynamics`` hold the other layers).

One calling convention: :func:`_call` calls an entry point whose last two
results are the status (code, message), turns a bad status into
:class:`beamid.InputError` or :class:`beamid.ConvergenceError` and returns
the other results. Sizes that follow from the arguments are hidden in the
binding (``!f2py intent(hide)``), so the functions here pass arrays only.
"""
from __future__ import annotations

import os
import threading
import weakref
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import _ext
from .errors import InputError, raise_for_status

_static = _ext.beamid_api_static
_fe = _ext.beamid_api_fe
_deck_api = _ext.beamid_api_deck
_modal = _ext.beamid_api_modal


def _text(value) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "surrogateescape")
    return str(value).rstrip("\x00 ")


def _call(entry: Callable[..., Any], *args: Any) -> Any:
    """Call ``entry``; raise on its trailing (code, message) and return the
    other results: one alone, several as a tuple."""
    *values, code, message = entry(*args)
    if code:
        raise_for_status(int(code), _text(message))
    return values[0] if len(values) == 1 else tuple(values)


def _floats(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64)


# ---------------------------------------------------------------- model, static solver

@lru_cache(maxsize=None)
def param_names(nbeams: int) -> tuple[str, ...]:
    """Names of the parameter vector of a chain of ``nbeams`` beams, in order."""
    count = int(_call(_static.api_param_count, nbeams))
    return tuple(_text(_call(_static.api_param_name, nbeams, i)).strip()
                 for i in range(1, count + 1))


@lru_cache(maxsize=None)
def _param_info(nbeams: int) -> tuple[tuple[str, str], ...]:
    return tuple(tuple(_text(x).strip() for x in _call(_static.api_param_info, nbeams, i))
                 for i in range(1, len(param_names(nbeams)) + 1))


def param_units(nbeams: int) -> tuple[str, ...]:
    """Units of the parameter vector of a chain of ``nbeams`` beams, in
    order (``"-"``: none; beamid_model's unit table)."""
    return tuple(unit for unit, _ in _param_info(nbeams))


def param_groups(nbeams: int) -> tuple[str, ...]:
    """What each parameter belongs to, in order: ``"beam"``, ``"point"``
    (a mass point), ``"joint"`` or ``"global"`` (the chain)."""
    return tuple(group for _, group in _param_info(nbeams))


def preset(name: str) -> tuple[int, np.ndarray]:
    """Number of beams and parameter vector of a built-in model."""
    nbeams = int(_call(_static.api_preset_size, name))
    values = _call(_static.api_preset, name, len(param_names(nbeams)))
    return nbeams, np.array(values, dtype=float)


def check_params(nbeams: int, params: np.ndarray) -> None:
    """Raise InputError naming the first bad parameter, if any."""
    _call(_static.api_check_params, nbeams, _floats(params))


def static_solve(nbeams: int, params: np.ndarray, load_kind: int, load_values: np.ndarray,
                 wrt: np.ndarray, tol: float = 0.0):
    """Arc-length static solve; returns outputs, doutputs (8 x nwrt), unknowns, info."""
    outputs, doutputs, unknowns, info = _call(_static.api_static_solve, nbeams, params,
                                              load_kind, load_values, wrt, tol)
    return outputs, doutputs.reshape(8, len(wrt)), unknowns, (int(info[0]), int(info[1]))


def static_shape(nbeams: int, params: np.ndarray, load_kind: int, load_values: np.ndarray,
                 unknowns: np.ndarray, s: np.ndarray, tol: float = 0.0):
    """Shape (x, y, psi, moment) at arc positions s from converged unknowns."""
    x, y, psi, moment = _call(_static.api_static_shape, nbeams, _floats(params), load_kind,
                              _floats(load_values), _floats(unknowns), float(tol),
                              np.ascontiguousarray(s, dtype=float))
    return np.array(x), np.array(y), np.array(psi), np.array(moment)


# ---------------------------------------------------------------- finite element chain
# beamid_api_fe binds beamid_fe_nodes: node tables (5, nnode), outboard slopes
# (2, nnode), loads (fx, fy, moment, moment_form).

def fe_mesh_sizes(nbeams: int, params: np.ndarray, nepb: int) -> tuple[int, int, int, int]:
    """(nnode, nfree, nhinge, half-bandwidth) of the mesh."""
    sizes = _call(_fe.api_fe_mesh_sizes, nbeams, params, nepb)
    return tuple(int(v) for v in sizes)


def fe_static(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, use_guess: int,
              steps: int, tol: float, guess: np.ndarray, guess_out: np.ndarray):
    """(nodes, nodes_out, energy, reactions, residual, info) of a static equilibrium."""
    return _call(_fe.api_fe_static, nbeams, params, nepb, loads, use_guess, steps, tol, guess,
                 guess_out)


def fe_path(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, dload: np.ndarray,
            guess: np.ndarray, guess_out: np.ndarray, lam0: float, ds: float, ds_max: float,
            direction: int, lam_min: float, lam_max: float, tol: float, max_points: int):
    """(npts, lam, nodes, nodes_out) along a path of equilibria."""
    return _call(_fe.api_fe_path, nbeams, params, nepb, loads, dload, guess, guess_out, lam0, ds,
                 ds_max, direction, lam_min, lam_max, tol, max_points)


def fe_buckling(nbeams: int, params: np.ndarray, nepb: int):
    """(pcr, mode, mode_out): linear buckling of the straight chain."""
    return _call(_fe.api_fe_buckling, nbeams, params, nepb)


def fe_modes(nbeams: int, params: np.ndarray, nepb: int, rotary: int, nfree: int):
    """(omega, phi, axial, dofs) of the linear modes."""
    return _call(_fe.api_fe_modes, nbeams, params, nepb, rotary, nfree)


def modal(nbeams: int, params: np.ndarray, nepb: int, loads: np.ndarray, nmodes: int,
          wrt: np.ndarray, kinds: np.ndarray, beams: np.ndarray, s: np.ndarray, nfree: int,
          spin: tuple[float, bool] = (0.0, True), wire_length: float = 0.0):
    """(freq, zeta, damped, q, phi, dq, dfreq, dzeta, dphi, shapes, dshapes, tension,
    dtension) of the modes about the static equilibrium (beamid_modal); ``spin`` =
    (Omega rad/s, coriolis): about a steady hub spin; ``wire_length`` > 0: about a
    radial wire's equilibrium (its tension and dT/dp)."""
    def pad(a: np.ndarray) -> np.ndarray:   # f2py does not pass empty arrays
        return a if a.size else np.zeros(1, dtype=a.dtype)

    spin_arr = np.array([float(spin[0]), 1.0 if spin[1] else 0.0], dtype=np.float64)
    return _call(_modal.api_modal, nbeams, params, nepb, loads, spin_arr, float(wire_length),
                 nmodes, wrt.size,
                 pad(wrt),
                 s.size, pad(kinds), pad(beams), pad(s), nfree)


def fe_axial_linear(nbeams: int, params: np.ndarray, nepb: int, point_masses: int) -> np.ndarray:
    """Axial frequencies of the linear-u model of Eq. 114."""
    return _call(_fe.api_fe_axial_linear, nbeams, params, nepb, point_masses)


def fe_modal_cost(nbeams: int, params: np.ndarray, nepb: int, rotary: int, nfree: int,
                  shape0: np.ndarray, shape0_out: np.ndarray, vel0: np.ndarray,
                  vel0_out: np.ndarray, t: float):
    """(omega, eta, kinetic, potential) of Skelton's modal cost."""
    return _call(_fe.api_fe_modal_cost, nbeams, params, nepb, rotary, nfree, shape0, shape0_out,
                 vel0, vel0_out, t)


def fe_system(nbeams: int, params: np.ndarray, nepb: int, rotary: int, q: np.ndarray,
              loads: np.ndarray):
    """(energy, force, jacobian, mass, load vector) at the free vector q."""
    return _call(_fe.api_fe_system, nbeams, params, nepb, rotary, q, loads)


# ---------------------------------------------------------------- decks, data, tasks
# beamid_api_deck: the deck and measurement readers and the task runners of
# beamid-batch, so both fronts read, validate and write alike.

def _path(path) -> bytes:
    """A file path for Fortran: its bytes (f2py refuses non-ASCII str)."""
    return os.fsencode(str(path))


class Handle:
    """A run held in the extension's handle table (beamid_api_runs) under a
    handle that this object owns: :meth:`close` (or the end of a ``with``
    block, or the collection of the object) releases it with ``closer``."""

    def __init__(self, handle: int, closer) -> None:
        self.id = int(handle)
        self._close = weakref.finalize(self, closer, self.id)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        return not self._close.alive

    def close(self) -> None:
        """Release the run in the extension (again: nothing happens)."""
        self._close()

    def _id(self) -> int:
        if self.closed:
            raise ValueError(f"{self!r}: the {type(self).__name__} is closed")
        return self.id


class DeckHandle(Handle):
    """A deck read once by the Fortran reader of beamid-batch
    (``beamid_deck_run``: the deck and the measurement files it names, each
    opened once), held in the extension under a handle that this object owns.
    Everything a run needs of the deck comes through it: its values
    (:meth:`values`), its measurement rows (:meth:`data`), its task run at
    once (:meth:`run_task`) or, for an estimation deck, in steps whose results
    are returned to the caller (``_core_estimation.deck_task_start`` with the
    handle). :meth:`close` (or the end of a ``with`` block, or the collection
    of the object) releases the deck and what its run computed.

    Raises InputError listing every problem of the deck (file, line, group,
    variable, value)."""

    def __init__(self, path: str | os.PathLike, fit_keys: str = "") -> None:
        self.path = str(path)
        #: &fit items given apart (the command line's), which replace the deck's
        self.fit_keys = fit_keys
        super().__init__(_call(_deck_api.api_deck_open, _path(path), fit_keys),
                         _deck_api.api_deck_close)
        #: held from the start of a run in steps to its write (one run at a time)
        self.lock = threading.RLock()

    def __repr__(self) -> str:
        return f"DeckHandle({self.path!r}, {'closed' if self.closed else 'open'})"

    def __reduce__(self):          # another process reads the file itself
        return (DeckHandle, (self.path, self.fit_keys))

    def values(self) -> dict:
        """The deck's values as the Fortran reader validated them (a new
        dict on each call; the file is not read again)."""
        return _deck_values(self._id())

    def data(self, stage: int = 0):
        """Rows of the deck's measurement file (stage 0) or of stage
        ``stage`` of an identify deck, as :func:`read_measurements`."""
        nrow = _call(_deck_api.api_deck_handle_data_size, self._id(), int(stage))
        return _rows(_call(_deck_api.api_deck_handle_data, self._id(), int(stage), int(nrow)))

    def run_task(self, task: str = "") -> tuple[str, list[str]]:
        """Run the deck's task (or ``task``, an estimation task for an
        estimation deck) as beamid-batch does and write its files:
        ``(summary line, files)``."""
        written, summary = _call(_deck_api.api_deck_handle_task, self._id(), task)
        return _text(summary), [line for line in _text(written).split("\n") if line]


def decks_open() -> int:
    """The number of decks the extension holds (handles not yet closed)."""
    return int(_deck_api.api_deck_handles_open())


def read_deck(path: str, fit_keys: str = "") -> dict:
    """Read and validate a deck with the Fortran reader (beamid_deck); every
    problem found is in the InputError's message, one per line. ``fit_keys``:
    &fit items given apart (``loss = 'huber'``, the command line's), which
    replace the deck's."""
    with DeckHandle(path, fit_keys) as handle:
        return handle.values()


def _deck_values(handle: int) -> dict:
    """The values of the deck held under ``handle`` (api_deck_handle_sizes, _arrays)."""
    sizes, reals, text = _call(_deck_api.api_deck_handle_sizes, handle)
    (nbeams, nparams, nwrt, nt, nexp, nfree, nprior, ncand, ndata, has_load, shape_points,
     fe_epb, fe_form, fe_rotary, fe_masses, fe_steps, sim_epb, sim_integrator, sim_friction,
     max_iter, load_kind) = (int(v) for v in sizes)
    (params, wrt, t_out, free, prior_index, prior_mean,
     prior_sigma) = _call(_deck_api.api_deck_handle_arrays, handle, nparams, nwrt, nt, nfree,
                          nprior)
    nkv = _call(_deck_api.api_deck_handle_spec_size, handle)
    exp_kind, kv_exp, kv_key, kv_value = _call(_deck_api.api_deck_handle_specs, handle, nexp,
                                               nkv)
    key_names = {k.number: name for name, k in spec_keys().items()}
    specs: list[dict] = [{} for _ in range(nexp)]
    for e, k, v in zip(kv_exp, kv_key, kv_value):     # named triples: no layout
        specs[int(e) - 1][key_names[int(k)]] = float(v)
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
        # each experiment: name, kind and its spec by the core's key names
        "experiments": [(n, int(k), spec) for n, k, spec in zip(names, exp_kind, specs)],
        "free": [int(i) - 1 for i in free],
        "prior": [(int(i) - 1, float(m), float(s))
                  for i, m, s in zip(prior_index, prior_mean, prior_sigma)],
        "candidates": lines[3 + nexp:3 + nexp + ncand], "alpha": float(reals[11]),
        "max_iter": max_iter, "ndata": ndata,
        "published": _published_groups(lines[3 + nexp + ncand:]),
        # task identify: one 'S name data free max_iter' line per stage
        "stages": [{"name": f[1], "data_path": f[2],
                    "free": [int(i) - 1 for i in f[3].split(",") if i],
                    "max_iter": int(f[4])}
                   for f in (ln.split("\t") for ln in lines[3 + nexp + ncand:])
                   if f[0] == "S" and len(f) == 5],
        # the &sensor table ('N name observation sigma', sigma 0: none of its
        # own) and the &fit groups whose data is a logger file ('C stage
        # experiment sigma', stage 1-based)
        "sensors": [(f[1], f[2], float(f[3]) or None)
                    for f in (ln.split("\t") for ln in lines[3 + nexp + ncand:])
                    if f[0] == "N" and len(f) == 4],
        "loggers": {int(f[1]) - 1: (f[2], float(f[3]) or None)
                    for f in (ln.split("\t") for ln in lines[3 + nexp + ncand:])
                    if f[0] == "C" and len(f) == 4},
    }


def deck_histories(deck: "str | DeckHandle") -> tuple[np.ndarray, np.ndarray]:
    """A deck's &history groups as the core's columns: spec (10, nh), each
    [experiment (1-based), beamid_loads' layout], and table rows (2, ntab).
    ``deck``: a :class:`DeckHandle` (the deck as read), or a path (read now)."""
    if not isinstance(deck, DeckHandle):
        with DeckHandle(deck) as handle:
            return deck_histories(handle)
    nh, ntab = _call(_deck_api.api_deck_handle_history_sizes, deck._id())
    spec, tab = _call(_deck_api.api_deck_handle_histories, deck._id(), int(nh), int(ntab))
    return (np.array(spec, dtype=float).reshape(10, int(nh)),
            np.array(tab, dtype=float).reshape(2, int(ntab)))


def _published_groups(lines: list[str]) -> list[dict]:
    """The &published groups from the reader's lines ('P table row note',
    'K kind section', 'Q quantity value digits', 'D deviation'; tab separated)."""
    groups: list[dict] = []
    for line in lines:
        kind, *fields = line.split("\t")
        if kind == "P":
            groups.append({"table": fields[0], "row": fields[1], "note": fields[2],
                           "values": {}, "deviations": [], "kind": "", "section": ""})
        elif kind == "K":        # the class of the group's deviations, its docs section
            groups[-1]["kind"], groups[-1]["section"] = fields[0], fields[1]
        elif kind == "Q":
            groups[-1]["values"][fields[0]] = (float(fields[1]), int(fields[2]))
        elif kind == "D":
            groups[-1]["deviations"].append(fields[0])
    return groups


def run_deck(path: str, task: str = "") -> list[str]:
    """Run a deck's task (or `task`, an estimation task for an estimation
    deck) as beamid-batch does (beamid_tasks); the files written."""
    return run_deck_report(path, task)[1]


def run_deck_report(path: str, task: str = "") -> tuple[str, list[str]]:
    """:func:`run_deck` and the summary line beamid-batch prints before the
    files: ``(summary, files)``."""
    with DeckHandle(path) as handle:
        return handle.run_task(task)


@lru_cache(maxsize=None)
def quantity_labels() -> tuple[str, ...]:
    """Names of the observation kinds, in code order (1-based codes;
    beamid_observations, read by beamid.observations)."""
    return tuple(q for q in _text(_deck_api.api_quantity_labels()).split("\n") if q)


@dataclass(frozen=True)
class SpecKey:
    """A key of the core's experiment specs (beamid_family SPEC_KEYS)."""

    name: str
    number: int            # 1-based: the key as the binding takes it
    row: int               # 0-based row in the legacy positional form (number - 1)
    families: tuple[str, ...]
    default: float
    about: str


@lru_cache(maxsize=None)
def spec_keys() -> dict[str, SpecKey]:
    """The core's key table of experiment specs, by name (api_spec_keys):
    the fronts build experiments by these names and keep no copy."""
    text = _text(_call(_ext.beamid_api_estimation.api_spec_keys))
    keys = {}
    for line in text.split("\n"):
        f = line.split("\t")
        if len(f) < 5 or f[0] == "kind":
            continue
        keys[f[0]] = SpecKey(f[0], len(keys) + 1, int(f[1]) - 1, tuple(f[2].split("+")),
                             float(f[3]), f[4])
    return keys


@dataclass(frozen=True)
class Family:
    """An experiment family of the core's registry (beamid_families)."""

    name: str                 #: 'static', 'release', 'modal'
    timed: bool               #: its rows are records in time (a clock offset, a burn-in)
    mesh_key: str             #: the spec key of its elements per beam ('': no mesh)
    kinds: Mapping[int, str]  #: its experiment kinds: code -> words (read-only)

    @property
    def meshed(self) -> bool:
        """Whether its experiments have a mesh of their own (the ``mesh`` candidate)."""
        return bool(self.mesh_key)


@lru_cache(maxsize=None)
def families() -> Mapping[str, Family]:
    """The core's registry of experiment families, by name (api_family_table;
    read-only): the fronts ask it what a family is, not which class an
    experiment is."""
    out = {}
    for line in _text(_call(_ext.beamid_api_estimation.api_family_table)).split("\n"):
        f = line.split("\t")
        if len(f) < 4:
            continue
        kinds = {int(c): w for c, w in (k.split(":", 1) for k in f[3].split(",") if k)}
        out[f[0]] = Family(f[0], f[1] == "1", f[2], MappingProxyType(kinds))
    return MappingProxyType(out)


def family_of_kind(kind: int) -> Family | None:
    """The family that takes experiments of kind code ``kind`` (None: no family)."""
    for fam in families().values():
        if int(kind) in fam.kinds:
            return fam
    return None


def spec_row(name: str) -> int:
    """The 0-based row of spec key ``name`` in a value column (the legacy
    positional form that :attr:`Problem.exp_values` and
    ``Release.encode`` still give: row = the key's number - 1)."""
    return spec_keys()[name].row


def spec_triples_of(specs: Sequence[Mapping[str, float]]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Experiments' specs by the core's key names (one mapping per
    experiment) as the binding's sparse named triples: (1-based experiment,
    key number, value) for every key given a value other than 0, keys in the
    key table's order within each experiment; a key not given takes its
    default in the core. A name that is no key is an InputError."""
    numbers = _key_numbers()
    exp: list[int] = []
    number: list[int] = []
    value: list[float] = []
    for j, spec in enumerate(specs, start=1):
        given = []
        for name, v in spec.items():
            k = numbers.get(name)
            if k is None:
                raise InputError(f"experiment {j}: spec key {name!r} is unknown; expected one "
                                 f"of {', '.join(numbers)}")
            if v != 0.0:
                given.append((k, float(v)))
        given.sort()
        exp += [j] * len(given)
        number += [k for k, _ in given]
        value += [v for _, v in given]
    return (np.array(exp, np.int32), np.array(number, np.int32), np.array(value, float))


@lru_cache(maxsize=None)
def _key_numbers() -> dict[str, int]:
    """Each key's number (1-based, the binding's), by name, in the table's order."""
    return {name: k.number for name, k in spec_keys().items()}


def spec_from_column(values) -> dict[str, float]:
    """The named spec of a value column of the legacy positional form (row
    spec_keys()[name].row; keys past its end are not given)."""
    v = [float(x) for x in values]
    return {k: v[sk.row] for k, sk in spec_keys().items() if sk.row < len(v)}


def spec_triples(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value columns of the legacy positional form (keys by row, one column
    per experiment; :func:`spec_triples_of` takes named specs) as the
    binding's sparse named triples: (1-based experiment, key number, value)
    for every nonzero entry; a key not given takes its default in the core."""
    rows, numbers = _spec_key_order()
    # experiments by column, keys in the table's order within each: the
    # nonzero entries of the transposed table, row by row
    by_exp = np.asarray(values, float).reshape(len(rows), -1)[rows, :].T
    j, k = np.nonzero(by_exp != 0.0)
    return ((j + 1).astype(np.int32), numbers[k], np.array(by_exp[j, k], float))


@lru_cache(maxsize=None)
def _spec_key_order() -> tuple[np.ndarray, np.ndarray]:
    """The rows of the legacy positional form and the key numbers, in the key table's order."""
    keys = list(spec_keys().values())
    return (np.array([k.row for k in keys], np.intp), np.array([k.number for k in keys],
                                                                np.int32))


def spec_column(spec: Mapping[str, float]) -> np.ndarray:
    """A value column of the legacy positional form from named values
    (rows of keys not named are 0: the core fills defaults)."""
    keys = spec_keys()
    col = np.zeros(len(keys))
    for name, v in spec.items():
        col[keys[name].row] = float(v)
    return col


def read_measurements(path: str):
    """Rows of a measurement CSV, validated by beamid_measurements: experiment
    names, t, quantity names, value, sigma, source lines."""
    nrow = _call(_deck_api.api_measurements_size, _path(path))
    return _rows(_call(_deck_api.api_measurements_read, _path(path), int(nrow)))


def _rows(out):
    """read_measurements' tuple from the outputs of a measurement entry."""
    t, value, sigma, line, quantity, exp_index, names, qnames = out
    exps = _text(names).split("\n")
    labels = _text(qnames).split("\n")
    return (tuple(exps[int(k) - 1] for k in exp_index), np.array(t, dtype=float),
            tuple(labels[int(q) - 1] for q in quantity), np.array(value, dtype=float),
            np.array(sigma, dtype=float), tuple(int(x) for x in line))


def exit_code(code: int) -> int:
    """Exit code of a status code (the one table in beamid_status)."""
    return int(_deck_api.api_exit_code(int(code)))
