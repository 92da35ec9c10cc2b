"""Exceptions raised by beamid.

Every status code returned by the Fortran core maps to one of these:
negative codes are input errors, positive codes numerical failures.
"""
from __future__ import annotations


class BeamidError(Exception):
    """Base class of every beamid error.

    ``exit_code`` is the exit code of the command line for this error (the
    table of docs/decks.md: 2 bad input, 3 numerical failure, 4 an output
    file cannot be written), the same as beamid-batch's."""

    exit_code: int = 2


class InputError(BeamidError, ValueError):
    """A bad deck, file row, parameter name or nonphysical value."""


class ConvergenceError(BeamidError, RuntimeError):
    """A numerical method did not converge (the message says which and how far)."""

    exit_code = 3


#: status code of an output file that cannot be written (beamid_status ERR_OUTPUT)
ERR_OUTPUT = -4


def raise_for_status(code: int, message: str | bytes) -> None:
    """Raise the exception that matches a Fortran status code (0: no error)."""
    if code == 0:
        return
    if isinstance(message, bytes):
        message = message.decode("utf-8", "replace")
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
