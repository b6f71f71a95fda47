"""The command line's arguments: numbers as written, the parser, the shared option groups."""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable
from decimal import Decimal, InvalidOperation
from typing import TYPE_CHECKING, Any, NoReturn

from benchbus._core import to_registers
from benchbus.cli._errors import UsageError

if TYPE_CHECKING:
    from benchbus import ProfileRegister

PROG = "benchbus"


PORT_ENV = "BENCHBUS_PORT"


_INTEGER = re.compile(r"[+-]?(?:0x[0-9a-f]+|[0-9]+)")


def parse_int(text: str) -> int:
    """An integer written in decimal (``100``) or hex (``0x64``), with an optional sign."""
    s = text.strip().lower().replace("_", "")
    if not _INTEGER.fullmatch(s):
        try:
            number = Decimal(s).is_finite()
        except InvalidOperation:
            number = False
        if number:
            raise ValueError(f"{text!r} is not a whole number")
        raise ValueError(f"{text!r} is not a number (write decimal, 100, or hex, 0x64)")
    return int(s, 16 if "x" in s else 10)


#: What a bool (a coil's value) may be written as on the command line.
BOOLS = {"1": True, "on": True, "true": True, "0": False, "off": False, "false": False}


def profile_value(register: ProfileRegister, text: str) -> bool | int | float | str:
    """The value ``text`` (as written on the command line) says for ``register`` of a
    profile: for a bool, true/false, on/off or 1/0 (any case); for a string, the text as it
    is; otherwise a whole number (decimal or 0x hex) or a decimal one (120.5, 1e3), or for
    an enum a member's name. The device checks it against the register (range, steps,
    members) before sending it; anything else is a UsageError naming the register."""
    if register.type == "bool":
        key = text.strip().lower()
        if key not in BOOLS:
            raise UsageError(f"{register.name} takes true or false (on/off, 1/0), got {text!r}")
        return BOOLS[key]
    if register.type == "string":
        return text
    try:
        return parse_int(text)
    except ValueError:
        pass
    if register.enum:
        return text.strip()
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise UsageError(f"{register.name} takes a number (decimal or 0x hex), got {text!r}")
    return value


def integer(low: int, high: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer in ``low..high``."""

    def convert(text: str) -> int:
        try:
            value = parse_int(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{what} must be {low} to {high}, got {text}")
        return value

    convert.__name__ = what  # argparse names the type in some messages
    return convert


#: The value types ``--type`` takes, and how many registers each lies over (the core's).
VALUE_TYPES = {
    kind: len(to_registers(0, kind))
    for kind in ("u16", "i16", "u32", "i32", "u64", "i64", "f32", "f64")
}
#: The layouts ``--order`` takes (see :func:`benchbus.from_registers`).
ORDERS = ("ABCD", "CDAB", "BADC", "DCBA")


def add_value_options(parser: argparse.ArgumentParser, verb: str, scale: str) -> None:
    """``--decimals`` (a number's decimals, which ``scale`` the raw words: "divide"),
    ``--type`` and ``--order`` (values of several registers), as ``verb`` ("read") them."""
    parser.add_argument(
        "--decimals",
        type=integer(0, 9, "decimals"),
        default=0,
        metavar="N",
        help=f"{scale} the values by 10**N",
    )
    parser.add_argument(
        "--type",
        choices=tuple(VALUE_TYPES),
        metavar="TYPE",
        help=f"{verb} values of TYPE ({', '.join(VALUE_TYPES)}), each over 1, 2 or 4 registers",
    )
    parser.add_argument(
        "--order",
        type=str.upper,
        choices=ORDERS,
        metavar="ORDER",
        help="how a --type value lies over its registers: ABCD (default), CDAB (word swap), "
        "BADC (byte swap) or DCBA",
    )


def add_profile_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--profile FILE``: the registers of a device profile, by name (``what`` they do)."""
    parser.add_argument(
        "--profile",
        metavar="FILE",
        help=f"a device profile (a TOML file, or a profile's name: 'benchbus profile list'):"
        f" {what}; its [line] gives the line defaults",
    )


def argument(text: str, convert: Callable[[str], Any], name: str) -> Any:
    """``convert(text)`` for the positional argument ``name``, its failure a usage error as
    argparse words it (for an argument whose meaning depends on other options)."""
    try:
        return convert(text)
    except argparse.ArgumentTypeError as exc:
        raise UsageError(f"argument {name}: {exc}") from None


def parse_units(text: str, low: int = 1, high: int = 255) -> list[int]:
    """Unit addresses from a list of numbers and ranges: ``1-10,17,0x20-0x22``."""
    units: set[int] = set()
    for part in text.split(","):
        bounds = [b for b in (s.strip() for s in part.split("-")) if b] if part.strip() else []
        if not 1 <= len(bounds) <= 2 or part.count("-") != len(bounds) - 1:
            raise ValueError(f"{text!r} is not a list of units (e.g. 1-10,17,0x20)")
        first, last = parse_int(bounds[0]), parse_int(bounds[-1])
        if not low <= first <= last <= high:
            raise ValueError(f"units must be {low} to {high}, in increasing ranges: got {part!r}")
        units.update(range(first, last + 1))
    return sorted(units)


def units_type(low: int, high: int) -> Callable[[str], list[int]]:
    """An argparse type: a list of units in ``low..high`` (see :func:`parse_units`)."""

    def convert(text: str) -> list[int]:
        try:
            return parse_units(text, low, high)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    convert.__name__ = "units"
    return convert


def positive(what: str) -> Callable[[str], float]:
    """An argparse type: a positive number (of seconds, or a factor)."""

    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what}: {text!r} is not a number") from None
        if not 0 < value < 1e9:
            raise argparse.ArgumentTypeError(f"{what} must be > 0, got {text}")
        return value

    convert.__name__ = what
    return convert


seconds = positive("seconds")


def number(text: str) -> float:
    """An argparse type: a finite number (an engineering value)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


_PARITIES = {"n": "N", "none": "N", "e": "E", "even": "E", "o": "O", "odd": "O"}


def parity(text: str) -> str:
    """An argparse type: N, E or O (or none, even, odd; any case)."""
    try:
        return _PARITIES[text.strip().lower()]
    except KeyError:
        raise argparse.ArgumentTypeError(f"parity is N, E or O, got {text!r}") from None


def framing(text: str) -> str:
    """An argparse type: rtu or ascii (any case)."""
    name = text.strip().lower()
    if name not in ("rtu", "ascii"):
        raise argparse.ArgumentTypeError(f"framing is rtu or ascii, got {text!r}")
    return name


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line: ``benchbus: read: <message>``."""

    def error(self, message: str) -> NoReturn:
        """Print the one-line usage error and exit with 2."""
        where = self.prog[len(PROG) :].strip() if self.prog.startswith(PROG) else self.prog
        text = f"{where}: {message}" if where else message
        self.exit(2, f"{PROG}: {text} (see {self.prog} --help)\n")


def _option_group_parser() -> Parser:
    """A parent parser for options that commands share, each left out of the namespace
    unless given: a command's own default would overwrite one given before it (the
    general options stand on both sides), and a line option left out takes the family's
    or profile's default (:func:`benchbus.cli._line.opt`)."""
    return Parser(add_help=False, argument_default=argparse.SUPPRESS)


def general_options() -> Parser:
    """The options every command takes: ``--verbose``, ``--traceback``."""
    parent = _option_group_parser()
    group = parent.add_argument_group("general options")
    group.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        help="log every frame sent and received, in hex, on stderr",
    )
    group.add_argument(
        "--traceback",
        action="store_true",
        help="on an error, show the Python traceback instead of one line",
    )
    return parent


def _rts_delay(text: str) -> tuple[float, float]:
    """An argparse type: ``BEFORE,AFTER`` seconds (the core checks their range)."""
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        before, after = (float(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--rts-delay takes BEFORE,AFTER in seconds, e.g. 0.001,0.001; got {text!r}"
        ) from None
    return before, after


def _framing_options(group: argparse._ArgumentGroup) -> None:
    """``--framing rtu|ascii`` and ``--bytesize 7|8``."""
    group.add_argument(
        "--framing",
        type=framing,
        metavar="rtu|ascii",
        help="Modbus RTU (default) or Modbus ASCII; ASCII's line format is 7E1 unless given",
    )
    group.add_argument(
        "--bytesize",
        type=integer(7, 8, "bytesize"),
        metavar="7|8",
        help="data bits (default 8; 7 with --framing ascii)",
    )


def line_options(unit: bool, rs485: bool = True, framing: bool = True) -> Parser:
    """The line options (``--port``, ``--baudrate``...; ``--unit`` with ``unit``, the RS485
    ones with ``rs485``, ``--framing`` and ``--bytesize`` with ``framing``), each left out of
    the namespace unless given."""
    parent = _option_group_parser()
    group = parent.add_argument_group(
        "line options (defaults: the device family's line format and timing)"
    )
    group.add_argument(
        "--port",
        metavar="PORT",
        help=f"serial port, tcp://HOST[:PORT] or rtu+tcp://HOST:PORT (default ${PORT_ENV})",
    )
    group.add_argument("--baudrate", type=integer(50, 4_000_000, "baudrate"), metavar="BPS")
    group.add_argument("--parity", type=parity, metavar="N|E|O")
    group.add_argument("--stopbits", type=integer(1, 2, "stopbits"), metavar="1|2")
    if framing:
        _framing_options(group)
    if unit:
        group.add_argument("--unit", type=integer(0, 255, "unit"), metavar="N", help="default 1")
    group.add_argument("--timeout", type=seconds, metavar="S", help="seconds to wait for a reply")
    group.add_argument(
        "--retries",
        type=integer(0, 10, "retries"),
        metavar="N",
        help="repeats after a timeout or a corrupt reply",
    )
    if rs485:
        group.add_argument(
            "--rs485",
            action="store_true",
            help="open a board UART in the Linux kernel's RS485 mode (RTS drives the "
            "transceiver; a USB adapter switches by itself and needs none)",
        )
        group.add_argument(
            "--rts-delay",
            type=_rts_delay,
            metavar="BEFORE,AFTER",
            help="with --rs485: seconds from RTS on to the first bit, and after the last",
        )
        group.add_argument(
            "--echo",
            action="store_true",
            help="the adapter hears its own requests (a local echo, which 'benchbus doctor' "
            "finds): each is read back and checked before the reply",
        )
    return parent


def family_options() -> Parser:
    """``--family BLD|C20``, for the commands that talk to a drive."""
    parent = _option_group_parser()
    parent.add_argument(
        "--family",
        type=str.upper,
        choices=("BLD", "C20"),
        help="BLD (BLD2, BLD3H; the default) or C20 (ZBLD.C20)",
    )
    return parent


def add_command(subparsers: Any, name: str, help: str, parents: list[Parser], **kw: Any) -> Any:
    """A command (or a command's action) called ``name`` under ``subparsers``, with the
    option groups of ``parents``; ``help`` is also its description."""
    return subparsers.add_parser(name, help=help, description=help, parents=parents, **kw)
