"""The ``benchbus`` command line (also ``python -m benchbus``).

::

    benchbus scan    --port PATH [--units 1-247] [--auto] [--progress]
    benchbus read    --port PATH [--unit N] ADDRESS [COUNT] [--hex | --signed --decimals N]
    benchbus write   --port PATH [--unit N] ADDRESS VALUE [VALUE ...]
    benchbus drive   --port PATH [--family BLD|C20] status|start|stop|reverse|set-speed RPM
                                                  |reset-fault
    benchbus pbl     --port PATH status|start|stop|reverse|set-speed RPM
    benchbus j2      --port PATH status|set-sv VALUE|auto|manual|set-output PERCENT
    benchbus monitor --port PATH drive|pbl|j2 [--interval S] [--count N | --duration S] [--csv FILE]
                                              [--no-reconnect]
    benchbus sim     drive|pbl|j2|instrument|atv31 [--unit N] [--baudrate B] [--seconds S]
    benchbus demo    [--port PATH [--unit N]] [--out FILE.png]
    benchbus ports   (the serial ports, with their USB ids, chip, maker and serial number)
    benchbus doctor  --port PATH [--unit N]  (what stands between benchbus and the port)

The line options (``--port``, ``--baudrate``, ``--parity``, ``--stopbits``, ``--unit``,
``--timeout``, ``--retries``; ``--rs485`` and ``--rts-delay BEFORE,AFTER`` for a board UART in
the Linux kernel's RS485 mode) go anywhere after the command; their defaults are those of the
device family the command talks to. ``--port`` falls back to ``$BENCHBUS_PORT``. Numbers
(addresses, values, units) are decimal or ``0x`` hex.

Errors print one line, ``benchbus: <what went wrong>``, on stderr and exit with 1 (2 for a
usage error, 130 after Ctrl-C; in ``monitor`` and ``sim`` Ctrl-C is the normal end and exits
0). ``--traceback`` shows the Python traceback instead, for a bug report. ``status`` and
``monitor`` refuse a unit recognised as another family than the command's.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime
import enum
import logging
import os
import re
import signal
import sys
import time
from collections.abc import Callable, Sequence
from decimal import Decimal, InvalidOperation
from types import FrameType
from typing import IO, TYPE_CHECKING, Any, NoReturn

import benchbus as bb
from benchbus._clock import ticks
from benchbus._device import NOTED
from benchbus._display import plural
from benchbus._families import FAMILIES, command_families, family, mismatch
from benchbus._gateway import IDLE_TIMEOUT, parse_allow, parse_listen
from benchbus._recognise import Probe
from benchbus._record import with_unit

if TYPE_CHECKING:
    from benchbus.sim import SimDevice

__all__ = ["main"]

PROG = "benchbus"
PORT_ENV = "BENCHBUS_PORT"


# ---- errors ------------------------------------------------------------------------------------


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


def _one_line(exc: BaseException) -> str:
    """What went wrong, in one line."""
    if isinstance(exc, ModuleNotFoundError):
        return f"the Python package {exc.name or '?'!r} is needed here and is not installed"
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, bb.ResponseTimeout):
        text += " (is the unit there, at this line format? see --port, --baudrate, --unit)"
    return "; ".join([text, *_notes(exc)])


def _notes(exc: BaseException) -> list[str]:
    """The notes added to ``exc`` on its way out (a failed stop on leaving a block), each in
    one line."""
    notes = getattr(exc, "__notes__", None)
    return [" ".join(str(n).split()) for n in notes] if isinstance(notes, list) else []


# ---- numbers -----------------------------------------------------------------------------------

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


def _integer(low: int, high: int, what: str) -> Callable[[str], int]:
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


def _units_type(low: int, high: int) -> Callable[[str], list[int]]:
    def convert(text: str) -> list[int]:
        try:
            return parse_units(text, low, high)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    convert.__name__ = "units"
    return convert


def _positive(what: str) -> Callable[[str], float]:
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


_seconds = _positive("seconds")


def _number(text: str) -> float:
    """An argparse type: a finite number (an engineering value)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


_PARITIES = {"n": "N", "none": "N", "e": "E", "even": "E", "o": "O", "odd": "O"}


def _listen(text: str) -> str:
    try:
        parse_listen(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _allow(text: str) -> str:
    try:
        parse_allow(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _unit_interval(text: str) -> tuple[int, float]:
    unit, sep, seconds = text.partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected UNIT=SECONDS, e.g. 5=0.15, not {text!r}")
    number = _number(seconds)
    if not 0.0 <= number <= 60.0:
        raise argparse.ArgumentTypeError(f"seconds must be 0..60, not {seconds!r}")
    return _integer(1, 255, "UNIT")(unit), number


def _parity(text: str) -> str:
    """An argparse type: N, E or O (or none, even, odd; any case)."""
    try:
        return _PARITIES[text.strip().lower()]
    except KeyError:
        raise argparse.ArgumentTypeError(f"parity is N, E or O, got {text!r}") from None


def _word(text: str, decimals: int) -> int:
    """A register word from a value as written on the command line.

    Without ``decimals``: an integer -32768..65535 (decimal or hex; negative values are
    written in two's complement). With ``decimals`` N: a decimal number with at most N
    decimals, written as value x 10**N.
    """
    if decimals == 0:
        try:
            value = parse_int(text)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    else:
        try:
            scaled = Decimal(text.strip()).scaleb(decimals)
        except InvalidOperation:
            raise UsageError(f"{text!r} is not a number") from None
        if not scaled.is_finite() or scaled != scaled.to_integral_value():
            raise UsageError(f"{text!r} has more than {decimals} decimals")
        value = int(scaled)
    if not -0x8000 <= value <= 0xFFFF:
        raise UsageError(f"{text!r} does not fit in a register (-32768 to 65535 raw)")
    return value & 0xFFFF


def _fmt(value: float) -> str:
    """A number for a table: integral values without a fraction, others to 4 decimals."""
    if float(value).is_integer():
        return str(int(value))
    return f"{value:.4f}".rstrip("0").rstrip(".")


def _measured(value: float, unit: str) -> str:
    """A value with its unit: ``1450 rpm``, ``25.3 °C`` (the number alone without one)."""
    return f"{_fmt(value)} {unit}".rstrip()


def _csv_number(value: float) -> str:
    """A number for a CSV file, at full precision."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _name(value: object) -> str:
    """An enum member by its name, anything else as ``str``."""
    return value.name if isinstance(value, enum.Enum) else str(value)


def _table(headers: Sequence[str] | None, rows: Sequence[Sequence[str]]) -> list[str]:
    """Left-aligned columns, two spaces apart."""
    lines = [list(headers)] if headers else []
    lines += [list(r) for r in rows]
    if not lines:
        return []
    widths = [max(len(line[i]) for line in lines if i < len(line)) for i in range(len(lines[0]))]
    return ["  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines]


def _print_table(headers: Sequence[str] | None, rows: Sequence[Sequence[str]]) -> None:
    for line in _table(headers, rows):
        print(line)


# ---- argument parsing --------------------------------------------------------------------------


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line: ``benchbus: read: <message>``."""

    def error(self, message: str) -> NoReturn:
        """Print the one-line usage error and exit with 2."""
        where = self.prog[len(PROG) :].strip() if self.prog.startswith(PROG) else self.prog
        text = f"{where}: {message}" if where else message
        self.exit(2, f"{PROG}: {text} (see {self.prog} --help)\n")


@dataclasses.dataclass(frozen=True)
class Line:
    """A device family's line defaults."""

    baudrate: int
    parity: str
    timeout: float
    retries: int
    unit: int = 1

    def describe(self, stopbits: int = 1) -> str:
        """``19200 8N1``."""
        return f"{self.baudrate} 8{self.parity}{stopbits}"


#: The line defaults of each command (the scan's timeout is per unit probed).
LINES = {
    "scan": Line(19200, "N", 0.05, 0),
    "read": Line(19200, "N", 0.1, 2),
    "write": Line(19200, "N", 0.1, 2),
    "gateway": Line(19200, "N", 0.1, 2),
    **{f.key: Line(*f.line, 2) for f in command_families()},
}

#: The line formats ``scan --auto`` tries, in order, and who uses them.
AUTO_FORMATS: tuple[tuple[int, str, str], ...] = (
    (19200, "N", "BLD2 / BLD3H / ZBLD.C20 drives; J2 and Taisong set to 19200"),
    (115200, "E", "PBL drives"),
    (9600, "N", "J2 controllers and Taisong meters (factory setting)"),
    (4800, "N", "Taisong meters"),
    (2400, "N", "Taisong meters"),
)

_S = argparse.SUPPRESS


def _general_options() -> _Parser:
    parent = _Parser(add_help=False)
    group = parent.add_argument_group("general options")
    group.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=_S,
        help="log every frame sent and received, in hex, on stderr",
    )
    group.add_argument(
        "--traceback",
        action="store_true",
        default=_S,
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


def _line_options(unit: bool, rs485: bool = True) -> _Parser:
    parent = _Parser(add_help=False)
    group = parent.add_argument_group(
        "line options (defaults: the device family's line format and timing)"
    )
    group.add_argument(
        "--port",
        metavar="PORT",
        default=_S,
        help=f"serial port, tcp://HOST[:PORT] or rtu+tcp://HOST:PORT (default ${PORT_ENV})",
    )
    group.add_argument(
        "--baudrate", type=_integer(50, 4_000_000, "baudrate"), metavar="BPS", default=_S
    )
    group.add_argument("--parity", type=_parity, metavar="N|E|O", default=_S)
    group.add_argument("--stopbits", type=_integer(1, 2, "stopbits"), metavar="1|2", default=_S)
    if unit:
        group.add_argument(
            "--unit", type=_integer(0, 255, "unit"), metavar="N", default=_S, help="default 1"
        )
    group.add_argument(
        "--timeout", type=_seconds, metavar="S", default=_S, help="seconds to wait for a reply"
    )
    group.add_argument(
        "--retries",
        type=_integer(0, 10, "retries"),
        metavar="N",
        default=_S,
        help="repeats after a timeout or a corrupt reply",
    )
    if rs485:
        group.add_argument(
            "--rs485",
            action="store_true",
            default=_S,
            help="open a board UART in the Linux kernel's RS485 mode (RTS drives the "
            "transceiver; a USB adapter switches by itself and needs none)",
        )
        group.add_argument(
            "--rts-delay",
            type=_rts_delay,
            metavar="BEFORE,AFTER",
            default=_S,
            help="with --rs485: seconds from RTS on to the first bit, and after the last",
        )
    return parent


def _rs485(args: argparse.Namespace) -> dict[str, Any]:
    """The Bus's ``rs485`` and ``rts_delay`` from ``--rs485`` and ``--rts-delay``."""
    rs485, delay = bool(_opt(args, "rs485", False)), _opt(args, "rts_delay")
    if delay is not None and not rs485:
        raise UsageError("--rts-delay goes with --rs485")
    return {"rs485": rs485, "rts_delay": delay}


def _family_options() -> _Parser:
    parent = _Parser(add_help=False)
    parent.add_argument(
        "--family",
        type=str.upper,
        choices=("BLD", "C20"),
        default=_S,
        help="BLD (BLD2, BLD3H; the default) or C20 (ZBLD.C20)",
    )
    return parent


def build_parser() -> argparse.ArgumentParser:
    """The whole command line."""
    general = _general_options()
    device = [general, _line_options(unit=True)]
    parser = _Parser(
        prog=PROG,
        description="Modbus RTU master for the lab bench: find, read, drive and watch RS485 "
        "devices, or simulate one on a pseudo-terminal.",
        epilog=f"Numbers are decimal or 0x hex. --port falls back to ${PORT_ENV}. "
        f"Run '{PROG} COMMAND --help' for a command's options.",
        parents=[general],
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {bb.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    def command(name: str, help: str, parents: list[_Parser], **kw: Any) -> Any:
        return commands.add_parser(name, help=help, description=help, parents=parents, **kw)

    # scan
    formats = "; ".join(f"{b} 8{p}1: {who}" for b, p, who in AUTO_FORMATS)
    scan = command(
        "scan",
        "find the units that answer on a port",
        [general, _line_options(unit=False)],
        epilog="Each unit is asked for one register (--address); an exception reply counts as "
        "an answer. The model is a best guess from Read Device Identification, then from "
        "registers: a drive's model code at 0x2103, a PBL's parameter table ending at 222, "
        "a J2's SV within LSP..USP, a Taisong's 37-register read limit; '?' when nothing "
        f"fits. --auto tries, in order: {formats}. A unit found at one format is not asked "
        "again at the next. On a pseudo-terminal (a simulator) every format carries, so "
        "every unit shows at the first one. Over tcp:// the line shows as 'tcp', --auto "
        "has nothing to try, identification gets the scan's --timeout (once unanswered, it "
        "is not asked of the next units), and a server that answers every unit id tried "
        "is said to, once.",
    )
    scan.add_argument(
        "--units",
        type=_units_type(1, 255),
        default=list(range(1, 248)),
        metavar="LIST",
        help="units to try: numbers and ranges, e.g. 1-10,17,0x20 (default 1-247)",
    )
    scan.add_argument(
        "--auto", action="store_true", help="try every line format the benchbus devices use"
    )
    scan.add_argument(
        "--address",
        type=_integer(0, 0xFFFF, "address"),
        default=0,
        help="the register each unit is asked for (default 0)",
    )
    scan.add_argument(
        "--progress",
        action="store_true",
        help="show the progress bar on stderr even when it is not a terminal",
    )
    scan.set_defaults(handler=_cmd_scan)

    # read
    read = command(
        "read",
        "read holding registers (function 0x03)",
        device,
        epilog="Prints one line per register: the address in hex, in decimal, and the value.",
    )
    read.add_argument("address", type=_integer(0, 0xFFFF, "ADDRESS"), metavar="ADDRESS")
    read.add_argument(
        "count",
        type=_integer(1, 0x10000, "COUNT"),
        nargs="?",
        default=1,
        metavar="COUNT",
        help="registers to read (default 1; more than 125 go in several requests)",
    )
    read.add_argument("--hex", action="store_true", help="print the values in hex")
    read.add_argument("--signed", action="store_true", help="values are 16-bit two's complement")
    read.add_argument(
        "--decimals",
        type=_integer(0, 9, "decimals"),
        default=0,
        metavar="N",
        help="divide the values by 10**N",
    )
    read.set_defaults(handler=_cmd_read)

    # write
    write = command(
        "write",
        "write holding registers (0x06 for one value, 0x10 for several)",
        device,
        epilog="Values are -32768 to 65535 (negative ones in two's complement), decimal or hex; "
        "with --decimals N, decimal numbers written as value x 10**N. --unit 0 broadcasts "
        "one value and waits for no reply.",
    )
    write.add_argument("address", type=_integer(0, 0xFFFF, "ADDRESS"), metavar="ADDRESS")
    write.add_argument("values", nargs="+", metavar="VALUE")
    write.add_argument("--multiple", action="store_true", help="use 0x10 even for a single value")
    write.add_argument(
        "--decimals",
        type=_integer(0, 9, "decimals"),
        default=0,
        metavar="N",
        help="multiply the values by 10**N",
    )
    write.add_argument(
        "--accept-count-echo",
        action="store_true",
        help="accept a 0x06 reply that carries a count of 1 instead of the value (PBL)",
    )
    write.set_defaults(handler=_cmd_write)

    # drive
    family = _family_options()
    drive = command(
        "drive",
        "a BLD2 / BLD3H / ZBLD.C20 drive (19200 8N1): status and common actions",
        [*device, family],
    )
    actions = drive.add_subparsers(dest="action", metavar="ACTION", required=True)

    def action(subparsers: Any, name: str, help: str, parents: list[_Parser]) -> Any:
        return subparsers.add_parser(name, help=help, description=help, parents=parents)

    leaf = [*device, family]
    action(actions, "status", "state, fault, speeds and measurements", leaf)
    for name, what in (("start", "run forward"), ("reverse", "run in reverse")):
        p = action(actions, name, f"{what} at the speed setpoint", leaf)
        p.add_argument(
            "--speed", type=_integer(0, 3000, "rpm"), metavar="RPM", help="set the setpoint first"
        )
    action(actions, "stop", "stop (decelerate, or as the stop mode says)", leaf)
    p = action(actions, "set-speed", "set the speed setpoint (0x2001)", leaf)
    p.add_argument("rpm", type=_integer(0, 3000, "RPM"), metavar="RPM")
    action(actions, "reset-fault", "reset a fault (command 7)", leaf)
    drive.set_defaults(handler=_cmd_drive)

    # pbl
    pbl = command("pbl", "a PBL-series drive (115200 8E1): status and common actions", device)
    actions = pbl.add_subparsers(dest="action", metavar="ACTION", required=True)
    action(actions, "status", "running, direction, speeds, measurements and alarms", device)
    for name, what in (("start", "run forward"), ("reverse", "run in reverse")):
        p = action(actions, name, f"{what} (control word bits 1 and 0)", device)
        p.add_argument(
            "--speed", type=_integer(0, 65535, "rpm"), metavar="RPM", help="set the setpoint first"
        )
        p.add_argument(
            "--take-control",
            action="store_true",
            help="set the start/stop source (204) to communication first if it is not",
        )
    action(actions, "stop", "stop (clear control word bit 0)", device)
    p = action(actions, "set-speed", "set the speed setpoint (parameter 201)", device)
    p.add_argument("rpm", type=_integer(0, 65535, "RPM"), metavar="RPM")
    pbl.set_defaults(handler=_cmd_pbl)

    # j2
    j2 = command("j2", "a J2 PID controller (9600 8N1): status and common actions", device)
    actions = j2.add_subparsers(dest="action", metavar="ACTION", required=True)
    action(actions, "status", "PV, SV, MV, mode, limits", device)
    p = action(actions, "set-sv", "set the setpoint SV (checked against LSP to USP)", device)
    p.add_argument("value", type=_number, metavar="VALUE")
    action(actions, "auto", "automatic mode: the PID sets the output", device)
    action(actions, "manual", "manual mode: the output stays as set", device)
    p = action(actions, "set-output", "set the output MV, percent (manual mode only)", device)
    p.add_argument("percent", type=_number, metavar="PERCENT")
    p.add_argument(
        "--manual", action="store_true", help="switch to manual mode first if in automatic"
    )
    j2.set_defaults(handler=_cmd_j2)

    # monitor
    monitor = command(
        "monitor",
        "a live table of a device's measurements until Ctrl-C",
        [*device, family],
        epilog="On a terminal the table is redrawn in place; otherwise one line is printed "
        "per sample. Samples are taken on a steady clock (deadlines that pass while a "
        "sample is read are skipped, and counted). The CSV file gets every measurement, "
        "with a header when the file is new; an existing file must have the same columns. "
        "A lost port (an adapter unplugged) is reported in one line and reopened at each "
        "sample until it is back.",
    )
    kinds = tuple(f.key for f in command_families())
    monitor.add_argument("device", choices=kinds, metavar="|".join(kinds))
    monitor.add_argument(
        "--interval", type=_seconds, default=0.5, metavar="S", help="seconds between samples"
    )
    until = monitor.add_mutually_exclusive_group()
    until.add_argument(
        "--count", type=_integer(1, 10**9, "count"), metavar="N", help="stop after N samples"
    )
    until.add_argument("--duration", type=_seconds, metavar="S", help="stop after S seconds")
    monitor.add_argument("--csv", metavar="FILE", help="append each sample to FILE")
    monitor.add_argument(
        "--no-reconnect",
        dest="reconnect",
        action="store_false",
        help="end with an error when the port is lost (default: say so, reopen it and go on)",
    )
    monitor.add_argument(
        "--fields",
        metavar="NAMES",
        help="comma-separated measurements to show (default: all; for a drive, the main ones)",
    )
    monitor.set_defaults(handler=_cmd_monitor)

    # sim
    sim = command(
        "sim",
        "serve a simulated device on a pseudo-terminal until Ctrl-C",
        [general],
        epilog="The first line of stdout is the pseudo-terminal's path: open it as the port "
        "(any line format works on it). Stops on Ctrl-C, SIGTERM or after --seconds, with "
        "exit status 0.",
    )
    sim.add_argument(
        "device",
        choices=tuple(SIM_DEVICES),
        metavar="|".join(SIM_DEVICES),
        help="drive: BLD2/BLD3H/C20; pbl: PBL drive; j2: J2 controller with a thermal "
        "process; instrument: Taisong meter; atv31: the Taisong manual's ATV31 drive",
    )
    sim.add_argument(
        "--unit",
        type=_units_type(1, 255),
        default=[1],
        metavar="N",
        help="unit address, or several (1-3,5): one device each (default 1)",
    )
    sim.add_argument(
        "--baudrate",
        type=_integer(50, 4_000_000, "baudrate"),
        metavar="BPS",
        help="the frame timing (default: the device's usual speed)",
    )
    sim.add_argument("--seconds", type=_seconds, metavar="S", help="stop after S seconds")
    sim.add_argument(
        "--model",
        type=str.upper,
        choices=("BLD2", "BLD3H", "C20"),
        default="BLD2",
        help="the drive model (drive only)",
    )
    sim.add_argument(
        "--speedup",
        type=_positive("speedup"),
        default=1.0,
        metavar="X",
        help="run the process X times faster than real time (j2, instrument)",
    )
    sim.set_defaults(handler=_cmd_sim)

    # gateway
    gateway = command(
        "gateway",
        "share one serial port between processes: a Modbus TCP server in front of it",
        [general, _line_options(unit=False)],
        epilog="The first line of stdout is the URL clients open as their port "
        "(bb.Bus('tcp://127.0.0.1:5020')). Requests from every client go over the one line, "
        "one at a time, with this command's timeout and retries; a unit that does not answer "
        "comes back to the client as exception 0x0B, a lost port as 0x0A (the port is "
        "reopened at the next request). Forwards functions 0x03, 0x06, 0x10 and 0x2B. For "
        "one machine; for a line shared across a network, use a dedicated gateway (mbusd). "
        "Modbus TCP has no authentication: listening beyond loopback prints a warning; "
        "--allow limits who may connect.",
    )
    gateway.add_argument(
        "--listen",
        metavar="HOST:PORT",
        type=_listen,
        default="127.0.0.1:5020",
        help="address to serve on (default 127.0.0.1:5020; port 0: any free port)",
    )
    gateway.add_argument(
        "--write-interval",
        metavar="UNIT=S",
        type=_unit_interval,
        action="append",
        default=[],
        help="least seconds between two writes to UNIT on the line, from any client "
        "(repeatable; a J2 controller needs 0.15)",
    )
    gateway.add_argument(
        "--idle-timeout",
        type=_seconds,
        default=IDLE_TIMEOUT,
        metavar="S",
        help=f"close a client silent for S seconds between requests (default {IDLE_TIMEOUT:g}); "
        "when --max-clients are connected, a new one replaces the longest idle",
    )
    gateway.add_argument(
        "--max-clients",
        type=_integer(1, 10_000, "max-clients"),
        default=32,
        metavar="N",
        help="clients served at once (default 32)",
    )
    gateway.add_argument(
        "--allow",
        metavar="ADDR[/BITS]",
        type=_allow,
        action="append",
        help="only this address or network may connect, e.g. 192.168.1.0/24 or ::1 "
        "(repeatable; default: any)",
    )
    gateway.add_argument("--seconds", type=_seconds, metavar="S", help="stop after S seconds")
    gateway.set_defaults(handler=_cmd_gateway)

    # ports
    ports = command(
        "ports",
        "list the serial ports, with the USB adapter's ids, names and chip",
        [general],
        epilog="For a USB adapter: its vendor:product ids, the chip family they belong to "
        "(FTDI, CH340, CP210x, PL2303...), and the manufacturer, product and serial number "
        "it reports. A port without them is the board's own (or the system does not say).",
    )
    ports.add_argument("--sysfs-root", metavar="DIR", help=_S)  # another sysfs tree, for tests
    ports.set_defaults(handler=_cmd_ports)

    # doctor
    doctor = command(
        "doctor",
        "check a serial port: what stands between benchbus and the devices on it",
        [general, _line_options(unit=True, rs485=False)],
        epilog="One line per finding: its verdict (ok, info, warn, fail), what was checked, "
        "what was found and the fix. Checks the platform, the port and who holds it, the "
        "permission to open it, the USB chip and an FTDI's latency timer, the driver's "
        "low-latency mode, the kernel RS485 mode, and whether a request comes back (a local "
        "echo: one read of register 0 goes to --unit). Exits 1 if any finding fails.",
    )
    doctor.add_argument("--sysfs-root", metavar="DIR", help=_S)  # other trees, for tests
    doctor.add_argument("--proc-root", metavar="DIR", help=_S)
    doctor.set_defaults(handler=_cmd_doctor)

    # demo
    demo = command(
        "demo",
        "run the benchbus demo and save its plot",
        [general],
        epilog="Without --port the demo runs on simulated devices.",
    )
    demo.add_argument("--port", metavar="PATH", help="a real port to run the demo on")
    demo.add_argument("--out", metavar="FILE.png", help="where to save the plot")
    demo.add_argument(
        "--unit", type=parse_int, default=1, help="the BLD drive's unit with --port (default 1)"
    )
    demo.set_defaults(handler=_cmd_demo)
    return parser


# ---- opening the line --------------------------------------------------------------------------


def _opt(args: argparse.Namespace, name: str, default: Any = None) -> Any:
    return getattr(args, name, default)


def _port(args: argparse.Namespace) -> str:
    port = _opt(args, "port") or os.environ.get(PORT_ENV)
    if not port:
        raise UsageError(f"--port is required (or set ${PORT_ENV})")
    return str(port)


def _line(args: argparse.Namespace, family: str) -> Line:
    """The family's line defaults with the options given on the command line."""
    base = LINES[family]
    return Line(
        baudrate=_opt(args, "baudrate", base.baudrate),
        parity=_opt(args, "parity", base.parity),
        timeout=_opt(args, "timeout", base.timeout),
        retries=_opt(args, "retries", base.retries),
        unit=_opt(args, "unit", base.unit),
    )


def _open_bus(args: argparse.Namespace, family: str, *, reconnect: bool = False) -> bb.Bus:
    line = _line(args, family)
    return bb.Bus(
        _port(args),
        baudrate=line.baudrate,
        parity=line.parity,
        stopbits=_opt(args, "stopbits", 1),
        timeout=line.timeout,
        retries=line.retries,
        reconnect=reconnect,
        **_rs485(args),
    )


def _unit(args: argparse.Namespace, family: str, *, broadcast: bool = False) -> int:
    unit = int(_line(args, family).unit)
    if unit == 0 and not broadcast:
        raise UsageError("unit 0 is the broadcast address: give --unit 1 to 255")
    return unit


# ---- scan --------------------------------------------------------------------------------------


class Progress:
    """A one-line text progress bar on a stream (a no-op when disabled)."""

    WIDTH = 24

    def __init__(self, total: int, stream: IO[str], enabled: bool) -> None:
        self.total = max(total, 1)
        self.stream = stream
        self.enabled = enabled
        self._shown = 0

    def show(self, done: int, note: str) -> None:
        """Redraw the bar at ``done`` of ``total``, followed by ``note``."""
        if not self.enabled:
            return
        filled = self.WIDTH * min(done, self.total) // self.total
        text = f"[{'#' * filled}{'.' * (self.WIDTH - filled)}] {done}/{self.total} {note}"
        self.stream.write("\r" + text.ljust(self._shown))
        self.stream.flush()
        self._shown = len(text)

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled and self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = 0


def _signed(word: int) -> int:
    return word - 0x10000 if word & 0x8000 else word


def _identification(bus: bb.Bus, unit: int) -> str | None:
    """Vendor and product code from Read Device Identification (0x2B / 0x0E); None when the
    unit refuses it or garbles the reply. A timeout is raised."""
    try:
        objects = bus.read_device_identification(unit)
    except (bb.ModbusException, bb.FrameError):
        return None
    return " ".join(objects[k] for k in (0, 1) if objects.get(k)) or "identified (no vendor)"


def guess_model(bus: bb.Bus, unit: int, *, identify: bool = True) -> str:
    """A best guess at what answers at ``unit``, in this order (each a few reads):

    - Read Device Identification (0x2B / 0x0E) answered: its vendor and product code (not
      asked with ``identify`` False);
    - each family of :data:`benchbus._families.FAMILIES` in turn, by its model probe: a
      drive by the model code at 0x2103 (:func:`benchbus._recognise.drive_model`), a PBL
      drive, then a J2 controller, by the tests that ``status`` and ``monitor`` check a
      unit's family with, a Taisong meter by its request limit (37 registers);
    - otherwise ``?``.
    """
    if identify:
        try:
            name = _identification(bus, unit)
        except bb.ResponseTimeout:
            name = None
        if name:
            return name
    probe = Probe(bus, unit)
    return next((name for f in FAMILIES if (name := f.identify(probe))), "?")


def _cmd_scan(args: argparse.Namespace) -> int:
    port = _port(args)
    given = [o for o in ("baudrate", "parity") if _opt(args, o) is not None]
    if args.auto and given:
        raise UsageError(f"--auto tries every line format: leave out --{given[0]}")
    line = _line(args, "scan")
    stopbits = _opt(args, "stopbits", 1)
    formats = [(b, p) for b, p, _ in AUTO_FORMATS] if args.auto else [(line.baudrate, line.parity)]
    # Over Modbus TCP the server (or gateway) keeps the line: there is no line format to try,
    # and a request it left unanswered is its own doing, not a unit's.
    tcp = port.lower().startswith("tcp://")
    if tcp:
        formats = formats[:1]
    units: list[int] = args.units
    progress = Progress(
        len(units) * len(formats), sys.stderr, bool(args.progress or sys.stderr.isatty())
    )
    found: dict[int, tuple[str, str]] = {}
    pending: tuple[int, str] | None = None  # a unit that answered, being identified
    identify = True  # whether to ask for Read Device Identification
    done = 0
    try:
        for baudrate, parity in formats:
            fmt = "tcp" if tcp else f"{baudrate} 8{parity}{stopbits}"
            with bb.Bus(
                port,
                baudrate=baudrate,
                parity=parity,
                stopbits=stopbits,
                # Over the network the identification gets the scan's own time, once.
                timeout=line.timeout if tcp else max(line.timeout, 0.1),
                retries=0 if tcp else 1,
                **_rs485(args),
            ) as bus:
                for unit in units:
                    done += 1
                    if unit in found:
                        continue
                    progress.show(done, f"unit {unit} at {fmt}, {len(found)} found")
                    for _ in range(line.retries + 1):
                        if bus.scan([unit], timeout=line.timeout, address=args.address):
                            pending = (unit, fmt)
                            progress.show(done, f"unit {unit} at {fmt}: identifying")
                            name = None
                            if identify:
                                try:
                                    name = _identification(bus, unit)
                                except bb.ResponseTimeout:
                                    # The server does not answer it: not asked of every unit.
                                    identify = not tcp
                            found[unit] = (fmt, name or guess_model(bus, unit, identify=False))
                            pending = None
                            break
            progress.show(done, f"{len(found)} found")
    except (KeyboardInterrupt, SystemError) as exc:
        if interrupted(exc):  # Ctrl-C: show what was found so far, then exit as interrupted
            if pending is not None:
                found[pending[0]] = (pending[1], "(not identified)")
            progress.close()
            _print_found(found)
        raise
    finally:
        progress.close()
    if not found:
        tried = "tcp" if tcp else ", ".join(f"{b} 8{p}{stopbits}" for b, p in formats)
        raise CliError(f"no unit answered on {port} (at {tried})")
    _print_found(found)
    if tcp and len(units) > 1 and len(found) == len(units):
        print(
            f"every unit id tried answered: the server at {port} answers any unit id (a "
            "device that speaks Modbus TCP itself, not a gateway to a line of units)"
        )
    return 0


def _print_found(found: dict[int, tuple[str, str]]) -> None:
    if found:
        rows = [[str(u), f"0x{u:02X}", fmt, model] for u, (fmt, model) in sorted(found.items())]
        _print_table(["unit", "hex", "line", "model"], rows)
        sys.stdout.flush()


# ---- read / write ------------------------------------------------------------------------------


def _cmd_read(args: argparse.Namespace) -> int:
    if args.hex and (args.signed or args.decimals):
        raise UsageError("--hex prints the raw words: leave out --signed and --decimals")
    if args.address + args.count > 0x10000:
        raise UsageError(f"{args.count} registers from {args.address:#06x} run past 0xFFFF")
    unit = _unit(args, "read")
    words: list[int] = []
    with _open_bus(args, "read") as bus:
        for start in range(args.address, args.address + args.count, 125):
            count = min(125, args.address + args.count - start)
            words += bus.read_holding_registers(unit, start, count)
    for offset, word in enumerate(words):
        address = args.address + offset
        if args.hex:
            text = f"0x{word:04X}"
        else:
            value = _signed(word) if args.signed else word
            text = str(Decimal(value).scaleb(-args.decimals)) if args.decimals else str(value)
        print(f"0x{address:04X}  {address}  {text}")
    return 0


def _cmd_write(args: argparse.Namespace) -> int:
    words = [_word(v, args.decimals) for v in args.values]
    if args.address + len(words) > 0x10000:
        raise UsageError(f"{len(words)} registers from {args.address:#06x} run past 0xFFFF")
    unit = _unit(args, "write", broadcast=True)
    if unit == 0 and len(words) > 1:
        raise UsageError("a broadcast (unit 0) writes one register")
    with _open_bus(args, "write") as bus:
        if unit == 0:
            bus.broadcast_write_register(args.address, words[0])
            how = "broadcast"
        elif len(words) == 1 and not args.multiple:
            bus.write_register(
                unit, args.address, words[0], accept_count_echo=args.accept_count_echo
            )
            how = "0x06"
        else:
            for i in range(0, len(words), 123):
                bus.write_registers(unit, args.address + i, words[i : i + 123])
            how = "0x10"
    shown = " ".join(str(w) for w in words)
    print(f"unit {unit}: wrote {shown} at 0x{args.address:04X} ({how})")
    return 0


# ---- drive / pbl / j2 --------------------------------------------------------------------------


def _open_drive(bus: bb.Bus, args: argparse.Namespace) -> bb.Drive:
    return bb.Drive(bus, _unit(args, "drive"), family=_opt(args, "family", "BLD"))


def _check_family(device: bb.Drive | bb.PblDrive | bb.J2Controller, key: str) -> None:
    """Refuse a unit recognised as another family than the command talks to."""
    other = mismatch(device.bus, device.unit, key)
    if other is not None:
        raise CliError(
            f"unit {device.unit} answers but is not {family(key).name} (looks like "
            f"{other.name}: see '{PROG} {other.key} --help', or check --port and --unit)"
        )


def _cmd_drive(args: argparse.Namespace) -> int:
    with _open_bus(args, "drive") as bus:
        drive = _open_drive(bus, args)  # not a `with`: that would stop the motor on leaving
        unit = drive.unit
        if args.action == "status":
            _check_family(drive, "drive")
            status = drive.status()
            t = drive.telemetry()
            u = drive.units()
            rows = [
                ("model", _name(drive.model)),
                ("state", _name(status.state)),
                ("fault", str(status.fault) if status.fault else "none"),
                ("speed", _measured(t.speed, u["speed"])),
                ("speed setpoint", _measured(drive.speed_setpoint, u["speed_setpoint"])),
                ("output frequency", _measured(t.output_frequency, u["output_frequency"])),
                ("output current", _measured(t.output_current, u["output_current"])),
                ("bus voltage", _measured(t.bus_voltage, u["bus_voltage"])),
                ("temperature", _measured(t.temperature, u["temperature"])),
                ("command source", _name(status.control_source)),
            ]
            _print_table(None, rows)
        elif args.action in ("start", "reverse"):
            if args.speed is not None:
                drive.speed_setpoint = args.speed
            (drive.forward if args.action == "start" else drive.reverse)()
            way = "forward" if args.action == "start" else "reverse"
            print(f"unit {unit}: running {way} at {drive.speed_setpoint} rpm")
        elif args.action == "stop":
            drive.stop()
            print(f"unit {unit}: stopping")
        elif args.action == "set-speed":
            drive.speed_setpoint = args.rpm
            print(f"unit {unit}: speed setpoint {args.rpm} rpm")
        else:
            drive.reset_fault()
            print(f"unit {unit}: fault reset")
    return 0


def _cmd_pbl(args: argparse.Namespace) -> int:
    with _open_bus(args, "pbl") as bus:
        pbl = bb.PblDrive(bus, _unit(args, "pbl"))
        unit = pbl.unit
        if args.action == "status":
            _check_family(pbl, "pbl")
            status = pbl.status()
            sample = pbl.sample()
            alarms = sorted(pbl.alarms)
            u = pbl.units()
            rows = [
                ("running", f"yes, {_name(status.direction)}" if status.running else "no"),
                ("direction asked", _name(pbl.direction)),
                ("speed", _measured(sample["speed"], u["speed"])),
                ("speed setpoint", _measured(pbl.speed_setpoint, u["internal_speed"])),
                ("bus voltage", _measured(sample["bus_voltage"], u["bus_voltage"])),
                ("current", _measured(sample["current"], u["current"])),
                ("power", _measured(sample["power"], u["power"])),
                ("alarms", ", ".join(alarms) if alarms else "none"),
                ("start/stop source", _name(pbl.start_stop_source)),
            ]
            _print_table(None, rows)
        elif args.action in ("start", "reverse"):
            source = pbl.start_stop_source
            if source != bb.StartStopSource.COMMUNICATION:
                if not args.take_control:
                    raise CliError(
                        f"unit {unit} takes start/stop from {_name(source)} (parameter 204), so "
                        "it would ignore a start: add --take-control to switch it to "
                        "COMMUNICATION"
                    )
                pbl.start_stop_source = bb.StartStopSource.COMMUNICATION
            if args.speed is not None:
                pbl.speed_setpoint = args.speed
            reverse = args.action == "reverse"
            pbl.direction = bb.Direction.REVERSE if reverse else bb.Direction.FORWARD
            pbl.start()
            way = "reverse" if reverse else "forward"
            print(f"unit {unit}: running {way} at {pbl.speed_setpoint} rpm")
        elif args.action == "stop":
            pbl.stop()
            print(f"unit {unit}: stopping")
        else:
            pbl.speed_setpoint = args.rpm
            print(f"unit {unit}: speed setpoint {args.rpm} rpm")
    return 0


def _cmd_j2(args: argparse.Namespace) -> int:
    with _open_bus(args, "j2") as bus:
        j2 = bb.J2Controller(bus, _unit(args, "j2"))
        unit = j2.unit
        if args.action == "status":
            _check_family(j2, "j2")
            names = ["PV", "SV", "MV", "AM", "LSP", "USP", "AT", "RAPNF", "INP"]
            v = dict(zip(names, j2.read_many(names)))
            u = j2.units()
            rows = [
                ("pv", _measured(v["PV"], u["PV"])),
                ("sv", _measured(v["SV"], u["SV"])),
                ("mv", _measured(v["MV"], u["MV"])),
                ("mode", _name(_enum(bb.J2Mode, v["AM"]))),
                ("limits", f"{_fmt(v['LSP'])} to {_measured(v['USP'], u['USP'])}"),
                ("autotune", "running" if v["AT"] else "off"),
                ("ramp", "running" if v["RAPNF"] else "off"),
                ("input", _name(_enum(bb.InputType, v["INP"]))),
            ]
            _print_table(None, rows)
        elif args.action == "set-sv":
            j2.sv = args.value
            print(f"unit {unit}: SV {_fmt(args.value)}")
        elif args.action in ("auto", "manual"):
            j2.mode = bb.J2Mode.AUTO if args.action == "auto" else bb.J2Mode.MANUAL
            print(f"unit {unit}: {args.action} mode")
        else:
            try:
                j2.set_output(args.percent, switch_to_manual=args.manual)
            except bb.StateError:
                raise CliError(
                    f"unit {unit} is in automatic mode and takes an output in manual mode "
                    f"only: run '{PROG} j2 manual' first, or add --manual"
                ) from None
            print(f"unit {unit}: MV {_fmt(args.percent)} %")
    return 0


def _enum(kind: type[enum.IntEnum], value: float) -> enum.IntEnum | int:
    try:
        return kind(int(value))
    except ValueError:
        return int(value)


# ---- monitor -----------------------------------------------------------------------------------

#: What a drive's monitor shows unless --fields says otherwise (its sample has ~20 fields).
DRIVE_FIELDS = (
    "speed",
    "speed_reference",
    "output_frequency",
    "output_current",
    "output_voltage",
    "bus_voltage",
    "output_power",
    "temperature",
)


class CsvLog:
    """Samples appended to a CSV file: ``time`` (ISO 8601), ``t (s)``, then the fields, each
    named with its unit (``speed (rpm)``)."""

    def __init__(self, path: str, units: dict[str, str]) -> None:
        self.path = path
        self.units = units
        self._file: IO[str] | None = None
        self._writer: Any = None

    def write(self, when: datetime.datetime, t: float, sample: dict[str, float]) -> None:
        """Append one row (the header first, if the file is new or empty)."""
        header = [
            "time",
            with_unit("t", "s"),
            *(with_unit(k, self.units.get(k, "")) for k in sample),
        ]
        if self._file is None:
            existing = self._header()
            if existing is not None and existing != header:
                raise CliError(
                    f"{self.path} has other columns ({','.join(existing)}): choose another file"
                )
            self._file = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115
            self._writer = csv.writer(self._file)
            if existing is None:
                self._writer.writerow(header)
        row = [when.isoformat(timespec="milliseconds"), f"{t:.3f}"]
        self._writer.writerow(row + [_csv_number(v) for v in sample.values()])
        self._file.flush()

    def _header(self) -> list[str] | None:
        try:
            with open(self.path, newline="", encoding="utf-8") as f:
                return next(csv.reader(f), None)
        except FileNotFoundError:
            return None

    def close(self) -> None:
        """Close the file."""
        if self._file is not None:
            self._file.close()
            self._file = None


class LiveTable:
    """The monitor's screen: redrawn in place on a terminal, a line per sample otherwise."""

    def __init__(
        self, stream: IO[str], title: str, fields: list[str], units: dict[str, str], tty: bool
    ) -> None:
        self.stream = stream
        self.title = title
        self.fields = fields
        self.units = [units.get(f, "") for f in fields]
        self.tty = tty
        self._drawn = 0
        self._header = [with_unit("t", "s"), *map(with_unit, fields, self.units)]
        self._widths = [max(len(h), 9) for h in self._header]

    def show(self, n: int, t: float, missed: int, sample: dict[str, float]) -> None:
        """Show one sample."""
        values = [_fmt(sample[f]) for f in self.fields]
        if self.tty:
            late = f", {missed} deadlines missed" if missed else ""
            lines = [self.title, f"sample {n}  t {t:.1f} s{late}  (Ctrl-C to stop)"]
            rows = [[f, v.rjust(12), u] for f, v, u in zip(self.fields, values, self.units)]
            lines += _table(None, rows)
            out = f"\x1b[{self._drawn}A\r" if self._drawn else ""
            out += "".join(f"{line}\x1b[K\n" for line in lines)
            self._drawn = len(lines)
        else:
            out = ""
            if n == 1:
                out += self._row(self._header) + "\n"
            out += self._row([f"{t:.3f}", *values]) + "\n"
        self.stream.write(out)
        self.stream.flush()

    def below(self) -> None:
        """Draw the next sample below what was printed since (not over it)."""
        self._drawn = 0

    def _row(self, cells: list[str]) -> str:
        return "  ".join(c.rjust(w) for c, w in zip(cells, self._widths))


def _cmd_monitor(args: argparse.Namespace) -> int:
    kind: str = args.device
    log: CsvLog | None = None
    samples = 0
    lost: float | None = None  # when the port was lost, while it is
    with _open_bus(args, kind, reconnect=args.reconnect) as bus:
        device: bb.Drive | bb.PblDrive | bb.J2Controller
        if kind == "drive":
            device = _open_drive(bus, args)
        elif kind == "pbl":
            device = bb.PblDrive(bus, _unit(args, kind))
        else:
            device = bb.J2Controller(bus, _unit(args, kind))
        _check_family(device, kind)
        units = device.sample_units()
        log = CsvLog(args.csv, units) if args.csv else None
        title = f"{kind} unit {device.unit} on {bus.port}, every {_fmt(args.interval)} s"
        table: LiveTable | None = None
        try:
            for n, _deadline, missed in ticks(args.interval, args.duration):
                try:
                    sample = device.sample()
                except bb.PortError as exc:
                    if not args.reconnect:
                        raise
                    if lost is None:
                        lost = time.monotonic()
                        _note(table, f"lost {bus.port} ({_one_line(exc)}): reconnecting")
                    continue
                if lost is not None:
                    _note(table, f"{bus.port} is back after {time.monotonic() - lost:.1f} s")
                    lost = None
                now = datetime.datetime.now().astimezone()
                t = n * args.interval
                if table is None:
                    fields = _fields(args.fields, kind, sample)
                    table = LiveTable(sys.stdout, title, fields, units, sys.stdout.isatty())
                samples += 1
                if log is not None:
                    log.write(now, t, sample)
                table.show(samples, t, missed, sample)
                if args.count is not None and samples >= args.count:
                    break
        except (KeyboardInterrupt, SystemError) as exc:
            if not interrupted(exc):
                raise
            _end_ctrl_c_line()
        finally:
            if log is not None:
                log.close()
    where = f", appended to {args.csv}" if args.csv else ""
    print(f"{plural(samples, 'sample')}{where}", file=sys.stderr)
    return 0


def _end_ctrl_c_line() -> None:
    """On a terminal, end the line its ``^C`` echo is on, so what follows starts a line."""
    if sys.stderr.isatty():
        print(file=sys.stderr)


def _note(table: LiveTable | None, text: str) -> None:
    """One line on stderr while the monitor runs, below the table (redrawn after it)."""
    print(f"{PROG}: monitor: {text}", file=sys.stderr, flush=True)
    if table is not None:
        table.below()


def _fields(spec: str | None, kind: str, sample: dict[str, float]) -> list[str]:
    if spec is None or spec.strip() == "all":
        if spec is None and kind == "drive":
            return [f for f in DRIVE_FIELDS if f in sample]
        return list(sample)
    names = [f.strip() for f in spec.split(",") if f.strip()]
    unknown = [f for f in names if f not in sample]
    if unknown or not names:
        raise UsageError(
            f"no measurement {', '.join(unknown) or spec!r}: choose from {', '.join(sample)}"
        )
    return names


# ---- sim ---------------------------------------------------------------------------------------

#: Each simulated device, with the baud rate its family usually runs at.
SIM_DEVICES: dict[str, int] = {f.key: f.line.baudrate for f in FAMILIES}


def _sim_device(kind: str, args: argparse.Namespace) -> SimDevice:
    of = family(kind)
    return of.simulate(**{option: getattr(args, option) for option in of.sim_options})


def _cmd_sim(args: argparse.Namespace) -> int:
    try:
        from benchbus.sim import Simulator
    except ModuleNotFoundError as exc:  # the message says what to install
        raise CliError(str(exc)) from None
    kind: str = args.device
    units: list[int] = args.unit
    baudrate: int = args.baudrate or SIM_DEVICES[kind]
    simulator = Simulator({u: _sim_device(kind, args) for u in units}, baudrate=baudrate)
    simulator.start()
    try:
        what = f"{args.model} drive" if kind == "drive" else kind
        at = ", ".join(str(u) for u in units)
        _serve_until_stopped(
            simulator.port,
            f"simulating {what} (unit {at}, {baudrate} baud frame timing)",
            args.seconds,
        )
    finally:
        simulator.stop()
    return 0


def _serve_until_stopped(where: str, what: str, seconds: float | None) -> None:
    """Print ``where`` (what clients open) on stdout and ``what`` on stderr, then block
    until Ctrl-C, SIGTERM or ``seconds`` (None: no limit), whichever comes first."""
    print(where, flush=True)
    print(f"{what} on {where}; Ctrl-C or SIGTERM stops it", file=sys.stderr, flush=True)
    stop = []

    def on_sigterm(signum: int, frame: FrameType | None) -> None:
        stop.append(signum)

    try:
        previous: Any = signal.signal(signal.SIGTERM, on_sigterm)
    except ValueError:  # not the main thread: no handler, Ctrl-C and --seconds still work
        previous = None
    try:
        end = None if seconds is None else time.monotonic() + seconds
        while not stop:
            left = 0.1 if end is None else min(0.1, end - time.monotonic())
            if left <= 0:
                break
            time.sleep(left)
    except KeyboardInterrupt:
        pass
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


# ---- gateway -----------------------------------------------------------------------------------


def _cmd_gateway(args: argparse.Namespace) -> int:
    line = _line(args, "gateway")
    with _open_bus(args, "gateway", reconnect=True) as bus:
        gateway = bb.Gateway(
            bus,
            args.listen,
            write_intervals=dict(args.write_interval),
            max_clients=args.max_clients,
            idle_timeout=args.idle_timeout,
            allow=args.allow,
        )
        try:
            gateway.start()
        except OSError as exc:
            raise CliError(f"cannot listen on {args.listen}: {exc.strerror or exc}") from None
        try:
            _serve_until_stopped(
                gateway.url,
                f"gateway for {bus.port} ({line.describe(_opt(args, 'stopbits', 1))})",
                args.seconds,
            )
        finally:
            gateway.stop()
    return 0


# ---- ports -------------------------------------------------------------------------------------


def _cmd_ports(args: argparse.Namespace) -> int:
    from benchbus._core import list_ports

    found = list_ports(args.sysfs_root)
    if not found:
        raise CliError("no serial port found (is the adapter plugged in?)")

    def cell(port: dict[str, str | int | None], key: str) -> str:
        value = port.get(key)
        return "-" if value is None else str(value)

    rows = [
        [
            cell(p, "path"),
            cell(p, "chip"),
            "-" if p["vid"] is None else f"{p['vid']:04x}:{p['pid']:04x}",
            *(cell(p, k) for k in ("manufacturer", "product", "serial_number", "driver")),
        ]
        for p in found
    ]
    _print_table(["port", "chip", "usb id", "manufacturer", "product", "serial", "driver"], rows)
    return 0


# ---- doctor ------------------------------------------------------------------------------------


def _cmd_doctor(args: argparse.Namespace) -> int:
    line = _line(args, "read")
    findings = bb.doctor(
        _port(args),
        baudrate=line.baudrate,
        parity=line.parity,
        stopbits=_opt(args, "stopbits", 1),
        unit=_unit(args, "read"),
        timeout=line.timeout,
        sysfs_root=args.sysfs_root,
        proc_root=args.proc_root,
    )
    for finding in findings:
        print(finding)
    return 1 if any(f.verdict == "fail" for f in findings) else 0


# ---- demo --------------------------------------------------------------------------------------


def _cmd_demo(args: argparse.Namespace) -> int:
    from benchbus._demo import run

    run(args.port, args.out, unit=args.unit)  # prints its table and where the plot went
    return 0


# ---- main --------------------------------------------------------------------------------------


def _configure_logging(verbose: bool, traceback: bool = False) -> None:
    """Warnings of the library on stderr; with ``verbose``, every frame too (the wire log).

    Without ``traceback``, a record that is also a note on the exception being raised is
    left to the error line, which shows the notes."""
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(logging.WARNING)  # the wire log has its own handler
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
    if not traceback:
        handler.addFilter(lambda record: not getattr(record, NOTED, False))
    logging.getLogger("benchbus").addHandler(handler)
    if verbose:
        bb.enable_wire_log(sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); the exit status."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version (0) and usage errors (2)
        return exc.code if isinstance(exc.code, int) else 2
    if _opt(args, "traceback", False):
        _configure_logging(bool(_opt(args, "verbose", False)), traceback=True)
        return int(args.handler(args))
    try:
        _configure_logging(bool(_opt(args, "verbose", False)))
        return int(args.handler(args))
    except UsageError as exc:
        print(f"{PROG}: {args.command}: {_one_line(exc)}", file=sys.stderr)
        return exc.status
    except CliError as exc:
        print(f"{PROG}: {_one_line(exc)}", file=sys.stderr)
        return exc.status
    except (KeyboardInterrupt, SystemError) as exc:
        if not interrupted(exc):
            print(f"{PROG}: unexpected {type(exc).__name__}: {_one_line(exc)}", file=sys.stderr)
            return 1
        if args.command in ("monitor", "sim", "gateway"):
            return 0
        _end_ctrl_c_line()
        print("; ".join([f"{PROG}: interrupted", *_notes(exc)]), file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`benchbus read ... | head`): nothing more to say to it.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    except (bb.BenchbusError, ValueError, TypeError, OSError, RuntimeError, ImportError) as exc:
        print(f"{PROG}: {_one_line(exc)}", file=sys.stderr)
        return 1
    except (Exception, BaseException) as exc:  # also a panic in the core (PanicException)
        if isinstance(exc, (SystemExit, GeneratorExit)):
            raise
        print(
            f"{PROG}: unexpected {type(exc).__name__}: {_one_line(exc)} "
            "(run again with --traceback to see where)",
            file=sys.stderr,
        )
        return 1
