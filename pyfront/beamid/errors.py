"""Exceptions raised by beamid.

Every status code returned by the Fortran core maps to one of these:
negative codes are input errors, positive codes numerical failures.
"""
from __future__ import annotations


class BeamidError(Exception):
    """Base class of every beamid error."""


class InputError(BeamidError, ValueError):
    """A bad deck, file row, parameter name or nonphysical value."""


class ConvergenceError(BeamidError, RuntimeError):
    """A numerical method did not converge (the message says which and how far)."""


class OutputError(BeamidError, OSError):
    """An output file or folder cannot be written (exit code 4 of both programs)."""


def raise_for_status(code: int, message: str | bytes) -> None:
    """Raise the exception that matches a Fortran status code (0: no error)."""
    if code == 0:
        return
    if isinstance(message, bytes):
        message = message.decode("utf-8", "replace")
    text = message.strip() or f"beamid status {code}"
    if code < 0:
        raise InputError(text)
    raise ConvergenceError(text)
