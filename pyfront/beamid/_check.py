"""The argument checks of the public API: one small validator per kind of
argument (issue 32).

Every public function and class of beamid checks what it is given here,
at its boundary, before anything reaches the Fortran core: a validator
takes the argument's name and value, returns the value converted (an
``int``, a ``float``, a float array, a tuple of names, a ``Path``) and
otherwise raises :class:`beamid.InputError` naming the argument, showing
the value and saying what was expected::

    n = _check.count("max_steps", max_steps, min=0)
    tol = _check.real("tol", tol, min=0.0)
    t = _check.reals("t_out", t_out, min_size=1, ascending=True)
    law = _check.choice("friction", friction, FRICTION_LAWS)

``tests/test_fuzz_api.py`` calls every public callable (and the methods of
its results) with wrong types, negative and huge counts, NaN and
infinities, empty and ragged arrays: each call must return or raise a
:class:`beamid.BeamidError`.
"""
from __future__ import annotations

import math
import numbers
import os
import re
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from .errors import InputError, check_memory

#: largest count that crosses the binding (a C int of the f2py layer)
MAX_COUNT = 2**31 - 1

__all__ = ["MAX_COUNT", "show", "fail", "count", "real", "reals", "choice", "names", "flag",
           "instance", "path", "mapping", "axes", "memory", "text", "is_int", "dask_client"]

memory = check_memory


def show(value: Any, width: int = 60) -> str:
    """A short repr of ``value`` for a message (long ones end with ...)."""
    try:
        if isinstance(value, np.ndarray) and value.size > 8:
            text = f"array of shape {value.shape}"
        else:
            text = repr(value)
    except Exception:  # noqa: BLE001 - a repr that fails must not hide the error
        text = f"<{type(value).__name__}>"
    return text if len(text) <= width else text[: width - 3] + "..."


def fail(name: str, value: Any, expected: str) -> NoReturn:
    """Raise InputError "<name> = <value>, expected <expected>"."""
    raise InputError(f"{name} = {show(value)}, expected {expected}")


def is_int(value: Any) -> bool:
    """An int or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _is_real(value: Any) -> bool:
    return (isinstance(value, numbers.Real) or isinstance(value, (np.integer, np.floating))) \
        and not isinstance(value, (bool, np.bool_))


def count(name: str, value: Any, *, min: int = 0, max: int = MAX_COUNT,
          none: bool = False, expected: str = "") -> int | None:
    """An integer in [min, max] (default max: the binding's largest, 2**31 - 1);
    ``none``: None passes (returned as None); ``expected`` words the refusal
    below ``min`` or of a non-integer (default "an integer >= min")."""
    if value is None and none:
        return None
    words = expected or (f"an integer >= {min}" if max == MAX_COUNT else
                         f"an integer from {min} to {max}")
    if not is_int(value):
        fail(name, value, words + (" (or None)" if none else ""))
    k = int(value)
    if k < min:
        fail(name, value, words)
    if k > max:
        fail(name, value, f"an integer from {min} to {max}" +
             (" (larger does not fit the Fortran core's integers)" if max == MAX_COUNT else ""))
    return k


def real(name: str, value: Any, *, min: float | None = None, max: float | None = None,
         above: float | None = None, below: float | None = None, finite: bool = True,
         none: bool = False, expected: str = "") -> float | None:
    """A real number (not a bool or a string): finite unless ``finite`` is
    False, >= ``min``, <= ``max``, > ``above``, < ``below``; ``none``: None
    passes. ``expected`` words the refusal (default: from the bounds)."""
    if value is None and none:
        return None
    words = expected or _bounds_words(min, max, above, below, finite)
    if not _is_real(value):
        fail(name, value, words)
    v = float(value)
    if math.isnan(v) or (finite and math.isinf(v)):
        fail(name, value, words)
    if (min is not None and v < min) or (max is not None and v > max) or \
            (above is not None and not v > above) or (below is not None and not v < below):
        fail(name, value, words)
    return v


def _bounds_words(min, max, above, below, finite) -> str:
    parts = []
    if above is not None:
        parts.append("> 0" if above == 0 else f"> {above:g}")
    if min is not None:
        parts.append(f">= {min:g}")
    if below is not None:
        parts.append(f"< {below:g}")
    if max is not None:
        parts.append(f"<= {max:g}")
    return ("a finite number" if finite else "a number") + (f" {' and '.join(parts)}"
                                                           if parts else "")


def reals(name: str, value: Any, *, ndim: int = 1, min_size: int = 0,
          shape: tuple[int, ...] | None = None, finite: bool = True,
          min: float | None = None, above: float | None = None, ascending: bool = False,
          scalar: bool = False, none: bool = False) -> np.ndarray | None:
    """A float64 array of ``ndim`` dimensions (``scalar``: a number counts as
    one value), at least ``min_size`` values, of ``shape`` when given,
    finite unless ``finite`` is False, every value >= ``min`` / > ``above``,
    ascending (non-decreasing) when asked; ``none``: None passes."""
    if value is None and none:
        return None
    what = f"{'a sequence' if ndim == 1 else f'a {ndim}-d array'} of " \
           f"{'finite ' if finite else ''}numbers"
    # an array is none of the kinds below (the abstract-class tests cost a
    # few microseconds a call on the fit's and the model's paths)
    if type(value) is np.ndarray:
        pass
    elif isinstance(value, (str, bytes, Mapping, set, frozenset)) or value is None:
        fail(name, value, what)
    elif scalar and _is_real(value):
        value = [value]
    elif isinstance(value, Iterator):
        value = list(value)
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        fail(name, value, what)
    if arr.ndim != ndim:
        fail(name, value, what + f" ({arr.ndim}-d given)")
    if shape is not None and arr.shape != tuple(shape):
        fail(name, value, f"shape {tuple(shape)}, not {arr.shape}")
    if arr.size < min_size:
        fail(name, value, what + f", at least {min_size}")
    bad = np.isnan(arr) | (np.isinf(arr) if finite else False)
    if min is not None:
        bad |= arr < min
    if above is not None:
        bad |= ~(arr > above)
    if bad.any():
        first = arr[bad].flat[0]
        limit = f" >= {min:g}" if min is not None else f" > {above:g}" if above is not None \
            else ""
        fail(name, value, what + limit + f" ({first!r} given)")
    if ascending and arr.size > 1 and np.any(np.diff(arr) < 0):
        fail(name, value, what + " in ascending order")
    return arr


def choice(name: str, value: Any, options: Iterable[str]) -> str:
    """One of the strings ``options``."""
    opts = list(options)
    if not isinstance(value, str) or value not in opts:
        fail(name, value, "one of " + ", ".join(repr(o) for o in opts))
    return value


def text(name: str, value: Any, *, empty: bool = False, none: bool = False) -> str | None:
    """A string (non-empty unless ``empty``); ``none``: None passes."""
    if value is None and none:
        return None
    if not isinstance(value, str) or (not empty and not value):
        fail(name, value, "a string" if empty else "a non-empty string")
    return value


def names(name: str, value: Any, *, allowed: Iterable[str] | None = None,
          min_size: int = 0, unique: bool = False, none: bool = False
          ) -> tuple[str, ...] | None:
    """A tuple of names from a name or an iterable of names (strings),
    each one of ``allowed`` when given, at least ``min_size`` of them,
    distinct when ``unique``; ``none``: None passes."""
    if value is None and none:
        return None
    # the common case, already a tuple of names, without the general checks
    # below (solve_static's and fit's per-call cost; the same result)
    if type(value) is tuple and allowed is None and not unique and \
            len(value) >= min_size and all(type(item) is str for item in value):
        return value
    what = "a name or a sequence of names (strings)"
    if isinstance(value, str):
        value = (value,)
    if isinstance(value, (bytes, Mapping)) or not isinstance(value, Iterable):
        fail(name, value, what)
    try:
        items = tuple(value)
    except Exception:  # noqa: BLE001 - an iterable that fails is not a list of names
        fail(name, value, what)
    for item in items:
        if not isinstance(item, str):
            fail(name, value, what + f" ({show(item)} is not a string)")
    if allowed is not None:
        known = list(allowed)
        for item in items:
            if item not in known:
                fail(name, value, "names from " + ", ".join(known) +
                     f" ({item!r} is not one)")
    if len(items) < min_size:
        fail(name, value, what + f", at least {min_size}")
    if unique:
        for k, item in enumerate(items):
            if item in items[:k]:
                fail(name, value, what + f", each once ({item!r} is given twice)")
    return items


def flag(name: str, value: Any) -> bool:
    """A bool (True/False, numpy's too)."""
    if not isinstance(value, (bool, np.bool_)):
        fail(name, value, "True or False")
    return bool(value)


def instance(name: str, value: Any, types: type | tuple[type, ...], expected: str,
             *, none: bool = False) -> Any:
    """``value`` itself when it is an instance of ``types`` (``expected``
    words them); ``none``: None passes."""
    if value is None and none:
        return None
    if not isinstance(value, types):
        fail(name, value, expected)
    return value


def path(name: str, value: Any, *, none: bool = False) -> Path | None:
    """A file path: a non-empty str or os.PathLike without NUL characters."""
    if value is None and none:
        return None
    if not isinstance(value, (str, os.PathLike)):
        fail(name, value, "a file path (str or os.PathLike)")
    try:
        text_ = os.fspath(value)
    except TypeError:
        fail(name, value, "a file path (str or os.PathLike)")
    if isinstance(text_, bytes):
        text_ = os.fsdecode(text_)
    if not text_ or "\x00" in text_:
        fail(name, value, "a file path (non-empty, without NUL characters)")
    return Path(text_)


def mapping(name: str, value: Any, *, min_size: int = 0, keys: type = str,
            none: bool = False) -> dict | None:
    """A dict copy of a mapping with ``keys``-typed keys and at least
    ``min_size`` entries; ``none``: None passes."""
    if value is None and none:
        return None
    what = f"a mapping (dict){' with at least one entry' if min_size else ''}"
    if not isinstance(value, Mapping):
        fail(name, value, what)
    out = dict(value)
    if len(out) < min_size:
        fail(name, value, what)
    for key in out:
        if not isinstance(key, keys):
            fail(name, value, what + f" keyed by {keys.__name__} ({show(key)} is not)")
    return out


def axes(name: str, value: Any) -> Any:
    """None or a matplotlib Axes to draw on."""
    if value is None:
        return None
    from matplotlib.axes import Axes

    if not isinstance(value, Axes):
        fail(name, value, "None or a matplotlib Axes")
    return value


#: a Dask scheduler address: [protocol://]host:port
_SCHEDULER = r"([a-z]+://)?[^\s:/]+:\d+/?"


def dask_client(name: str, value: Any) -> Any:
    """None, a scheduler address ('tcp://host:8786') or a
    dask.distributed.Client (without Dask installed only None or an
    address passes; nothing connects here)."""
    if value is None:
        return None
    words = "None, a dask.distributed.Client or a scheduler address such as 'tcp://host:8786'"
    if isinstance(value, str):
        if not re.fullmatch(_SCHEDULER, value):
            fail(name, value, words)
        return value
    try:
        import distributed
    except ImportError:
        fail(name, value, words + " (Dask is not installed)")
    if not isinstance(value, distributed.Client):
        fail(name, value, words)
    return value
