"""Exceptions raised by beamid.

Every status code returned by the Fortran core maps to one of these:
negative codes are input errors, positive codes numerical failures.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path


class BeamidError(Exception):
    """Base class of every beamid error.

    ``exit_code`` is the exit code of the command line for this error (the
    table of docs/decks.md: 2 bad input, 3 numerical failure, 4 an output
    file cannot be written), the same as beamid-batch's."""

    exit_code: int = 2


class InputError(BeamidError, ValueError):
    """A bad deck, file row, parameter name or nonphysical value."""


#: memory bound of an array a user asks for (bytes; the deck reader's bound too)
MAX_BYTES = 4 * 2**30


def check_memory(need: float, subject: str, digits: str = ".3g") -> None:
    """InputError "<subject> would need about N GiB of memory (limit 4 GiB)"
    when ``need`` bytes exceed :data:`MAX_BYTES` (``digits``: N's format)."""
    if need > MAX_BYTES:
        raise InputError(f"{subject} would need about {need / 2**30:{digits}} GiB of memory "
                         f"(limit {MAX_BYTES / 2**30:.0f} GiB)")


class ConvergenceError(BeamidError, RuntimeError):
    """A numerical method did not converge (the message says which and how far)."""

    exit_code = 3


#: status code of an output file that cannot be written (beamid_status ERR_OUTPUT)
ERR_OUTPUT = -4


def raise_for_status(code: int, message: str) -> None:
    """Raise the exception that matches a Fortran status code (0: no error;
    ``message`` decoded by the caller, beamid._core._text)."""
    if code == 0:
        return
    text = message.strip() or f"beamid status {code}"
    if code < 0:
        error = InputError(text)
        if code == ERR_OUTPUT:
            error.exit_code = 4
        raise error
    raise ConvergenceError(text)


class OutputError(BeamidError, OSError):
    """An output file or folder cannot be written (exit code 4 of both programs)."""

    exit_code = 4


def _write_all(outputs: list[tuple[Path, object]]) -> list[Path]:
    """The one all-or-none writer of the Python outputs: write every output
    through a temporary file in its folder and rename them only when all are
    written: all files or none (OutputError, exit code 4)."""
    temps: list[tuple[str, Path]] = []
    try:
        for path, write in outputs:
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                       suffix=path.suffix)
            os.close(fd)
            temps.append((tmp, path))
            write(tmp)
            os.chmod(tmp, 0o666 & ~_umask())
        for tmp, path in temps:
            os.replace(tmp, path)
    except BaseException as exc:
        for tmp, _ in temps:
            if os.path.exists(tmp):
                os.unlink(tmp)
        if isinstance(exc, OSError):
            raise OutputError(f"cannot write {exc.filename or path}: "
                              f"{exc.strerror or exc}") from None
        raise
    return [path for _, path in temps]


def _write_text(path: Path, text: str) -> list[Path]:
    """Write one text file all or none (:func:`_write_all`)."""
    return _write_all([(Path(path), lambda tmp: Path(tmp).write_text(text))])


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
