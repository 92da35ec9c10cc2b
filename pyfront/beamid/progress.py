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
import threading
from contextlib import contextmanager
from typing import Iterable, Iterator, TypeVar

import numpy as np

T = TypeVar("T")

__all__ = ["progress", "bar_enabled", "watch"]


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


@contextmanager
def watch(total: float, desc: str = "", unit: str = "s",
          enabled: bool | None = None, delay: float = 1.0) -> Iterator[np.ndarray]:
    """A one-entry array for a long Fortran call to write its progress into.

    The Fortran core writes how far it got (for a time integration: the last
    output time reached) into ``slot[0]`` while it runs without Python's lock
    (the binding is ``threadsafe``); on a terminal a thread redraws a tqdm bar
    from it every 0.1 s, from ``delay`` seconds on, so short calls show
    nothing. Elsewhere the slot is filled and nobody looks.

    >>> with watch(2.6, enabled=False) as slot:
    ...     slot[0] = 1.3
    >>> float(slot[0])
    1.3
    """
    slot = np.zeros(1)
    if not bar_enabled(enabled) or not total > 0.0:
        yield slot
        return
    try:
        from tqdm import tqdm
    except ImportError:
        yield slot
        return
    done = threading.Event()

    def redraw() -> None:
        with tqdm(total=float(total), desc=desc or None, unit=unit, file=sys.stderr,
                  leave=False, dynamic_ncols=True, delay=delay,
                  bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} " + unit
                  + " [{elapsed}<{remaining}]") as bar:
            while not done.wait(0.1):
                bar.update(float(slot[0]) - bar.n)
            bar.update(float(slot[0]) - bar.n)   # where the call ended
            bar.refresh()

    thread = threading.Thread(target=redraw, daemon=True)
    thread.start()
    try:
        yield slot
    finally:
        done.set()
        thread.join()
