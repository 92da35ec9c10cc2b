"""Modal test data in: modal parameters as arrays (as EMA software such as
sdypy-EMA returns them) and Universal File Format files (data sets 55, mode
shapes; 58, measured functions, kept for the record) through pyuff, an
optional extra (``pip install 'beamid[uff]'``). Both give the rows of a
:class:`beamid.Modal` experiment (docs/modal.md)::

    data = beamid.modal_rows("M0", freq_hz, shapes, stations, damping=xi)
    uff = beamid.read_uff("test.uff", "M0", {1: "shape_n@1:0.4", 2: "shape_n@2:0.5"})
    uff.data, uff.functions
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from . import _check, observations
from .errors import InputError
from .measurements import Measurements
from .modal import normalize_shape, parse_station

__all__ = ["modal_rows", "read_uff", "UFFModal"]


def _real_shape(column: np.ndarray) -> np.ndarray:
    """A (possibly complex) mode shape turned real: rotated so that its largest
    entry is real, then its real part (a lightly damped mode is nearly real)."""
    if np.iscomplexobj(column):
        k = int(np.argmax(np.abs(column)))
        column = np.real(column * np.exp(-1j * np.angle(column[k])))
    return np.asarray(column, dtype=float)


def _per_mode(name: str, value: Any, n: int) -> np.ndarray:
    """One positive sigma or one per mode (n), as an array of n."""
    v = _check.reals(name, value, scalar=True, min_size=1)
    if v.size not in (1, n) or not np.all(v > 0):
        _check.fail(name, value, f"a positive sigma or {n} of them (one per mode)")
    return np.broadcast_to(v, (n,))


def modal_rows(experiment: str, freq: Any, shapes: Any = None, stations: Sequence[str] = (),
               *, damping: Any = None, modes: Sequence[int] | None = None,
               sigma_freq: float | Sequence[float] = 0.01,
               sigma_damping: float | Sequence[float] = 0.002,
               sigma_shape: float = 0.01) -> Measurements:
    """Rows of a modal experiment from arrays.

    ``freq``: the measured natural frequencies (Hz), one per measured mode;
    ``shapes``: (stations x modes) mode shapes, real or complex (a complex
    mode is rotated real first), each normalized as the experiment predicts
    (:func:`beamid.modal.normalize_shape`: unit norm, the largest entry
    positive and written first, where the experiment reads the sign of its
    model mode); ``stations``: a name per shape row
    (``shape_n@1:0.4``...); ``damping``: the damping ratios (a rows of
    ``damping[k]``; None: no damping rows); ``modes``: the model mode number
    of each measured mode (from :func:`beamid.pair_modes`; default 1, 2, ...).
    Sigmas: per frequency (Hz) or one, per damping ratio or one, one for the
    normalized shape entries.
    """
    experiment = _check.text("experiment", experiment)
    f = _check.reals("freq", freq, min_size=1, min=0.0)
    n = f.size
    if modes is None:
        modes = list(range(1, n + 1))
    if isinstance(modes, (str, bytes)) or not hasattr(modes, "__len__"):
        _check.fail("modes", modes, "a sequence of model mode numbers")
    modes = [_check.count("modes", k, min=1) for k in modes]
    if len(modes) != n or len(set(modes)) != n:
        raise InputError(f"modes = {list(modes)}, expected {n} distinct model mode numbers "
                         "(one per measured frequency)")
    sf = _per_mode("sigma_freq", sigma_freq, n)
    rows: list[tuple[str, float, str, float, float]] = []
    for i, k in enumerate(modes):
        rows.append((experiment, 0.0, f"freq[{k}]", float(f[i]), float(sf[i])))
    if damping is not None:
        z = _check.reals("damping", damping, min_size=1, min=0.0)
        if z.size != n:
            raise InputError(f"damping has {z.size} ratios, expected {n} (one per frequency)")
        sz = _per_mode("sigma_damping", sigma_damping, n)
        for i, k in enumerate(modes):
            rows.append((experiment, 0.0, f"damping[{k}]", float(z[i]), float(sz[i])))
    if shapes is not None:
        if isinstance(stations, str):
            stations = (stations,)
        names = [parse_station(s) for s in stations]
        try:
            arr = np.asarray(shapes)
        except (ValueError, TypeError):
            _check.fail("shapes", shapes, "a (stations x modes) array")
        if np.iscomplexobj(arr):
            if arr.ndim != 2 or not np.all(np.isfinite(arr)):
                _check.fail("shapes", shapes, "a finite (stations x modes) array")
        else:
            arr = _check.reals("shapes", shapes, ndim=2, min_size=1)
        if arr.shape != (len(names), n):
            raise InputError(f"shapes has shape {arr.shape}, expected ({len(names)}, {n}): "
                             "one row per station, one column per frequency")
        ss = _check.real("sigma_shape", sigma_shape, above=0.0)
        for i, k in enumerate(modes):
            col = normalize_shape(_real_shape(arr[:, i]))
            # the largest entry first: the modal experiment signs its mode by
            # the mode's first shape row (beamid_modal_experiments)
            first = int(np.argmax(np.abs(col)))
            for j in [first] + [j for j in range(len(names)) if j != first]:
                kind, beam, s = names[j]
                rows.append((experiment, 0.0, f"{kind}@{beam}:{s:g}[{k}]", float(col[j]), ss))
    for _, _, q, _, _ in rows:
        observations.parse(q)
    return Measurements.from_rows(rows, source="<modal arrays>")


@dataclass(frozen=True)
class UFFModal:
    """What :func:`read_uff` read: the modal rows and the measured functions of
    the data sets 58 (each (label, abscissa, ordinate), for the record)."""

    data: Measurements
    functions: tuple[tuple[str, np.ndarray, np.ndarray], ...]
    frequencies: np.ndarray
    damping: np.ndarray


def _pyuff() -> Any:
    try:
        import pyuff
    except ImportError:
        raise InputError("read_uff needs the optional package pyuff: pip install "
                         "'beamid[uff]' (or pip install pyuff)") from None
    return pyuff


def read_uff(path: Any, experiment: str, stations: Mapping[int, str], *, direction: int = 2,
             modes: Sequence[int] | None = None, sigma_freq: float = 0.01,
             sigma_shape: float = 0.01, sigma_damping: float | None = None) -> UFFModal:
    """Read a Universal File Format file: each data set 55 (analysis type 2,
    normal mode, or 3, complex mode) is a measured mode, its frequency and
    its response at the nodes named in ``stations`` (node number -> station
    name such as ``shape_n@1:0.4``) along ``direction`` (1, 2 or 3: r1, r2,
    r3); its viscous damping ratio gives ``damping[k]`` rows when
    ``sigma_damping`` is given. Data sets 58 are kept in ``functions``.
    ``modes``: the model mode of each measured mode (default 1, 2, ...).
    Needs pyuff (an optional extra)."""
    file = _check.path("path", path)
    experiment = _check.text("experiment", experiment)
    stations = _check.mapping("stations", stations, min_size=1, keys=int)
    direction = _check.count("direction", direction, min=1, max=3)
    sigma_freq = _check.real("sigma_freq", sigma_freq, above=0.0)
    sigma_shape = _check.real("sigma_shape", sigma_shape, above=0.0)
    sigma_damping = _check.real("sigma_damping", sigma_damping, above=0.0, none=True)
    pyuff = _pyuff()
    if not file.is_file():
        raise InputError(f"path = {str(file)!r}: no such file")
    try:
        sets = pyuff.UFF(str(file)).read_sets()
    except Exception as exc:     # pyuff raises bare exceptions on malformed files
        raise InputError(f"{file}: not a readable Universal File Format file ({exc})") from None
    if isinstance(sets, dict):
        sets = [sets]
    freqs, shapes, damp, functions = [], [], [], []
    for ds in sets:
        if ds.get("type") == 58:
            label = f"{ds.get('rsp_node', '?')}:{ds.get('rsp_dir', '?')}/" \
                    f"{ds.get('ref_node', '?')}:{ds.get('ref_dir', '?')}"
            functions.append((label, np.asarray(ds.get("x")), np.asarray(ds.get("data"))))
            continue
        if ds.get("type") != 55 or ds.get("analysis_type") not in (2, 3):
            continue
        nodes = [int(n) for n in np.asarray(ds["node_nums"]).ravel()]
        resp = np.asarray(ds[f"r{direction}"])
        missing = [n for n in stations if n not in nodes]
        if missing:
            raise InputError(f"{file}: data set 55 of mode {ds.get('mode_n')} has no node "
                             f"{missing[0]} (stations name nodes {sorted(stations)})")
        shapes.append([resp[nodes.index(n)] for n in stations])
        if ds.get("analysis_type") == 2:
            freqs.append(float(ds["freq"]))
            damp.append(float(ds.get("modal_damp_vis", 0.0)))
        else:
            s = complex(ds["eig"])
            freqs.append(abs(s) / (2 * np.pi))
            damp.append(-s.real / abs(s) if abs(s) > 0 else 0.0)
    if not freqs:
        raise InputError(f"{file}: no data set 55 with a normal or complex mode")
    arr = np.array(shapes).T
    data = modal_rows(experiment, freqs, arr, list(stations.values()),
                      damping=damp if sigma_damping is not None else None, modes=modes,
                      sigma_freq=sigma_freq, sigma_shape=sigma_shape,
                      sigma_damping=sigma_damping if sigma_damping is not None else 0.002)
    return UFFModal(data=data, functions=tuple(functions), frequencies=np.array(freqs),
                    damping=np.array(damp))
