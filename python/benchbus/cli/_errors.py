"""How the command line fails: one line, and an exit status."""

from __future__ import annotations

import sys

import benchbus as bb


class CliError(Exception):
    """A failure the command line reports in one line, with exit status ``status``."""

    status = 1


class UsageError(CliError):
    """A command line that cannot run as given (exit status 2, as argparse's own errors)."""

    status = 2


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl-C: a KeyboardInterrupt, or one that reached Python as the
    cause of a SystemError (a Ctrl-C landing while the compiled core calls into Python
    logging can come out that way)."""
    return isinstance(exc, KeyboardInterrupt) or (
        isinstance(exc, SystemError) and isinstance(exc.__cause__, KeyboardInterrupt)
    )


def one_line(exc: BaseException) -> str:
    """What went wrong, in one line."""
    if isinstance(exc, ModuleNotFoundError):
        return f"the Python package {exc.name or '?'!r} is needed here and is not installed"
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, bb.ResponseTimeout):
        text += " (is the unit there, at this line format? see --port, --baudrate, --unit)"
    return "; ".join([text, *notes(exc)])


def notes(exc: BaseException) -> list[str]:
    """The notes added to ``exc`` on its way out (a failed stop on leaving a block), each in
    one line."""
    notes = getattr(exc, "__notes__", None)
    return [" ".join(str(n).split()) for n in notes] if isinstance(notes, list) else []


def end_ctrl_c_line() -> None:
    """On a terminal, end the line its ``^C`` echo is on, so what follows starts a line."""
    if sys.stderr.isatty():
        print(file=sys.stderr)
