"""How the command line fails: one line, and an exit status."""

from __future__ import annotations

import sys

import benchbus as bb
from benchbus._families import family


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


#: What the library's messages suggest doing in Python, and the command line's own way
#: to do it (the longest first where one contains another).
CLI_WORDS = (
    ("set both with j2.limits = (low, high)", "set both with 'benchbus j2 set-limits LOW HIGH'"),
    (
        "call reopen() once it is back, or open the Bus with reconnect=True",
        "run the command again once it is back",
    ),
    ("call reopen() once it is back", "run the command again once it is back"),
    ("open the Bus with echo=True: bb.Bus(port, echo=True)", "give the commands --echo"),
    ("open the Bus with echo=True", "give the commands --echo"),
    ("open the Bus with rs485=True", "give the commands --rs485"),
    ("open the Bus without echo=True", "leave out --echo"),
    ("echo=True is for a serial line", "--echo is for a serial line"),
    ("rs485=True is for a local serial port", "--rs485 is for a local serial port"),
    ("rs485=True sets the Linux kernel's RS485 mode", "--rs485 sets the Linux kernel's RS485 mode"),
    ("leave rs485 off", "leave out --rs485"),
    (
        "switch with mode = manual, or set_output(percent, switch_to_manual=True)",
        "run 'benchbus j2 manual' first, or add --manual to set-output",
    ),
)


def in_cli_words(text: str) -> str:
    """``text`` with each suggestion of Python code replaced by the command line's own."""
    for python, command in CLI_WORDS:
        text = text.replace(python, command)
    return text


def one_line(exc: BaseException) -> str:
    """What went wrong, in one line, suggesting the command line's commands and options
    where the library's message suggests Python code."""
    if isinstance(exc, ModuleNotFoundError):
        return f"the Python package {exc.name or '?'!r} is needed here and is not installed"
    text = in_cli_words(" ".join(str(exc).split())) or type(exc).__name__
    if isinstance(exc, bb.WrongDevice):
        text = wrong_device(exc)
    if isinstance(exc, bb.ResponseTimeout):
        text += " (is the unit there, at this line format? see --port, --baudrate, --unit)"
    return "; ".join([text, *notes(exc)])


def wrong_device(exc: bb.WrongDevice) -> str:
    """A unit of another family than the command's, with the command that talks to it."""
    from benchbus.cli._args import PROG  # which imports this module

    expected, other = family(exc.expected), family(exc.looks_like)
    return (
        f"unit {exc.unit} answers but is not {expected.name} (looks like {other.name}: see "
        f"'{PROG} {other.key} --help', or check --port and --unit)"
    )


def notes(exc: BaseException) -> list[str]:
    """The notes added to ``exc`` on its way out (a failed stop on leaving a block), each in
    one line."""
    notes = getattr(exc, "__notes__", None)
    return (
        [in_cli_words(" ".join(str(n).split())) for n in notes] if isinstance(notes, list) else []
    )


def end_ctrl_c_line() -> None:
    """On a terminal, end the line its ``^C`` echo is on, so what follows starts a line."""
    if sys.stderr.isatty():
        print(file=sys.stderr)
