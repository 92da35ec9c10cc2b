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
        if _is_output_status(code):
            raise OutputError(text)
        raise InputError(text)
    raise ConvergenceError(text)


#: exit code of an unwritable output (beamid_status; docs/development.md)
_EXIT_OUTPUT = 4


def _is_output_status(code: int) -> bool:
    """Whether a status code means "an output cannot be written", asked of the
    Fortran table of exit codes (beamid_status exit_code, exported as
    ``beamid._core.exit_code`` when the core has it), so the code is not
    repeated here."""
    try:
        from ._core import exit_code
    except ImportError:       # a core without the exit-code table
        return False
    return exit_code(int(code)) == _EXIT_OUTPUT
