"""``benchbus scan``: find the units that answer on a port, and guess what they are."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from typing import IO

import benchbus as bb
from benchbus._core import _endpoint_kind
from benchbus._families import FAMILIES
from benchbus._recognise import Probe
from benchbus.cli._args import Parser, integer, units_type
from benchbus.cli._errors import CliError, UsageError, interrupted
from benchbus.cli._line import (
    BusOptions,
    adapter_options,
    bus_options_of,
    new_bus,
    opt,
    port_of,
    stopbits_of,
)
from benchbus.cli._output import print_table

__all__ = ["AUTO_FORMATS", "HELP", "add_arguments", "guess_model", "run"]


#: The line formats ``scan --auto`` tries, in order, and who uses them.
AUTO_FORMATS: tuple[tuple[int, str, str], ...] = (
    (19200, "N", "BLD2 / BLD3H / ZBLD.C20 drives; J2 and Taisong set to 19200"),
    (115200, "E", "PBL drives"),
    (9600, "N", "J2 controllers and Taisong meters (factory setting)"),
    (4800, "N", "Taisong meters"),
    (2400, "N", "Taisong meters"),
)


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


def _describe(args: argparse.Namespace, options: BusOptions, baudrate: int, parity: str) -> str:
    """``19200 8N1``: the line format of ``options`` at ``baudrate`` and ``parity``."""
    line = dataclasses.replace(options, baudrate=baudrate, parity=parity)
    return line.describe(stopbits_of(args, line))


def run(args: argparse.Namespace) -> int:
    """Run ``benchbus scan`` as ``args`` say; the exit status."""
    port = port_of(args)
    given = [o for o in ("baudrate", "parity") if opt(args, o) is not None]
    if args.auto and given:
        raise UsageError(f"--auto tries every line format: leave out --{given[0]}")
    options = bus_options_of(args, "scan")
    formats = (
        [(b, p) for b, p, _ in AUTO_FORMATS] if args.auto else [(options.baudrate, options.parity)]
    )
    # Over the network the server (or gateway, or converter) keeps the line: there is no line
    # format to try; and over Modbus TCP a request it left unanswered is its own doing, not a
    # unit's.
    kind = _endpoint_kind(port)  # a port string a Bus refuses: its ValueError, as the Bus's
    tcp = kind == "tcp"
    if kind != "serial":
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
            line = dataclasses.replace(options, baudrate=baudrate, parity=parity)
            stopbits = stopbits_of(args, line)
            fmt = "tcp" if tcp else line.describe(stopbits)
            with new_bus(
                port,
                baudrate=baudrate,
                parity=parity,
                stopbits=stopbits,
                framing=line.framing,
                bytesize=line.bytesize,
                # Over the network the identification gets the scan's own time, once.
                timeout=options.timeout if tcp else max(options.timeout, 0.1),
                retries=0 if tcp else 1,
                **adapter_options(args),
            ) as bus:
                for unit in units:
                    done += 1
                    if unit in found:
                        continue
                    progress.show(done, f"unit {unit} at {fmt}, {len(found)} found")
                    for _ in range(options.retries + 1):
                        if bus.scan([unit], timeout=options.timeout, address=args.address):
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
        tried = "tcp" if tcp else ", ".join(_describe(args, options, b, p) for b, p in formats)
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
        print_table(["unit", "hex", "line", "model"], rows)
        sys.stdout.flush()


_FORMATS = "; ".join(f"{b} 8{p}1: {who}" for b, p, who in AUTO_FORMATS)

#: What ``benchbus scan`` does, as ``--help`` says.
HELP = "find the units that answer on a port"
#: The rest of its ``--help``.
EPILOG = (
    "Each unit is asked for one register (--address); an exception reply counts as "
    "an answer. The model is a best guess from Read Device Identification, then from "
    "registers: a drive's model code at 0x2103, a PBL's parameter table ending at 222, "
    "a J2's SV within LSP..USP, a Taisong's 37-register read limit; '?' when nothing "
    f"fits. --auto tries, in order: {_FORMATS}. A unit found at one format is not asked "
    "again at the next. On a pseudo-terminal (a simulator) every format carries, so "
    "every unit shows at the first one. Over tcp:// the line shows as 'tcp', --auto "
    "has nothing to try, identification gets the scan's --timeout (once unanswered, it "
    "is not asked of the next units), and a server that answers every unit id tried "
    "is said to, once."
)
#: Its line options (see :func:`benchbus.cli._args.line_options`).
LINE_OPTIONS = {"unit": False}


def add_arguments(parser: Parser, parents: list[Parser]) -> None:
    """The arguments of ``benchbus scan`` (``parents``: its option groups, for its actions)."""
    parser.add_argument(
        "--units",
        type=units_type(1, 255),
        default=list(range(1, 248)),
        metavar="LIST",
        help="units to try: numbers and ranges, e.g. 1-10,17,0x20 (default 1-247)",
    )
    parser.add_argument(
        "--auto", action="store_true", help="try every line format the benchbus devices use"
    )
    parser.add_argument(
        "--address",
        type=integer(0, 0xFFFF, "address"),
        default=0,
        help="the register each unit is asked for (default 0)",
    )
    parser.add_argument(
        "--progress",
        action="store_true",
        help="show the progress bar on stderr even when it is not a terminal",
    )
