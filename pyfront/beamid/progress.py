"""Progress bars for long runs, shown only to a person watching a terminal.

``progress(items)`` wraps ``items`` in a tqdm bar on standard error when
standard error is a terminal and tqdm can be imported; otherwise (a pipe, a
file, a CI log, tqdm missing) it returns the iterable unchanged, so logs and
captured output never contain bar redraws.

>>> list(progress(range(3), enabled=False))
[0, 1, 2]
"""
from __future__ import annotations

import sys
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")

__all__ = ["progress", "bar_enabled"]


def bar_enabled(enabled: bool | None = None) -> bool:
    """Whether a bar would be drawn: ``enabled`` when given, else whether
    standard error is a terminal."""
    if enabled is not None:
        return bool(enabled)
    stream = sys.stderr
    try:
        return stream is not None and stream.isatty()
    except (AttributeError, ValueError):  # a replaced or closed stream
        return False


def progress(iterable: Iterable[T], total: int | None = None, desc: str = "",
             enabled: bool | None = None) -> Iterable[T] | Iterator[T]:
    """``iterable`` with a tqdm progress bar on standard error.

    Parameters
    ----------
    iterable : the items to go through (each is yielded unchanged).
    total : number of items, when ``len(iterable)`` does not give it.
    desc : a short label in front of the bar.
    enabled : True draws the bar, False never does; None (default) draws it
        only when standard error is a terminal.

    Without a bar (not a terminal, ``enabled=False`` or tqdm not installed)
    the iterable itself is returned.
    """
    if not bar_enabled(enabled):
        return iterable
    try:
        from tqdm import tqdm
    except ImportError:
        return iterable
    return tqdm(iterable, total=total, desc=desc or None, file=sys.stderr,
                leave=False, dynamic_ncols=True)
